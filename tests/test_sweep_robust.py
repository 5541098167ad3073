"""Robust and carried planners: the bisections find the boundary they are built to find.

The co-simulation is replaced by rules with a known answer (a threshold per Monte Carlo draw, a
motion-time threshold), so the expected result follows in closed form; the planners are real."""


import numpy as np
import pytest

from qmt_drake.sweep import robust
from qmt_drake.sweep.runner import dask_client
from qmt_drake.sweep.spec import load_spec


@pytest.fixture(scope="module")
def client():
    """One local Dask cluster (2 workers) for the module's three searches: starting one costs ~4 CPU-s,
    and the searches' answers follow from their rules whatever the number of workers."""
    with dask_client(None, 2) as cl:
        yield cl


def fake_plan(ref):
    return {"plan_key": ref.key}


def threshold_case(case, plan_doc):
    """Carried iff the time scale reaches this draw's threshold 1 + (0.4 - friction)."""
    fr, s = case.parameters["friction"], case.sim["time_scale"]
    return {"key": case.key, "label": case.label, "parameters": case.parameters, "status": "ok",
            "held": s >= 1.0 + (0.4 - fr), "max_slip_m": 1e-4, "motion_time_s": 2.0 * s}


def test_robust_time_scale_finds_the_quantile(tmp_path, client):
    raw = {"name": "rb", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
           "monte_carlo": {"cases": 20, "seed": 5},
           "parameters": {"friction": {"dist": "uniform", "low": 0.2, "high": 0.4}}}
    spec = load_spec(raw)
    thresholds = np.sort([1.0 + (0.4 - d["friction"]) for d in spec.samples()])
    target = 0.9
    # smallest s with at least 90% of the 20 thresholds <= s: the 18th smallest threshold
    exact = thresholds[int(np.ceil(target * 20)) - 1]
    r = robust.robust_time_scale(spec, tmp_path, target=target, client=client, s_min=1.0, s_max=1.5,
                                 rel_tol=0.01, case_fn=threshold_case, plan_fn=fake_plan)
    assert r["found"] and r["p"] >= target
    assert exact <= r["time_scale"] <= exact * 1.01 + 1e-12
    pts = {h["time_scale"]: h["meets_target"] for h in r["history"]}
    assert all(ok == (s >= exact) for s, ok in pts.items())  # monotone, as the rule is
    # Unreachable target: every draw needs more than s_max = 1.05 for a few draws.
    r2 = robust.robust_time_scale(spec, tmp_path, target=0.999, client=client, s_min=1.0, s_max=1.05,
                                  case_fn=threshold_case, plan_fn=fake_plan)
    assert not r2["found"] and r2["time_scale"] is None


class Rule:
    T_star = None  # carried iff the executed motion lasts at least this long [s]


@pytest.fixture
def fake_cosim(monkeypatch):
    rule = Rule()

    def carried(scenario, plan, *, time_scale=1.0, feedforward="full", time_step_s=None):
        return {"held": plan.motion_time_s * time_scale >= rule.T_star, "max_slip_m": 1e-4,
                "detached_at_s": None}
    monkeypatch.setattr(robust, "carried_in_cosim", carried)
    return rule


def test_fastest_carried_ruckig_bisects_the_jerk_limit(fake_cosim, scenarios):
    sc = scenarios["thesis-ch2"]
    fake_cosim.T_star = fake_cosim_T = 3.0  # carried iff the motion lasts >= 3.0 s (bang-bang: 2.981 s)
    plan = robust.plan_fastest_carried(sc, "ruckig", jerk_range_m_s3=(1.0, 300.0), rel_tol=0.001)
    assert plan.feasible and plan.method == "ruckig-carried"
    assert fake_cosim_T <= plan.motion_time_s <= fake_cosim_T * 1.001
    s = plan.extra["carried_search"]
    assert s["lost_above"] > s["chosen"] and all(p["held"] == (p["motion_time_s"] >= 3.0) for p in s["points"])


def test_fastest_carried_time_scale_of_a_family_plan(fake_cosim, scenarios):
    sc = scenarios["thesis-ch4"]
    fake_cosim.T_star = 1.9  # the thesis plan (1.716 s) must be slowed by 1.9 / 1.716
    plan = robust.plan_fastest_carried(sc, "thesis", rel_tol=0.001)
    assert plan.feasible
    assert 1.9 <= plan.motion_time_s <= 1.9 * 1.001
    assert plan.peak_moment_ratio == pytest.approx(0.9996 * (1.716 / plan.motion_time_s) ** 2, rel=2e-3)


def test_plan_robust_returns_the_slowed_plan(tmp_path, problems, client):
    from qmt_drake.plan import family_plan
    P = problems["thesis-ch4"]
    plan = family_plan(P, P.genes_vector(P.scenario.reported["genes"]), "thesis")
    raw = {"name": "pr", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
           "monte_carlo": {"cases": 8, "seed": 1},
           "parameters": {"friction": {"dist": "uniform", "low": 0.3, "high": 0.4}}}
    slowed, r = robust.plan_robust(plan, raw, tmp_path, target=0.99, client=client, s_min=1.0, s_max=1.2,
                                   rel_tol=0.01, case_fn=threshold_case, plan_fn=fake_plan)
    assert slowed.motion_time_s == pytest.approx(plan.motion_time_s * r["time_scale"])
    assert slowed.feasible and slowed.method == "thesis-robust"
    assert slowed.peak_moment_ratio < plan.peak_moment_ratio



