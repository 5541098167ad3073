"""Issue 27 item 6: `--method collocation` on the planar and spatial arms (energy/collocation_kinds.py) and
`retime` on seed 001's arm (its joint-space transfer), each plan checked by an independent sampler: Drake's
CalcInverseDynamics on a separate plant (tests/test_energy_cross_kind's helpers) at 10x the plan's re-check rate.
Small knot counts keep them to seconds."""

import json

import numpy as np
import pytest

from qmt_drake.apps.cli import main
from qmt_drake.energy.as_transfer import load_transfer_plan, transfer_scenario_of
from qmt_drake.energy.cross_kind import plan_energy_time_transfer
from qmt_drake.energy.dynamics import drake_inverse_dynamics
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.plan_files import load_plan
from qmt_drake.planners import registry
from qmt_drake.planners.baselines.paths import task_joint_points
from qmt_drake.planners.spatial_plan_io import load_spatial_plan
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.transfer_scenario import load_scenario
from tests.test_energy_cross_kind import _drake_planar_torques, _drake_torques


def _times(T: float, rate_hz: float) -> np.ndarray:
    return np.linspace(0.0, T, int(np.ceil(T * 10 * rate_hz)) + 1)


def test_collocation_plans_the_planar_magnet_arm(tmp_path):
    """plan_with("collocation", thesis-ch4, knots=3) (the registry's row of `plan --method collocation`): a feasible plan through the task's points, at
    rest at both ends, whose acceleration is continuous at the knots (the Hermite-Simpson defects are the
    double integrator's exact integration), whose motor torques by Drake at 10x the re-check rate hold, whose z
    recomputed from them is the plan's, and which costs less than the family's SNOPT optimum it started from."""
    sc = load_scenario("thesis-ch4")
    lines: list[str] = []
    plan = registry.plan(sc, "collocation", knots=3, progress=lines.append)
    x = plan.extra
    # a line for the seed and one per solve (a long run says where it is)
    assert lines[0].startswith("collocation: seeded") and len(lines) == 2 + x["refine_rounds"]
    assert plan.feasible and plan.method == "collocation" and x["converged"] and x["knots_per_segment"] == 3
    q, qd, _ = plan.sample([0.0, plan.motion_time_s])
    pts = task_joint_points(sc)
    assert np.allclose(q, pts[[0, -1]], atol=1e-9) and np.allclose(qd, 0.0, atol=1e-6)  # qd one-sided 1e-9 s inside (trajectory.ONE_SIDED_S)
    knots = np.r_[0.0, np.cumsum(np.repeat(np.asarray(x["segment_times_s"]) / 3, 3))] * x.get("slowdown_factor", 1.0)
    assert np.allclose(plan.sample(knots[::3])[0], pts, atol=1e-7)  # every task point at its knot
    a = plan.trajectory.evaluate(knots[1:-1], knots[1:-1] - 1e-6)[2]
    b = plan.trajectory.evaluate(knots[1:-1], knots[1:-1] + 1e-6)[2]
    assert np.max(np.abs(a - b)) < 1e-5 * np.max(np.abs(a))
    t = _times(plan.motion_time_s, sc.sampling.check_rate_hz)
    qs, qds, qdds = plan.sample(t)
    tau = _drake_planar_torques(sc.arm, qs, qds, qdds)
    assert np.max(np.abs(tau) / (sc.gear_ratio * np.asarray(sc.limits.motor_torque_limit_Nm))) <= 1.0 + 1e-9
    z = x["c1"] * np.trapezoid(np.sum(tau * tau, axis=1), t) + x["c2"] * plan.motion_time_s
    assert z == pytest.approx(x["z"], rel=1e-3)
    family = plan_energy_time_transfer(sc, method="snopt")
    assert x["z"] < family.extra["z"] and x["z"] < x["start_z"]
    # its plan file (1 kHz samples, the quintic between them) re-checks as the plan did: each breakpoint's q, qd
    # stored AT it (a one-sided 1e-9 s inset once made the reload 1.0027 of the moment limit, infeasible)
    plan.write_json(tmp_path / "c.json")
    again = load_plan(tmp_path / "c.json", sc)
    assert again.feasible
    assert again.check.peak_moment_ratio == pytest.approx(plan.check.peak_moment_ratio, abs=1e-6)


