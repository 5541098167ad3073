"""The fastest-carried searches' every-cell option (qmt_drake/carried_cells.py, issue 29 item 4): a scale lost
at one cell is raised to the smallest scale carried at every cell; a cell Drake cannot build is 'n/a' and
does not count; bad cells stop in one line (the API and `--carried-cells`, exit 2)."""

from types import SimpleNamespace

import pytest

from qmt_drake.apps.cli import main as cli_main
from qmt_drake.carried_cells import (
    RAISE_FACTOR,
    carried_at_every_cell,
    check_cells,
    parse_cells,
    resolve_cells,
    scenario_at,
    spatial_cell_runner,
    spatial_default_cell,
    transfer_cell_runner,
    transfer_default_cell,
)
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import hand_plugin
from qmt_drake.planners import plan_with
from qmt_drake.sim.sim_settings import APPROXIMATION_ENUMS
from qmt_drake.sweep.robust import carried_in_cosim
from qmt_drake.transfer_scenario import load_scenario
from tests.spatial_fixtures import load_or_skip, shipped_toppra

ALL_1MS = resolve_cells("all", 1e-3)


def stand_in(thresholds: dict, na=("tamsi",), calls=None):
    """run(k, h, a): carried iff k is in none of the cell's lost intervals (default: lost below 1.0), the
    slip falling with k; approximations in `na` cannot run. calls: every (k, h, a) run, appended."""
    def run(k, h, a):
        if calls is not None:
            calls.append((k, h, a))
        if a in na:
            return {"outcome": "n/a", "held": None, "error": "TAMSI does not support weld constraints"}
        held = not any(lo <= k < hi for lo, hi in thresholds.get((h, a), [(0.0, 1.0)]))
        slip = 1e-3 / k
        return {"outcome": "carried" if held else "slipped", "held": held, "quantity": "max_slip_m",
                "value": slip, "threshold": 1e-3, "ratio": slip / 1e-3, "slip_m": slip}
    return run


def test_a_scale_lost_at_one_cell_is_raised_to_the_smallest_scale_carried_everywhere():
    calls = []
    run = stand_in({(0.25e-3, "lagged"): [(0.0, 1.03)]}, calls=calls)
    r = carried_at_every_cell(run, 1.0, ALL_1MS, k_max=2.0, rel_tol=0.002, default_cell=(1e-3, "sap"))
    assert r["raised"] and r["status"] == "raised"
    assert 1.03 <= r["time_scale"] <= 1.03 * 1.002 + 1e-12  # within the stated relative tolerance
    assert r["lost_below"] < 1.03 and r["time_scale"] / r["lost_below"] - 1 <= 0.002 + 1e-12
    assert r["table_at_chosen"]["0.25 ms lagged"]["held"] is False
    assert all(c["held"] is not False for c in r["table"].values())
    assert [k for k, c in r["table"].items() if c["held"] is None] == ["1 ms tamsi", "0.5 ms tamsi", "0.25 ms tamsi"]
    assert r["default_cell"] == "1 ms sap" and len(r["cells"]) == 12
    # the tries ran only the lost cell; the answer ran at all twelve
    tried = {(h, a) for k, h, a in calls if k not in (1.0, r["time_scale"])}
    assert tried == {(0.25e-3, "lagged")}
    assert r["runs"] == len(set(calls)) == len(calls)  # memoised: no cell run twice at a scale
    assert r["relative_to_chosen"] == pytest.approx(r["time_scale"] - 1.0)


def test_a_cell_lost_only_above_the_chosen_scale_joins_the_raise():
    # 1 ms similar carries x1 and loses [1.025, 1.06): the first answer (~1.03) is lost there, so it goes on
    run = stand_in({(1e-3, "lagged"): [(0.0, 1.03)], (1e-3, "similar"): [(1.025, 1.06)]})
    r = carried_at_every_cell(run, 1.0, ALL_1MS, k_max=2.0, rel_tol=0.002)
    assert 1.06 <= r["time_scale"] <= 1.06 * 1.002 + 1e-12
    assert r["table_at_chosen"]["1 ms similar"]["held"] is True
    assert any("1 ms similar" in t["outcomes"] for t in r["tries"])
    assert all(c["held"] is not False for c in r["table"].values())


def test_carried_everywhere_at_the_chosen_scale_is_kept_and_not_carried_up_to_k_max_is_none():
    calls = []
    r = carried_at_every_cell(stand_in({}, calls=calls), 1.1, ALL_1MS, k_max=2.0)
    assert r["time_scale"] == 1.1 and not r["raised"] and r["lost_below"] is None and len(calls) == 12
    lost = carried_at_every_cell(stand_in({(1e-3, "sap"): [(0.0, 5.0)]}), 1.1, ALL_1MS, k_max=1.3)
    assert lost["time_scale"] is None and lost["status"] == "not_carried" and lost["lost_below"] == 1.3
    assert max(t["time_scale"] for t in lost["tries"]) == 1.3  # growth by RAISE_FACTOR, clipped to k_max
    assert RAISE_FACTOR > 1