def test_fastest_carried_converged_refines_the_step_until_verdicts_agree(monkeypatch, scenarios):
    """A rule whose verdict depends on the step as drift does: at 2 ms a plan must last >= 1.9 s to
    be 'carried', at 1 ms and finer >= 1.8 s (the ch.4 thesis plan lasts 1.716 s). The 2 ms
    bracket's lost neighbour (~1.9 s) is carried at 1 ms, so 2 ms is not converged; the 1 ms
    bracket keeps its verdicts at 0.5 ms."""
    calls = []

    def carried(scenario, plan, *, time_scale=1.0, feedforward="full", time_step_s=None):
        calls.append(time_step_s)
        T_star = 1.9 if time_step_s >= 2e-3 else 1.8
        return {"held": plan.motion_time_s * time_scale >= T_star, "max_slip_m": 1e-4, "detached_at_s": None}
    monkeypatch.setattr(robust, "carried_in_cosim", carried)
    plan = robust.plan_fastest_carried_converged(scenarios["thesis-ch4"], "thesis", rel_tol=0.002)
    s = plan.extra["carried_search"]
    conv = s["convergence"]
    assert [c["time_step_s"] for c in conv] == [2e-3, 1e-3]
    assert not conv[0]["converged"] and conv[0]["lost_neighbour_at_check_step"]["held"]
    assert conv[0]["chosen_at_check_step"]["held"]
    assert 1.9 <= conv[0]["motion_time_s"] <= 1.9 * 1.002 + 1e-9
    assert conv[1]["converged"] and s["converged"] and s["time_step_s"] == 1e-3
    assert not conv[1]["lost_neighbour_at_check_step"]["held"]
    assert 1.8 <= plan.motion_time_s <= 1.8 * 1.002 + 1e-9
    assert conv[1]["lost_neighbour_motion_time_s"] < 1.8 <= plan.motion_time_s
    assert 0.5e-3 in calls and 0.25e-3 not in calls  # stopped at the first converged step
    # warm start: the 1 ms search's slow end is the 2 ms bracket's lost neighbour (carried at 1 ms)
    assert s["points"][1]["motion_time_s"] == pytest.approx(conv[0]["lost_neighbour_motion_time_s"], rel=1e-12)


def test_fastest_carried_converged_says_when_no_step_converges(monkeypatch, scenarios):
    def carried(scenario, plan, *, time_scale=1.0, feedforward="full", time_step_s=None):
        # the threshold keeps falling with the step: never converged
        return {"held": plan.motion_time_s * time_scale >= 1.75 + 100 * time_step_s, "max_slip_m": 1e-4,
                "detached_at_s": None}
    monkeypatch.setattr(robust, "carried_in_cosim", carried)
    plan = robust.plan_fastest_carried_converged(scenarios["thesis-ch4"], "thesis", steps_s=(2e-3, 1e-3),
                                                 rel_tol=0.002)
    s = plan.extra["carried_search"]
    assert s["converged"] is False and [c["converged"] for c in s["convergence"]] == [False, False]
    assert s["time_step_s"] == 1e-3  # the finest step tried is what is returned


def test_fastest_carried_time_scales_a_given_plan(fake_cosim, scenarios):
    """base_plan: the time-scale search runs on a plan the caller already has (no planning)."""
    from qmt_drake.planners import plan_with
    base = plan_with("thesis", scenarios["thesis-ch4"])
    fake_cosim.T_star = 1.8
    plan = robust.plan_fastest_carried(scenarios["thesis-ch4"], "mine", base_plan=base, rel_tol=0.001)
    assert plan.method == "mine-carried" and 1.8 <= plan.motion_time_s <= 1.8 * 1.001
    assert plan.extra["carried_search"]["chosen"] == pytest.approx(plan.motion_time_s / base.motion_time_s)


def test_plan_for_success_searches_the_lower_bound_and_checks_on_a_fresh_sweep(tmp_path, client):
    """plan --success P: the time scale whose Wilson lower bound reaches P under the scenario's
    uncertainty section, then a fresh sweep with another seed (the rule has a closed-form answer)."""
    from qmt_drake import load_scenario, plan_with
    sc = load_scenario("thesis-ch3", overrides={"uncertainty": {
        "parameters": {"friction": {"dist": "uniform", "low": 0.2, "high": 0.4}},
        "monte_carlo": {"cases": 30, "seed": 5}}})
    plan = plan_with("thesis", sc)
    pf = tmp_path / "p.json"
    plan.write_json(pf)
    slowed, summary = robust.plan_for_success(plan, pf, tmp_path, target=0.8, check_cases=40, s_max=1.5,
                                              client=client, case_fn=threshold_case, plan_fn=fake_plan)
    s = summary["search"]["time_scale"]
    assert summary["search"]["ci_low"] >= 0.8
    assert slowed.motion_time_s == pytest.approx(plan.motion_time_s * s, rel=1e-12)
    check = summary["fresh_check"]
    assert check["cases"] == 40 and check["seed"] != 5
    # the rule: carried iff s >= 1.4 - friction with friction ~ U(0.2, 0.4): P(carried) = (s - 1) / 0.2
    assert check["carried"] / 40 == pytest.approx(min(1.0, (s - 1.0) / 0.2), abs=0.2)


def test_success_needs_an_uncertainty_section_and_a_probability(capsys):
    from qmt_drake.apps.cli import main
    assert main(["plan", "thesis-ch3", "--method", "thesis", "--success", "0.9"]) == 2
    assert "no uncertainty section" in capsys.readouterr().err
    assert main(["plan", "thesis-ch4", "--method", "thesis", "--success", "1.5"]) == 2
    assert "a probability in (0, 1)" in capsys.readouterr().err
