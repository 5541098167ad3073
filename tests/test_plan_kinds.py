"""One Plan type for every scenario kind (issue 18): plan_with gives an api.Plan for a transfer, a
spatial and an energy-time scenario; each writes a file that plan.load_plan reads back with no
scenario given (sample() equal to 1e-12 at random times) and refuses, in one line, when given a
scenario of another kind or another scenario of the same kind."""

from __future__ import annotations

import json

import numpy as np
import pytest

from qmt_drake import api
from qmt_drake.errors import QmtInputError
from qmt_drake.outcome import OUTCOMES
from qmt_drake.plan_files import load_plan

# kind -> (scenario, method, options): the quickest planner of each kind
CASES = {
    "transfer": ("thesis-ch4", "thesis", {}),
    "spatial_transfer": ("ur5-suction-bins", "toppra", {"n_grid": 300}),
    "energy_time": ("ohsaka-fig3", "snopt", {"pattern": (1, -1, -1)}),
}
# a scenario of each other kind, to give a plan file to
OTHER = {"transfer": "ur5-suction-bins", "spatial_transfer": "ohsaka-fig3", "energy_time": "thesis-ch4"}
SAME_KIND_OTHER = {"transfer": "thesis-ch2", "spatial_transfer": "ur5-magnet-part", "energy_time": "ohsaka-fig2"}


def _scenario(name):
    try:
        return api.load_scenario(name)
    except QmtInputError as exc:  # example-robot-data (a test extra) missing
        if "example-robot-data" not in str(exc):
            raise
        pytest.skip(str(exc))


@pytest.fixture(scope="module", params=sorted(CASES))
def planned(request, tmp_path_factory):
    name, method, options = CASES[request.param]
    sc = _scenario(name)
    plan = api.plan_with(method, sc, **options)
    path = tmp_path_factory.mktemp(request.param) / "plan.json"
    plan.write_json(path)
    return request.param, sc, plan, path


def test_plan_with_returns_an_api_plan_of_the_scenarios_kind(planned):
    kind, sc, plan, path = planned
    assert isinstance(plan, api.Plan) and plan.scenario_kind == kind and plan.scenario is sc
    s = plan.summary()
    assert s["scenario_kind"] == kind and s["motion_time_s"] == plan.motion_time_s > 0
    assert s["feasible"] is True and plan.check.feasible
    assert json.loads(path.read_text())["scenario_kind"] == kind
    q, qd, qdd = plan.sample(np.array([0.0, plan.motion_time_s]))
    assert q.shape == qd.shape == qdd.shape == (2, plan.n_dof)
    # the plan rests at both ends (every family and planner here starts and stops at rest)
    np.testing.assert_allclose(qd, 0.0, atol=1e-9)


def test_write_json_and_load_plan_round_trip(planned):
    kind, sc, plan, path = planned
    back = load_plan(path)  # the scenario reloaded from the file itself
    assert type(back) is type(plan) and back.scenario_kind == kind and back.method == plan.method
    assert back.scenario.name == sc.name
    assert back.motion_time_s == pytest.approx(plan.motion_time_s, rel=0, abs=1e-12)
    t = np.random.default_rng(7).uniform(0.0, plan.motion_time_s, 64)
    for a, b in zip(plan.sample(t), back.sample(t)):
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
    assert back.feasible == plan.feasible
    assert load_plan(path, sc).motion_time_s == back.motion_time_s  # and against the scenario given


@pytest.mark.parametrize("which", ["other kind", "same kind"])
def test_load_plan_refuses_a_file_given_with_the_wrong_scenario_in_one_line(planned, which):
    kind, sc, plan, path = planned
    other = _scenario(OTHER[kind] if which == "other kind" else SAME_KIND_OTHER[kind])
    with pytest.raises(QmtInputError) as e:
        load_plan(path, other)
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg and other.name in msg, msg
    if which == "other kind":
        assert f"plan for scenario {sc.name}, not one for the" in msg


def test_simulate_refuses_another_kinds_plan(planned):
    kind, sc, plan, _ = planned
    other = _scenario(OTHER[kind])
    with pytest.raises(QmtInputError) as e:
        api.simulate(other, plan)
    assert "\n" not in str(e.value) and f"plan for scenario {sc.name}, not for the" in str(e.value)


def test_an_energy_plan_file_keeps_the_old_keys_and_its_cost_is_recomputed(tmp_path):
    name, method, options = CASES["energy_time"]
    plan = api.plan_with(method, api.load_scenario(name), **options)
    path = tmp_path / "plan.json"
    plan.write_json(path)
    d = json.loads(path.read_text())
    for key in ("kind", "scenario", "method", "c1", "c2", "m", "divisions", "theta0_deg", "X0", "XT", "optima",
                "plan"):
        assert key in d, key
    assert d["kind"] == "energy_time" and set(d["plan"]) >= {"theta0_rad", "m", "x", "motion_time_s", "z", "z_fine"}
    # the cost the optimiser reported equals the plan's own (recomputed from x), and z = c2 T + c1 energy
    (opt,) = d["optima"]
    assert d["cost_z"] == pytest.approx(opt["z"], rel=1e-12)
    assert d["cost_z"] == pytest.approx(d["c2"] * plan.motion_time_s + d["c1"] * d["energy_integral_N2m2s"],
                                        rel=1e-12)
    # a file edited to end elsewhere is refused: the end is measured, not read
    d["trajectory"]["x"][0] += 0.05
    bad = path.with_name("bad.json")
    bad.write_text(json.dumps(d))
    with pytest.raises(QmtInputError, match="away from ohsaka-fig3's goal"):
        load_plan(bad)


def test_simulate_runs_every_kinds_plan_and_says_it_in_the_one_vocabulary(planned):
    """The shipped plans of each kind are carried as planned (thesis-ch4's reported genes, UR5 suction
    TOPP-RA: docs/spatial.md, ohsaka-fig3's optimum reaches its goal)."""
    kind, sc, plan, _ = planned
    r = api.simulate(sc, plan)
    assert r["outcome"] in OUTCOMES and r["held"] == (r["outcome"] == "carried")
    assert r["outcome"] == "carried", r["outcome"]
    assert r["final_goal_error_rad"] < 1e-3
