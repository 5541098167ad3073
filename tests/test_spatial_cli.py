"""The one CLI on spatial scenarios (issue 19): plan -> plan file -> simulate through main() in-process,
the CSV against its own finite differences, the plan file rebuilding the planned trajectory exactly,
the carried search's bracket, and one-line refusals (exit 2, no traceback)."""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from qmt_drake.apps.cli import main
from qmt_drake.config.scenario import SPATIAL_METHODS
from qmt_drake.errors import QmtInputError
from qmt_drake.outcome import OUTCOMES
from qmt_drake.planners.spatial_carried import carried_plan, carried_search
from qmt_drake.planners.spatial_methods import METHODS
from qmt_drake.planners.spatial_plan_io import REBUILD_TOL, load_spatial_plan, plan_file_dict
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.transfer_scenario import load_scenario
from tests.spatial_fixtures import shipped_toppra

SC = "ur5-suction-bins"


def _main(*argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in argv])
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def sc():
    try:
        return load_spatial_scenario(SC)
    except QmtInputError as exc:  # example-robot-data (a test extra) missing
        if "example-robot-data" not in str(exc):
            raise
        pytest.skip(str(exc))


@pytest.fixture(scope="module")
def planned(sc, tmp_path_factory):
    """The family optimum planned, written and co-simulated through the CLI (one run for the module)."""
    d = tmp_path_factory.mktemp("spatial_cli")
    plan, csv, sim = d / "p.json", d / "p.csv", d / "sim.json"
    rc, out, err = _main("plan", SC, "--method", "family_optimum", "--json", plan, "--trajectory-csv", csv, "--quiet")
    assert rc == 0, err
    rc_s, out_s, err_s = _main("simulate", SC, "--plan", plan, "--json", sim)
    assert rc_s == 0, err_s
    return {"dir": d, "plan": plan, "csv": csv, "sim": sim, "out": out, "out_sim": out_s}


def test_plan_prints_the_summary_and_writes_a_plan_file_that_holds(sc, planned):
    assert planned["out"].startswith(f"{SC} family_optimum: T = ")
    assert "x the TOPP-RA bound" in planned["out"] and "re-check max ratio" in planned["out"]
    d = json.loads(planned["plan"].read_text())
    assert d["scenario"] == SC and d["method"] == "family_optimum" and d["n_dof"] == 6
    assert d["recheck_max_ratio"] <= 1.0
    # the TOPP-RA bound printed is TOPP-RA's own duration: the via cubic cannot beat it on this path
    bound = shipped_toppra(SC).raw_duration_s
    assert f"{d['duration_s'] / bound:.4f} x the TOPP-RA bound {bound:.4f} s" in planned["out"]


def test_simulate_prints_the_outcome_word_and_writes_it(planned):
    r = json.loads(planned["sim"].read_text())
    assert r["outcome"] in OUTCOMES and r["held"] == (r["outcome"] == "carried")
    assert planned["out_sim"].startswith(f"{SC} family_optimum x1: {r['outcome']}")
    # the smooth family optimum stays inside the finer co-simulated grip set (the benchmark's finding)
    assert r["outcome"] == "carried" and r["final_goal_error_rad"] < 1e-3


def test_simulate_records_the_run(planned, tmp_path):
    """--record writes one self-contained Meshcat HTML file (the stick-figure arm, the part, the floor)."""
    rec = tmp_path / "rec.html"
    rc, out, err = _main("simulate", SC, "--plan", planned["plan"], "--record", rec)
    assert rc == 0 and f"recording {rec}" in out, err
    html = rec.read_text()
    assert len(html) > 100_000 and "meshcat" in html.lower()