def test_cells_and_the_cli_flag_are_checked_in_one_line():
    assert parse_cells("all") == "all"
    assert parse_cells("1:sap, 0.25:lagged,1:sap") == [(1e-3, "sap"), (0.25e-3, "lagged")]
    assert resolve_cells([(5e-4, "similar")], 1e-3) == [(5e-4, "similar")]
    assert resolve_cells("all", 2e-3)[-1] == (0.5e-3, "lagged")
    for bad in ("", "1:foo", "0:sap", "-1:sap", "x:sap", "1sap", "nan:sap", "1:sap,", "ALL"):
        with pytest.raises(QmtInputError, match="--carried-cells") as e:
            parse_cells(bad)
        assert "\n" not in str(e.value)
    for bad in ([], [(0, "sap")], [(1e-3,)], "some", [(True, "sap")], 3, [(1e-3, "SAP")]):
        with pytest.raises(QmtInputError, match="cells"):
            check_cells(bad)


@pytest.mark.parametrize("argv, needle", [
    (["plan", "crane-tray", "--method", "toppra", "--carried-cells", "all"], "an option of --carried"),
    (["plan", "crane-tray", "--method", "toppra", "--carried", "--carried-cells", "1:foo"], "--carried-cells"),
    (["plan", "ur5-suction-bins", "--method", "toppra", "--carried", "--carried-cells", "0.3:sap"], "1 ms divided"),
    (["plan", "crane-tray", "--method", "toppra", "--carried", "--carried-cells", "5:sap"], "control period"),
])
def test_bad_carried_cells_stop_the_cli_with_exit_2(argv, needle, capsys):
    assert cli_main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and "Traceback" not in err[0], err


def test_a_cell_drake_cannot_build_is_na_with_drakes_reason():
    sc = load_or_skip("ur5-suction-bins")
    assert spatial_default_cell(sc) == (1e-3, "sap")
    cell = spatial_cell_runner(sc, shipped_toppra("ur5-suction-bins").trajectory)(1.0, 1e-3, "tamsi")
    assert cell["outcome"] == "n/a" and cell["held"] is None and "TAMSI" in cell["error"]


def test_the_transfer_default_cell_is_the_searchs_own_run_and_the_approximation_reaches_the_plant():
    sc = load_scenario("crane-tray")
    plan = plan_with("ruckig", sc)  # (1 s to plan; TOPP-RA's 3-12 s)
    assert transfer_default_cell(sc) == (1e-3, "lagged")
    own = carried_in_cosim(sc, plan, time_scale=1.03)  # the carried search's predicate at its default cell
    lagged = transfer_cell_runner(sc, plan)(1.03, 1e-3, "lagged")
    assert own["max_tilt_rad"] > 0
    assert (lagged["held"], lagged["slip_m"], lagged["max_tilt_rad"]) == (own["held"], own["max_slip_m"],
                                                                          own["max_tilt_rad"])  # bit for bit
    assert lagged["quantity"] is not None and lagged["ratio"] == pytest.approx(lagged["value"] / lagged["threshold"])
    for a, enum in APPROXIMATION_ENUMS.items():  # each cell's plant is built with its approximation and step
        cosim = hand_plugin(sc).build_cosim(scenario_at(sc, a), plan, time_scale=1.03, time_step_s=0.25e-3)
        assert (cosim.plant.get_discrete_contact_approximation(), cosim.plant.time_step()) == (enum, 0.25e-3)


def test_the_spatial_search_takes_the_raised_scale_and_without_cells_is_unchanged(monkeypatch):
    import qmt_drake.planners.spatial_carried as spatial_carried

    def factor(traj):
        return getattr(traj, "factor", 1.0)

    def sim(sc, traj, **kw):  # the default cell: carried from x1.1
        held = factor(traj) >= 1.1
        return {"outcome": "carried" if held else "detached", "held": held, "max_grip_ratio_while_held": 1.0}

    monkeypatch.setattr(spatial_carried, "simulate_spatial", sim)
    monkeypatch.setattr(spatial_carried, "spatial_half_step", lambda sc, traj, **kw: {
        "half_step_s": 5e-4, "verdict_at_half_step": "carried", "flips_at_half_step": False, "k": factor(traj)})
    monkeypatch.setattr(spatial_carried, "spatial_cell_runner", lambda sc, traj, **kw: stand_in(
        {(0.25e-3, "lagged"): [(0.0, 1.2)]} | {c: [(0.0, 1.1)] for c in ALL_1MS if c != (0.25e-3, "lagged")}))
    sc = SimpleNamespace(name="stand-in", hand_kind="suction", hand_physics="weld")
    plan = SimpleNamespace(trajectory=SimpleNamespace(duration_s=2.0, sample=None), duration_s=2.0, method="toppra")
    plain = spatial_carried.carried_search(sc, plan)
    assert "every_cell" not in plain and 1.1 <= plain["chosen"] < 1.12
    s = spatial_carried.carried_search(sc, plan, cells="all")
    every = s["every_cell"]
    assert every["chosen_at_default_cell"] == plain["chosen"] and every["raised"]
    assert s["chosen"] == every["time_scale"] and 1.2 <= s["chosen"] <= 1.2 * 1.002
    assert s["lost_below"] == every["lost_below"] < 1.2
    assert s["cosim"]["held"] and s["points"][-1]["time_scale"] == s["chosen"]  # its default-cell run
    assert s["half_step"]["k"] == s["chosen"]
    assert {k for k in s if k != "every_cell"} == set(plain)
