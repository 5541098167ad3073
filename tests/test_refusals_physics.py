"""Issue 27 item 6: a refusal remains only where physics makes the combination meaningless, and says so;
the other feature x kind cells of docs/features.md run (session 13, helper refusals)."""

from __future__ import annotations

import json

import pytest

from qmt_drake.actuators import check_own_actuator
from qmt_drake.errors import QmtInputError
from qmt_drake.transfer_scenario import load_scenario


def test_planar_simulate_with_its_own_actuator_says_which_ran(thesis_plan_file, tmp_path):
    import json

    from qmt_drake.apps.cli import main
    out = tmp_path / "s.json"
    assert main(["simulate", "thesis-ch4", "--plan", str(thesis_plan_file), "--actuator", "dc_motor", "--quiet",
                 "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["actuator"] == "dc_motor" and d["actuator_kind"] == "dc_motor_gear" and d["outcome"] == "carried"


def test_planar_actuator_flag_names_the_yaml_actuator():
    thesis = load_scenario("thesis-ch4")
    check_own_actuator(thesis, None)
    check_own_actuator(thesis, "dc_motor")  # its YAML actuator: DC motors with gears
    with pytest.raises(QmtInputError, match="actuator.kind dc_motor_gear \\(--actuator dc_motor\\)"):
        check_own_actuator(thesis, "ideal")
    tray = load_scenario("crane-tray")
    with pytest.raises(QmtInputError, match="Dynamixel position servos .* firmware closes the position loop"):
        check_own_actuator(tray, "dc_motor")


@pytest.fixture(scope="module")
def energy_plan(tmp_path_factory):
    from qmt_drake.apps.cli import main
    pj = tmp_path_factory.mktemp("energy") / "p.json"
    assert main(["plan", "ohsaka-fig3", "--method", "snopt", "--pattern=+--", "--json", str(pj), "--quiet"]) == 0
    return pj


def test_energy_time_margin_is_the_final_error_against_the_arrival_tolerance(energy_plan, tmp_path, capsys):
    import json

    from qmt_drake.apps.cli import main
    from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    sj = tmp_path / "s.json"
    assert main(["simulate", "ohsaka-fig3", "--plan", str(energy_plan), "--margin", "--json", str(sj)]) == 0
    s = json.loads(sj.read_text())
    m = s["margin"]
    assert m["quantity"] == "final_error_rad" and m["value"] == s["final_error_rad"]
    assert m["threshold"] == ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    assert m["ratio"] == pytest.approx(s["final_error_rad"] / ARRIVAL_TOLERANCE_DC_MOTOR_RAD, rel=1e-12)
    assert s["reached_goal"] == (m["ratio"] <= 1.0)
    assert "ideal, unlimited torque sources" in m["flip"]
    assert "margin: final_error_rad" in capsys.readouterr().out


@pytest.mark.parametrize("argv,reason", [
    (["--actuator", "dc_motor"], "ideal torque sources (the paper models no motor"),
    (["--explicit"], "no motor-voltage loop to step explicitly"),
    (["--feedforward", "back-emf"], "no motor voltage and no back-EMF"),
])
def test_energy_time_simulate_refusals_state_the_physics(energy_plan, capsys, argv, reason):
    from qmt_drake.apps.cli import main
    assert main(["simulate", "ohsaka-fig3", "--plan", str(energy_plan), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert reason in err and "\n" not in err and "Traceback" not in err


def test_energy_time_simulate_takes_a_plant_step_and_refuses_one_out_of_range(energy_plan, tmp_path, capsys):
    """--time-step-ms makes seed 001's plant discrete at that step (the default: continuous); the tracking
    error shrinks towards the continuous run's as the step does (a discrete plant converging, not a flag)."""
    from qmt_drake.apps.cli import main
    errors = {}
    for step in (None, "1", "0.25"):
        sj = tmp_path / f"s{step}.json"
        assert main(["simulate", "ohsaka-fig3", "--plan", str(energy_plan), "--json", str(sj), "--quiet",
                     *(["--time-step-ms", step] if step else [])]) == 0
        s = json.loads(sj.read_text())
        assert s["time_step_s"] == (None if step is None else float(step) * 1e-3)
        errors[step] = s["max_tracking_error_rad"]
    assert errors[None] < errors["0.25"] < errors["1"]
    for bad in ("0", "-1", "20", "nan"):
        assert main(["simulate", "ohsaka-fig3", "--plan", str(energy_plan), "--time-step-ms", bad]) == 2
        err = capsys.readouterr().err.strip()
        assert "plant step in (0, 10] ms (default" in err and "--time-step-ms" in err and "\n" not in err


@pytest.fixture(scope="module")
def thesis_plan_file(tmp_path_factory):
    from qmt_drake.apps.cli import main
    pj = tmp_path_factory.mktemp("thesis") / "p.json"
    assert main(["plan", "thesis-ch4", "--method", "thesis", "--json", str(pj), "--quiet"]) == 0
    return pj


def test_export_of_a_planar_plan_streams_its_samples_and_rechecks_the_interpolation(thesis_plan_file, tmp_path):
    import json

    import numpy as np

    from qmt_drake.apps.cli import main
    from qmt_drake.export import LinearStream
    from qmt_drake.plan import recheck
    from qmt_drake.plan_files import load_plan
    sc = load_scenario("thesis-ch4")
    plan = load_plan(thesis_plan_file, scenario=sc)
    out, rep = tmp_path / "s.csv", tmp_path / "r.json"
    rc = main(["export", str(thesis_plan_file), "--scenario", "thesis-ch4", "--format", "csv", "--rate", "125",
               "--interp", "linear", "--out", str(out), "--json", str(rep)])
    r = json.loads(rep.read_text())
    assert rc == (0 if r["stream_holds"] else 3)
    head, *rows = out.read_text().splitlines()
    assert head.split(",") == ["time_s", *sc.arm.joint_names]
    data = np.array([[float(v) for v in row.split(",")] for row in rows])
    t, q = data[:, 0], data[:, 1:]
    assert np.allclose(np.diff(t), 1 / 125) and t[-1] >= plan.motion_time_s
    np.testing.assert_array_equal(q, plan.sample(np.minimum(t, plan.motion_time_s))[0])
    # the linear stream's evaluate (what the planar report refines on) is its sample() inside each interval
    lin = LinearStream(t, q)
    mid = 0.5 * (t[1:] + t[:-1])
    for a, b in zip(lin.evaluate(mid, mid), lin.sample(mid)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(lin.evaluate(mid, mid)[1], np.diff(q, axis=0) * 125, rtol=1e-12)
    own = recheck(sc, lin, r["stream_recheck"]["check_rate_hz"])
    assert r["stream_recheck"]["max"] == pytest.approx(own.worst_ratio, rel=1e-12)
    assert r["stream_recheck"]["binding"] == max(own.peak_ratios, key=own.peak_ratios.get)
    assert r["stream_peak_jerk"]["peak_jerk_ratio"] is None  # a planar scenario states no jerk limit


def test_export_of_an_energy_time_plan_checks_the_yaml_torque_limits(energy_plan, tmp_path):
    """The stream's torques, recomputed here by Drake's own inverse dynamics (not the PlanarChain the export
    uses) from the CSV's positions at 125 Hz and the plan's own velocities/accelerations there, agree with
    the plan; the report's ratio is the joint torque over the YAML's 200 N m limits."""
    import json

    import numpy as np

    from qmt_drake.apps.cli import main
    from qmt_drake.energy.dynamics import drake_inverse_dynamics
    from qmt_drake.energy.scenario import get_experiment
    from qmt_drake.plan_files import load_plan
    E = get_experiment("ohsaka-fig3")
    plan = load_plan(energy_plan, E)
    out, rep = tmp_path / "s.csv", tmp_path / "r.json"
    rc = main(["export", str(energy_plan), "--scenario", "ohsaka-fig3", "--format", "csv", "--rate", "125",
               "--interp", "cubic", "--out", str(out), "--json", str(rep)])
    r = json.loads(rep.read_text())
    assert rc == (0 if r["stream_holds"] else 3)
    head, *rows = out.read_text().splitlines()
    assert head == "time_s,joint1,joint2,joint3"
    data = np.array([[float(v) for v in row.split(",")] for row in rows])
    t = np.minimum(data[:, 0], plan.motion_time_s)
    q, qd, qdd = plan.sample(t)
    np.testing.assert_array_equal(data[:, 1:], q)
    tau = np.abs(drake_inverse_dynamics(q, qd, qdd)) / np.asarray(E.torque_limit_Nm)
    own = r["plan_recheck_same_rate"]  # sampled at 10 kHz: at least the 125 Hz samples' peak
    for j, name in enumerate(("joint1", "joint2", "joint3")):
        assert own[f"joint_torque[{name}]"] >= tau[:, j].max() * (1 - 1e-9)


@pytest.mark.parametrize("name", ["thesis-ch4", "crane-tray"])
def test_retime_of_a_planar_path_keeps_its_waypoints_and_its_limits_between_samples(name):
    """A path through 6 postures of the scenario's own thesis plan, retimed by TOPP-RA under the planar
    limit set: the timed motion passes every waypoint (to 1e-6 rad), starts and ends at rest, and every
    limit column sampled 5x finer than the re-check (50 kHz) stays within 1e-6 of its limit."""
    import numpy as np

    from qmt_drake.planners import plan_with
    from qmt_drake.retime_planar import retime_planar_path
    sc = load_scenario(name)
    base = plan_with("thesis", sc)
    Q = base.sample(np.linspace(0.0, base.motion_time_s, 6))[0]
    p = retime_planar_path(sc, Q, n_grid=400)
    assert p.feasible and p.method == "retime_toppra"
    t = np.linspace(0.0, p.motion_time_s, int(p.motion_time_s * 50_000) + 1)
    q, qd, qdd = p.sample(t)
    for w in Q:
        assert np.min(np.linalg.norm(q - w, axis=1)) < 1e-3  # on the 50 kHz grid: 1e-3 rad
    np.testing.assert_allclose(q[[0, -1]], Q[[0, -1]], atol=1e-9)
    assert np.abs(qd[[0, -1]]).max() < 1e-6
    ls = sc.limit_set
    cols = ls.columns(q, qd, qdd)[:, ls.ratio_mask]
    assert cols.max() <= 1.0 + 1e-6
    assert cols.max() > 0.98  # the fastest timing: some limit is reached


def test_retime_refusals_on_planar_and_energy_state_why(capsys):
    from qmt_drake.apps.cli import main
    # seed 001's fig. 2 states no torque limit: no fastest timing of a path exists (fig. 3's YAML has them: it retimes)
    assert main(["retime", "ohsaka-fig2", "--path", "x.csv"]) == 2
    assert "a minimum-time plan needs the joints' torque limits" in capsys.readouterr().err
    assert main(["retime", "thesis-ch4", "--path", "x.csv", "--method", "ga"]) == 2
    assert "retimed with --method toppra" in capsys.readouterr().err


def test_toppra_drake_on_a_spatial_arm_takes_the_joint_limits_and_the_recheck_holds_the_rest():
    """Drake's Toppra on the UR5 magnet's IK'd path (200 grid points): its s(t) rebuilt as a
    ToppraTrajectory has Drake's own duration (to 1e-9 relative, before the hold), the plan names the
    limits Drake's Toppra could not take, and the project's full re-check holds at 10x its rate (the
    slow-down >= 1); never faster than the project's TOPP-RA on the same path with every row."""
    from qmt_drake.planners import registry
    from qmt_drake.planners.spatial_trajectory import check
    from qmt_drake.spatial_task import load_spatial_scenario
    sc = load_spatial_scenario("ur5-magnet-part")
    p = registry.plan(sc, "toppra-drake", n_grid=200)
    assert p.method == "toppra-drake" and p.feasible
    assert p.info["not_in_drake_toppra"] == ["motor_torque", "magnet_moment"]
    assert p.raw_duration_s == pytest.approx(p.info["drake_duration_s"], rel=1e-9)
    assert p.hold_scale >= 1.0
    assert check(sc, p.trajectory, 10 * sc.recheck_rate_hz)["max"] <= 1.0 + 1e-6
    full = registry.plan(sc, "toppra", n_grid=200)
    assert p.duration_s >= full.duration_s * (1 - 1e-6)