def test_csv_velocity_is_the_derivative_of_its_position(planned):
    lines = planned["csv"].read_text().splitlines()
    assert lines[0].split(",")[:2] == ["t_s", "q1_rad"] and "qd6_rad_s" in lines[0] and "qdd6_rad_s2" in lines[0]
    a = np.loadtxt(planned["csv"], delimiter=",", skiprows=1)
    t, q, qd, qdd = a[:, 0], a[:, 1:7], a[:, 7:13], a[:, 13:19]
    h = 1e-3
    assert np.allclose(np.diff(t)[:-1], h, atol=1e-9) and np.abs(qd).max() > 1.0
    # Central difference on a piecewise cubic: |error| <= h^2/6 max|q'''|, and q''' (constant on each
    # piece) is the qdd column's own difference quotient; + the CSV's 12 digits (5e-12 rad / 2h).
    jerk = np.abs(np.diff(qdd, axis=0)).max(axis=0) / h
    i = np.flatnonzero(np.isclose(t[2:] - t[:-2], 2 * h, rtol=0, atol=1e-9)) + 1
    fd = (q[i + 1] - q[i - 1]) / (t[i + 1] - t[i - 1])[:, None]
    tol = h ** 2 / 6 * jerk + 1e-8
    assert np.all(np.abs(fd - qd[i]) <= tol), (np.abs(fd - qd[i]).max(axis=0), tol)
    assert np.abs(fd - qd[i]).max() > 1e-9  # the test sees the difference it bounds, not zeros


def test_plan_file_rebuilds_the_planned_trajectory(sc, planned):
    p = load_spatial_plan(planned["plan"], sc)
    a = np.loadtxt(planned["csv"], delimiter=",", skiprows=1)
    q, qd, qdd = p.trajectory.sample(a[:, 0])
    np.testing.assert_allclose(np.hstack([q, qd, qdd]), a[:, 1:], rtol=0, atol=1e-9)
    assert p.recheck["max"] <= 1.0 and p.pose_error.max() < 1e-6


@pytest.mark.parametrize("method", ["toppra", "ruckig", "trajopt"])
def test_every_trajectory_kind_rebuilds_exactly(sc, method, tmp_path):
    """plan_file_dict proves the rebuild on write; here the file is read back and compared once more."""
    rc, _, err = _main("plan", SC, "--method", method, "--json", tmp_path / "p.json", "--quiet")
    assert rc == 0, err
    p = load_spatial_plan(tmp_path / "p.json", sc)
    d = json.loads((tmp_path / "p.json").read_text())
    t = np.asarray(d["trajectory"]["t_s"])
    for key, got in zip(("q_rad", "qd_rad_s", "qdd_rad_s2"), p.trajectory.sample(t)):
        np.testing.assert_allclose(got, np.asarray(d["trajectory"][key]), rtol=0, atol=REBUILD_TOL, err_msg=key)
    assert abs(p.duration_s - d["duration_s"]) <= REBUILD_TOL


def test_a_tampered_plan_file_is_refused(sc, planned, tmp_path):
    d = json.loads(planned["plan"].read_text())
    spec = d["rebuild"]["inner"] if d["rebuild"]["kind"] == "time_scaled" else d["rebuild"]  # held by scale_to_hold
    spec["qd_rad_s"][1][0] += 0.1  # a via velocity changed by hand: the samples disagree
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    rc, out, err = _main("simulate", SC, "--plan", bad)
    assert rc == 2 and "differs from its own samples" in err and err.count("\n") == 1


def test_carried_search_brackets_the_fastest_carried_scale():
    """The magnet's TOPP-RA plan is lost as planned (benchmark); the bisection keeps a carried upper and
    a lost lower end, (k_max - 1) / 2^iterations apart, and every scale tried is consistent with it."""
    mg = load_spatial_scenario("ur5-magnet-part")
    tp = shipped_toppra("ur5-magnet-part", 400)
    s = carried_search(mg, tp, k_max=1.5, iterations=2)  # carried at 1.5 (benchmark: about 1.37)
    assert s["lost_below"] is not None and s["chosen"] is not None
    assert s["chosen"] - s["lost_below"] == pytest.approx(0.5 / 2 ** 2)
    for pt in s["points"]:
        assert (pt["outcome"] == "carried") == (pt["time_scale"] >= s["chosen"]), s["points"]
    p = carried_plan(mg, tp, s)
    assert p.method == "toppra-carried" and p.duration_s == pytest.approx(tp.duration_s * s["chosen"])
    assert p.recheck["max"] <= 1.0 and p.pose_error.max() < 1e-6  # measured again on the slowed plan
    assert plan_file_dict(mg, p)["rebuild"]["kind"] == "time_scaled"


