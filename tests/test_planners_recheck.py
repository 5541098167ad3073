"""Feasible holds between the samples: every planner's output, sampled 10x finer than the check
rate (100 kHz, no refinement), never exceeds the refined peaks its plan reports, and a feasible plan
never exceeds 1 there."""

import numpy as np
import pytest

from qmt_drake.planners import plan_with

METHODS = {
    "ga": {"max_generations": 120},
    "optimum": {},
    "thesis": {},
    "toppra": {"measure_polygon_cost": False},
    "toppra-drake": {},
    "ruckig": {},
    "trajopt": {"num_control_points": 10, "constraint_samples": 40},
}


CASES = [("thesis-ch4", m) for m in sorted(METHODS)] + [("thesis-ch2", m) for m in ("thesis", "toppra", "ruckig")]


@pytest.mark.parametrize("name, method", CASES)
def test_every_planner_holds_between_samples(scenarios, name, method):
    sc = scenarios[name]
    plan = plan_with(method, sc, seed=0, **METHODS[method])
    ls = sc.limit_set
    fine = ls.report(plan.trajectory, 10 * sc.sampling.check_rate_hz, refine=False)
    for term, refined in plan.check.peak_ratios.items():
        assert fine.peak_ratios[term] <= refined * (1 + 1e-12), (term, fine.peak_ratios[term], refined)
    if plan.feasible:
        assert max(fine.peak_ratios.values()) <= 1.0
        assert fine.joint_range_ok


def test_refinement_finds_a_peak_between_samples(scenarios):
    """A coarse check rate misses the true peak; refinement recovers the fine-grid peak."""
    sc = scenarios["thesis-ch4"]
    plan = plan_with("thesis", sc)
    ls = sc.limit_set
    coarse = ls.report(plan.trajectory, 50.0, refine=False)
    refined = ls.report(plan.trajectory, 50.0, refine=True)
    fine = ls.report(plan.trajectory, 100000.0, refine=False)
    assert coarse.peak_moment_ratio < fine.peak_moment_ratio - 1e-5
    assert refined.peak_moment_ratio == pytest.approx(fine.peak_moment_ratio, rel=1e-6)
    assert refined.peak_moment_ratio >= fine.peak_moment_ratio * (1 - 1e-12)
    np.testing.assert_allclose(refined.peak_motor_torque_ratio, fine.peak_motor_torque_ratio, rtol=1e-6)


def test_gravity_time_scale_search_stays_within_the_family_budget():
    """With gravity the family optimum bisects the time scale; it must not sample motions slower
    than the family's slowest (all genes at their upper bounds): such samples once cost the
    crane-tray optimum all the machine's memory. Rows with no feasible scale within the budget
    are nan."""
    from qmt_drake.planners.optimum import tight_scale
    from qmt_drake.problem import PlanningProblem
    from qmt_drake.transfer_scenario import load_scenario
    sc = load_scenario("crane-tray")
    problem = PlanningProblem(sc)
    assert not problem.limit_set.time_scaling_is_exact
    genes = np.array([[0.05, 0.001], [0.3, 0.2], [1.0, 1.0]])
    lam = tight_scale(problem, genes)
    slowest = problem.family.motion_time_s(problem.upper[None])[0]
    T = problem.family.motion_time_s(genes) * lam
    assert np.all(np.isfinite(lam)) and np.all(T <= slowest * (1 + 1e-12))
    # tight: slightly faster breaks a limit, the found scale keeps them all
    assert np.all(problem.peaks(problem.family.time_scaled(genes, lam)).feasible)
    assert not np.any(problem.peaks(problem.family.time_scaled(genes, lam * (1 - 1e-6))).feasible)


def test_slow_down_search_stops_at_the_time_budget():
    """trajopt with the thesis arms' rows only (payload moment and effort, limit_rows="moment": no tray
    terms) tilts the tray: no slowing within the family's time budget keeps the bottle, so the plan is
    infeasible, quickly, instead of re-checking ever slower motions (finish.slow_to_limits_factor's cap)."""
    from qmt_drake.planners.baselines.finish import slowest_allowed_motion_s
    from qmt_drake.transfer_scenario import load_scenario
    sc = load_scenario("crane-tray")
    plan = plan_with("trajopt", sc, limit_rows="moment", **METHODS["trajopt"])
    assert not plan.feasible
    assert plan.motion_time_s <= slowest_allowed_motion_s(sc) * (1 + 1e-9)
    assert plan.extra["slowdown_factor"] * plan.extra["raw_check"]["motion_time_s"] <= slowest_allowed_motion_s(sc) * (1 + 1e-9)