def test_collocation_plans_a_spatial_arm(tmp_path, capsys):
    """`plan ur5-magnet-part --method collocation --option knots=2`: a spatial plan held at its re-check rate
    without a slow-down (its magnet term is partly balanced by the motion, which no slow-down keeps), through
    the task poses, whose torques by Drake at 10x the re-check rate hold and whose z recomputed from them is
    the plan's, below the via cubic's SNOPT optimum it started from."""
    path = tmp_path / "c.json"
    assert main(["plan", "ur5-magnet-part", "--method", "collocation", "--option", "knots=2", "--quiet",
                 "--json", str(path)]) == 0
    sc = load_spatial_scenario("ur5-magnet-part")
    plan = load_spatial_plan(path, sc)
    info = json.loads(path.read_text())["info"]
    assert plan.feasible and plan.recheck["max"] <= 1.0 and info["z"] < info["start_z"]
    q = plan.sample(plan.pose_times_s)[0]
    assert np.allclose(q, sc.q_poses_rad, atol=1e-7)
    t = _times(plan.motion_time_s, sc.recheck_rate_hz)
    tau = _drake_torques(sc, *plan.sample(t))
    assert np.max(np.abs(tau) / sc.torque_limit_Nm) <= 1.0 + 1e-9
    z = info["c1"] * np.trapezoid(np.sum(tau * tau, axis=1), t) + info["c2"] * plan.motion_time_s
    assert z == pytest.approx(info["z"], rel=1e-3)


@pytest.mark.parametrize("option,msg", [("knots=1", "knots = 1"), ("knots=2.5", "--option knots 2.5 must be an integer")])
def test_bad_knots_exit_2_one_line(option, msg, capsys):
    assert main(["plan", "thesis-ch4", "--method", "collocation", "--option", option, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and "\n" not in err and "Traceback" not in err


def test_retime_times_a_path_of_the_energy_arm_under_its_torque_limits(tmp_path, capsys, monkeypatch):
    """`retime ohsaka-fig3 --path path.csv`: TOPP-RA along a joint path of seed 001's arm (its joint-space
    transfer) under its joint torque limits; Drake's torques at 10x the re-check rate reach the limit and never
    pass it; `simulate ohsaka-fig3 --plan` runs the file in seed 001's execution; ohsaka-fig2 (no torque
    limits: no fastest timing) is refused in one line."""
    monkeypatch.chdir(tmp_path)
    E = get_experiment("ohsaka-fig3")
    sc = transfer_scenario_of(E)
    Q = np.linspace(sc.q_poses_rad[0], sc.q_poses_rad[1], 6)
    Q[1:-1, 1] += 0.2 * np.sin(np.linspace(0, np.pi, 6)[1:-1])  # a path that is not the straight line
    (tmp_path / "path.csv").write_text(",".join(sc.joint_names) + "\n"
                                       + "\n".join(",".join(repr(float(v)) for v in r) for r in Q) + "\n")
    assert main(["retime", "ohsaka-fig3", "--path", "path.csv", "--json", "r.json"]) == 0
    plan = load_transfer_plan(tmp_path / "r.json", E)
    t = _times(plan.motion_time_s, sc.recheck_rate_hz)
    tau = drake_inverse_dynamics(*plan.sample(t), sc.urdf)
    assert 0.99 < np.max(np.abs(tau) / np.asarray(E.torque_limit_Nm)) <= 1.0 + 1e-9
    assert main(["simulate", "ohsaka-fig3", "--plan", "r.json", "--json", "s.json"]) == 0
    s = json.loads((tmp_path / "s.json").read_text())
    assert s["reached_goal"] and s["method"] == "retime_toppra"
    capsys.readouterr()
    assert main(["retime", "ohsaka-fig2", "--path", "path.csv"]) == 2
    err = capsys.readouterr().err.strip()
    assert "needs the joints' torque limits" in err and "\n" not in err
