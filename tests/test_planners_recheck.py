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