def test_plan_carried_through_the_cli(sc, tmp_path):
    """--carried on the suction TOPP-RA plan: carried as planned (benchmark), so the search stops at
    x1 after one co-simulation, says so, and the file keeps the search and replays the same plan."""
    rc, out, err = _main("plan", SC, "--method", "toppra", "--carried", "--json", tmp_path / "c.json", "--quiet")
    assert rc == 0, err
    d = json.loads((tmp_path / "c.json").read_text())
    s = d["info"]["carried_search"]
    assert d["method"] == "toppra-carried" and s["chosen"] == 1.0 and s["lost_below"] is None
    assert [p["outcome"] for p in s["points"]] == ["carried"] and s["cosim"]["held"]
    assert out.rstrip().endswith("carried in the co-simulation at x1.0000, as planned")
    assert load_spatial_plan(tmp_path / "c.json", sc).duration_s == pytest.approx(d["duration_s"], abs=REBUILD_TOL)


@pytest.fixture(scope="module")
def planar_plan(tmp_path_factory):
    p = tmp_path_factory.mktemp("planar") / "ch4.json"
    rc, _, err = _main("plan", "thesis-ch4", "--method", "ga", "--generations", "5", "--json", p, "--quiet")
    assert rc == 0, err
    return p


@pytest.mark.parametrize("argv, needle", [
    (["plan", SC, "--method", "bogus"], "invalid choice: 'bogus'"),
    (["plan", SC, "--method", "thesis"], "--method thesis plans planar (kind: transfer) scenarios, not spatial (3-D) ones"),
    (["plan", SC, "--success", "1.5"], "--success 1.5 must be a probability in (0, 1)"),
    (["plan", SC, "--success", "0.9", "--carried"], "--carried and --success both choose the time scale"),
    (["plan", SC, "--method", "toppra", "--checkpoint", "c.pkl"], "--checkpoint: not an option of the spatial (3-D) "
     "toppra planner (the planners that take it: planar ga; spatial (3-D) ga; energy-time ga)"),
    (["plan", SC, "--method", "toppra", "--generations", "5"], "--generations: not an option of the spatial (3-D) toppra"),
    (["plan", SC, "--method", "toppra", "--option", "bogus=1"], "--option bogus: not an option of the spatial (3-D) "
     "toppra planner; it takes family, n_grid"),
    (["plan", SC, "--method", "toppra", "--option", "n_grid=1.5"], "--option n_grid 1.5 must be an integer"),
    (["plan", SC, "--carried", "--carried-max-scale", "0.5"], "--carried-max-scale 0.5 must exceed 1"),
    (["plan", SC, "--c2", "5"], "--c2: not an option of the spatial (3-D) ga planner (the planners that take it: "
     "planar snopt, ipopt, steepest and collocation; spatial (3-D) snopt"),
    (["simulate", SC, "--plan", "{missing}"], "does not exist"),
    (["simulate", SC, "--plan", "{planar}"], "is a planar plan for scenario thesis-ch4, not one for the spatial (3-D) scenario"),
    (["simulate", "thesis-ch4", "--plan", "{spatial}"], "is a spatial (3-D) plan for scenario ur5-suction-bins"),
    (["simulate", "ur5-magnet-part", "--plan", "{spatial}"], "was made for scenario ur5-suction-bins, not ur5-magnet-part"),
    (["simulate", SC, "--plan", "{spatial}", "--time-scale", "-1"], "--time-scale -1.0 must be a finite positive"),
    (["plan", SC, "--method", "ga", "--generations", "1000000"], "a spatial GA of population 40 x 1e+06 generations"),
    (["plan", SC, "--method", "ga", "--option", "population=10000000", "--allow-large"], "more memory than this machine"),
    (["simulate", SC, "--plan", "{spatial}", "--time-scale", "5000"], "a replay at time scale 5000"),
    (["simulate", SC, "--plan", "{spatial}", "--time-scale", "1e6", "--allow-large"], "more memory than this machine"),
    (["simulate", SC, "--plan", "{spatial}", "--actuator", "stepper"], "invalid choice: 'stepper'"),
    (["simulate", SC, "--plan", "{spatial}", "--feedforward", "none"], "applies to actuator dc_motor"),
    (["simulate", SC, "--plan", "{spatial}", "--explicit"], "the ideal actuator has no motor loop: add --actuator dc_motor"),
    (["simulate", SC, "--plan", "{spatial}", "--time-step-ms", "20"], "takes a plant step in (0, 5] ms"),
    (["simulate", "thesis-ch4", "--plan", "{planar}", "--actuator", "ideal"], "actuator.kind dc_motor_gear"),
    (["simulate", "ohsaka-fig3", "--actuator", "ideal"], "--actuator: seed 001's arm is driven by ideal torque sources"),
])
def test_refusals_are_one_line_exit_2(sc, planned, planar_plan, tmp_path, argv, needle):
    files = {"{missing}": tmp_path / "none.json", "{planar}": planar_plan, "{spatial}": planned["plan"]}
    rc, out, err = _main(*[files.get(a, a) for a in argv])
    assert rc == 2, (rc, out, err)
    assert needle in err and err.count("\n") == 1 and "Traceback" not in err, err


