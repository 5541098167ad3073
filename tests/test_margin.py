"""The verdict's margin (qmt_drake/margin.py): the cheap margin in every simulate result, consistent with
the outcome; the flip-scale bisection brackets a real flip; the half-step verdict is recorded."""

import numpy as np
import pytest

from qmt_drake.apps.benchmark import _half_step
from qmt_drake.errors import QmtInputError
from qmt_drake.margin import criterion, flip_time_scale, half_step_verdict, verdict_margin
from qmt_drake.margin_runs import (
    search_half_step,
    spatial_margin,
    spatial_plant_options,
    transfer_run,
    with_margin,
)
from qmt_drake.sim.reference import GenesPlan
from qmt_drake.sim.runner import run_transfer_simulate, simulate_transfer
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.transfer_scenario import load_scenario
from tests.spatial_fixtures import load_or_skip
from tests.test_actuator_names import lift

GA_GENES_CH4 = (0.622, 0.532, 0.562)  # seed 000 section 4.4: the GA's plan, on its moment limit


@pytest.fixture(scope="module")
def ch4():
    sc = load_scenario("thesis-ch4")
    return sc, GenesPlan(sc, GA_GENES_CH4, method="thesis_ga")


def check_consistent(d: dict) -> None:
    """ratio = value / threshold for every criterion; carried iff every ratio is below 1; the deciding
    criterion is the largest ratio among those of the outcome (all of them when carried)."""
    m = d["margin"]
    for c in m["criteria"]:
        assert c["ratio"] == pytest.approx(c["value"] / c["threshold"], rel=1e-12)
    ratios = [c["ratio"] for c in m["criteria"]]
    assert (d["outcome"] == "carried") == (max(ratios) < 1.0), m
    pool = m["criteria"] if d["outcome"] == "carried" else [c for c in m["criteria"] if c["outcome_over"] == d["outcome"]]
    assert m["ratio"] == max(c["ratio"] for c in pool)
    if d["outcome"] != "carried":
        assert m["outcome_over"] == d["outcome"] and m["ratio"] >= 1.0


def test_planar_result_states_its_margin(ch4):
    sc, plan = ch4
    d = run_transfer_simulate(sc, plan)
    check_consistent(d)
    slip = next(c for c in d["margin"]["criteria"] if c["outcome_over"] == "slipped")
    assert slip["value"] == d["max_slip_m"] and slip["threshold"] == 1e-3  # the held limit of sim/runner.py
    lost = run_transfer_simulate(sc, plan, time_scale=0.9)  # 23 % more acceleration than the moment limit
    assert lost["outcome"] != "carried"
    check_consistent(lost)


@pytest.mark.parametrize("duration_s", [1.0, 0.25])
def test_spatial_result_states_its_margin(duration_s):
    sc = load_or_skip("ur5-suction-bins")
    r = simulate_spatial(sc, lift(sc, duration_s))
    r["margin"] = spatial_margin(sc, r)
    check_consistent(r)
    assert r["margin"]["criteria"][0]["value"] == r["max_grip_ratio_while_held"]


def test_flip_scale_brackets_a_real_flip(ch4):
    sc, plan = ch4
    run = transfer_run(sc, plan)
    base = run(1.0, None)
    assert base["outcome"] == "carried"
    lines = []
    f = flip_time_scale(run, base, tolerance=0.01, max_runs=6, progress=lines.append)
    assert f["flip_time_scale"] is not None and f["runs"] == len(lines) <= 6
    assert f["lost_at"] < f["flip_time_scale"] < f["carried_at"] <= 1.0
    assert f["carried_at"] / f["lost_at"] - 1 <= 0.01 and f["converged"]
    # either side, run again through the co-simulation itself (not the margin's runner)
    assert simulate_transfer(sc, plan, time_scale=f["carried_at"], keep_series=False).held
    assert not simulate_transfer(sc, plan, time_scale=f["lost_at"], keep_series=False).held
    assert all(line.startswith("margin: run ") and " of at most 6: " in line for line in lines)


def test_half_step_verdict_is_recorded(ch4):
    sc, plan = ch4
    run = transfer_run(sc, plan)
    base = run(1.0, None)
    h = half_step_verdict(run, base, base["time_step_s"])
    assert h["half_step_s"] == base["time_step_s"] / 2
    assert h["verdict_at_half_step"] in ("carried", "lost") and h["slip_at_half_step"] >= 0.0
    assert h["changes_verdict"] == (h["verdict_at_half_step"] != "carried")
    s = search_half_step(sc, plan, feedforward="none")  # the carried search's report (plan command)
    assert s["half_step_s"] == 1e-3 and s["verdict_at_half_step"] == h["outcome_at_half_step"]
    assert s["slip_at_half_step"] == pytest.approx(h["slip_at_half_step"], rel=1e-12)


def test_benchmark_row_reads_the_half_step_from_the_converged_search():
    conv = {"check_step_s": 5e-4, "chosen_at_check_step": {"held": False, "outcome": "slipped", "max_slip_m": 1.2e-3}}
    assert _half_step({"convergence": [conv]}) == {"verdict_at_half_step": "slipped", "slip_at_half_step": 1.2e-3,
                                                   "flips_at_half_step": True, "half_step_s": 5e-4}


def test_margin_inputs_are_refused_in_one_line():
    with pytest.raises(QmtInputError, match="approximation"):
        spatial_plant_options(approximation="implicit")
    with pytest.raises(QmtInputError, match="1 ms divided"):
        spatial_plant_options(time_step_s=0.3e-3)
    m = verdict_margin("carried", [criterion("x", np.nan, 1.0, "slipped")])  # not measured: never deciding
    assert m["ratio"] is None and m["criteria"][0]["ratio"] is None


def test_energy_time_margin_is_its_final_error_and_says_why_there_is_no_flip():
    class EnergyLike:  # with_margin reads only the plan's kind
        scenario_kind = "energy_time"

    r = with_margin(None, EnergyLike(), {"reached_goal": True, "final_error_rad": 2e-4}, expensive=True)
    assert r["margin"]["quantity"] == "final_error_rad" and r["margin"]["ratio"] == pytest.approx(0.2)
    assert r["margin"]["flip"].startswith("not available")