def test_load_scenario_points_to_the_cli_and_names_the_methods():
    assert SPATIAL_METHODS == METHODS
    with pytest.raises(QmtInputError, match=rf"qmt-drake plan {SC} --method toppra\|ruckig\|family_optimum\|ga\|"
                                            rf"trajopt\|toppra-drake\|snopt\|ipopt\|steepest\|collocation --json PLAN.json` .* `qmt-drake simulate {SC} --plan"):
        load_scenario(SC)


def test_plan_help_lists_the_spatial_methods():
    rc, out, _ = _main("scenarios")
    assert rc == 0 and f"{SC} spatial_transfer" in out
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit):
        main(["plan", "--help"])
    assert "Spatial (3-D) scenarios" in " ".join(buf.getvalue().split())
    assert "toppra, ruckig, family_optimum, ga, trajopt" in " ".join(buf.getvalue().split())


def test_a_tray_hand_plans_and_simulates_through_the_cli(tmp_path):
    """The tray hand's result has no cup-to-hand distance: the CLI says where the cup ended on the tray."""
    plan = tmp_path / "panda.json"
    rc, out, err = _main("plan", "panda-tray-cup", "--method", "toppra", "--json", plan, "--quiet")
    assert rc == 0, err
    rc, out, err = _main("simulate", "panda-tray-cup", "--plan", plan)
    assert rc == 0 and "Traceback" not in err, err
    assert out.startswith("panda-tray-cup toppra x1: carried") and "from its seat on the tray" in out


def test_simulate_through_dc_motors(planned):
    """--actuator dc_motor (the scenario's actuators.motor, full feedforward by default) on the planned
    family optimum: carried like the ideal run, with the motor columns in the JSON."""
    out = planned["dir"] / "dc.json"
    rc, text, err = _main("simulate", SC, "--plan", planned["plan"], "--actuator", "dc_motor", "--json", out)
    assert rc == 0, err
    d, ideal = json.loads(out.read_text()), json.loads(planned["sim"].read_text())
    assert d["actuator"] == "dc_motor" and ideal["actuator"] == "ideal"
    assert d["outcome"] == ideal["outcome"] == "carried" and text.startswith(f"{SC} family_optimum x1: carried")
    assert d["max_motor_torque_over_limit"] <= 1.0 + 1e-9 and len(d["max_current_A"]) == 6
