"""Issue 27 item 6 across kinds: the transfer planners on seed 001's energy-time arm (energy/as_transfer.py),
run through the real CLI, each plan checked by an independent sampler: Drake's own inverse dynamics with
gravity (energy/dynamics.drake_inverse_dynamics, a fresh plant of the URDF) at 10x the plan's re-check rate,
every joint torque within the scenario's limits.joint_torque_Nm."""

import json

import numpy as np
import pytest
from pydrake.multibody.tree import MultibodyForces

from qmt_drake.apps.cli import main
from qmt_drake.energy.as_transfer import load_transfer_plan, transfer_scenario_of
from qmt_drake.energy.cross_kind import plan_energy_time_spatial, plan_energy_time_transfer
from qmt_drake.energy.dynamics import drake_inverse_dynamics
from qmt_drake.energy.kinematics import tip_position
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.plan_files import load_plan
from qmt_drake.planners.spatial_plan_io import load_spatial_plan
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.transfer_scenario import load_scenario


def _torque_ratio(plan, E) -> float:
    """max |tau_i| / tau_max,i of the plan sampled at 10x its re-check rate (Drake's inverse dynamics)."""
    rate = 10 * plan.scenario.recheck_rate_hz
    t = np.linspace(0.0, plan.motion_time_s, int(np.ceil(plan.motion_time_s * rate)) + 1)
    q, qd, qdd = plan.sample(t)
    tau = drake_inverse_dynamics(q, qd, qdd, plan.scenario.urdf)
    return float(np.max(np.abs(tau) / np.asarray(E.torque_limit_Nm)))


@pytest.fixture(scope="module")
def fig3_toppra(tmp_path_factory):
    path = tmp_path_factory.mktemp("fig3") / "toppra.json"
    assert main(["plan", "ohsaka-fig3", "--method", "toppra", "--quiet", "--json", str(path)]) == 0
    return path


def test_toppra_on_the_energy_arm_holds_the_torque_limits_between_samples(fig3_toppra):
    """`qmt-drake plan ohsaka-fig3 --method toppra`: the file reads back against the experiment, starts at
    its start posture, ends on X(T), and Drake's torques at 100 kHz stay within the limits (the re-check's
    binding limit is the torque: the plan is torque-limited, not limited by the implied bounds)."""
    E = get_experiment("ohsaka-fig3")
    d = json.loads(fig3_toppra.read_text())
    assert d["scenario_kind"] == "spatial_transfer" and d["method"] == "toppra" and d["feasible"]
    plan = load_transfer_plan(fig3_toppra, E)
    q = plan.sample([0.0, plan.motion_time_s])[0]
    assert np.allclose(q[0], E.problem().theta0, atol=1e-9)
    assert np.linalg.norm(tip_position(E.arm, q[1]) - np.asarray(E.coordinate_vector_m[2:])) < 1e-9
    assert plan.recheck["binding"].startswith("motor_torque")
    ratio = _torque_ratio(plan, E)
    assert 0.99 < ratio <= 1.0 + 1e-9  # at the limit (time-optimal), never over it


def test_simulate_runs_the_transfer_plan_in_the_energy_time_execution(fig3_toppra, tmp_path, capsys):
    out = tmp_path / "sim.json"
    assert main(["simulate", "ohsaka-fig3", "--plan", str(fig3_toppra), "--json", str(out)]) == 0
    s = json.loads(out.read_text())
    assert s["method"] == "toppra" and s["reached_goal"] and s["max_tracking_error_rad"] < 1e-2


def test_ruckig_plan_is_checked_by_drake_inverse_dynamics(tmp_path, capsys):
    E = get_experiment("ohsaka-fig3")
    path = tmp_path / "ruckig.json"
    assert main(["plan", "ohsaka-fig3", "--method", "ruckig", "--quiet", "--json", str(path)]) == 0
    assert _torque_ratio(load_transfer_plan(path, E), E) <= 1.0 + 1e-9


def test_drake_toppra_that_knows_no_torque_exits_3_with_the_least_violating_plan(tmp_path, capsys):
    """Drake's Toppra times the path under the joint bounds only; its plan's torque re-check fails even
    slowed down, so the CLI writes it with feasible false and exits 3."""
    path = tmp_path / "td.json"
    assert main(["plan", "ohsaka-fig3", "--method", "toppra-drake", "--quiet", "--json", str(path)]) == 3
    d = json.loads(path.read_text())
    assert d["feasible"] is False and "INFEASIBLE" in capsys.readouterr().out


@pytest.mark.parametrize("argv,msg", [
    (["ohsaka-fig2", "--method", "toppra"], "needs the joints' torque limits"),
    (["ohsaka-fig3", "--method", "ruckig", "--generations", "2"], "--generations"),
    (["ohsaka-fig3", "--method", "toppra", "--execute", "x.png"], "--execute"),
    (["ohsaka-fig3", "--method", "ruckig", "--carried"], "carries no payload"),
])
def test_bad_options_exit_2_one_line(argv, msg, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["plan", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and "\n" not in err and "Traceback" not in err


def test_the_adapter_keeps_the_experiment_arm_and_postures():
    """The transfer's two task poses are the experiment's X(0), X(T) in the x-z plane, reached by Drake's
    kinematics at the adapter's postures; only the joint torques are limit terms (no hand)."""
    E = get_experiment("ohsaka-fig4")
    sc = transfer_scenario_of(E)
    X = np.asarray(E.coordinate_vector_m)
    assert np.allclose(sc.poses_m, [[X[0], 0, X[1]], [X[2], 0, X[3]]])
    for q, p in zip(sc.q_poses_rad, sc.poses_m):
        assert np.linalg.norm(sc.ik.pose(q)[0] - p) < 1e-9
    assert [t.name for t in sc.terms()] == ["motor_torque"]
    assert np.allclose(sc.torque_limit_Nm, E.torque_limit_Nm)


# ------------------------------------------------------------------ the energy-time cost on a spatial arm

def _drake_torques(sc, q, qd, qdd) -> np.ndarray:
    """Joint torques by a fresh MultibodyPlant of the scenario's URDF with its carried part welded to the hand
    (model/urdf_check.load_arm_plant), Drake's CalcInverseDynamics with gravity, plus the reflected rotor
    inertia N^2 J_r qdd; joints mapped by name."""
    plant, _, names = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, carried=sc.body.as_dict())
    assert names == list(sc.joint_names)
    ctx = plant.CreateDefaultContext()
    iq = [plant.GetJointByName(n).position_start() for n in names]
    iv = [plant.GetJointByName(n).velocity_start() for n in names]
    forces = MultibodyForces(plant)
    out = np.empty_like(q)
    x, v, a = np.zeros(plant.num_positions()), np.zeros(plant.num_velocities()), np.zeros(plant.num_velocities())
    for k in range(len(q)):
        x[iq], v[iv], a[iv] = q[k], qd[k], qdd[k]
        plant.SetPositions(ctx, x)
        plant.SetVelocities(ctx, v)
        forces.SetZero()
        plant.CalcForceElementsContribution(ctx, forces)
        out[k] = plant.CalcInverseDynamics(ctx, a, forces)[iv]
    return out + sc.drive["reflected_inertia_kgm2"] * qdd


@pytest.mark.parametrize("method", ["snopt", "steepest"])
def test_energy_time_solvers_plan_a_spatial_arm_within_its_torque_limits(method, tmp_path, capsys):
    """`qmt-drake plan ur5-magnet-part --method snopt|steepest`: a plan of the spatial kind whose cost z =
    integral (c1 tau'tau + c2) dt, recomputed from Drake's own torques at 10x the plan's re-check rate, is
    the plan's (the 400-point trapezoid against the fine grid: 1e-3), cheaper than the solver's start, with
    every torque within the limits at those samples."""
    path = tmp_path / "p.json"
    assert main(["plan", "ur5-magnet-part", "--method", method, "--quiet", "--json", str(path)]) == 0
    sc = load_spatial_scenario("ur5-magnet-part")
    plan = load_spatial_plan(path, sc)
    info = json.loads(path.read_text())["info"]
    assert plan.feasible and info["objective"] == "energy_time" and info["z"] < info["start_z"]
    t = np.linspace(0.0, plan.motion_time_s, int(np.ceil(plan.motion_time_s * 10 * sc.recheck_rate_hz)) + 1)
    q, qd, qdd = plan.sample(t)
    tau = _drake_torques(sc, q, qd, qdd)
    assert np.max(np.abs(tau) / sc.torque_limit_Nm) <= 1.0 + 1e-9
    z = info["c1"] * np.trapezoid(np.sum(tau * tau, axis=1), t) + info["c2"] * plan.motion_time_s
    assert z == pytest.approx(info["z"], rel=1e-3)


def test_snopt_and_ipopt_agree_on_the_spatial_energy_time_optimum():
    """Two solvers on the same program (energy/cross_kind.py) from the same start: the same optimum (on
    panda-tray-cup, whose tray rows make many constraints active at once, they stop 0.2 % apart in z: two
    KKT points of the sampled program, not one optimum)."""
    sc = load_spatial_scenario("ur5-suction-bins")
    a, b = (plan_energy_time_spatial(sc, method=m) for m in ("snopt", "ipopt"))
    assert a.info["z"] == pytest.approx(b.info["z"], rel=1e-5)


@pytest.mark.parametrize("argv,msg", [
    (["ur5-suction-bins", "--method", "snopt", "--c2", "0"], "c2 = 0 has no stable solution"),
    (["ur5-suction-bins", "--method", "steepest", "--m", "3"], "--m: not an option of the spatial (3-D) steepest"),
])
def test_spatial_energy_time_bad_options_exit_2_one_line(argv, msg, capsys):
    assert main(["plan", *argv, "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and "\n" not in err and "Traceback" not in err


# ------------------------------------------------------------------ the energy-time cost on a planar arm

def _drake_planar_torques(arm, q, qd, qdd) -> np.ndarray:
    """Joint torques by Drake's CalcInverseDynamics with gravity on the arm's plant (the carried part welded,
    the actuators' reflected rotor inertia in its mass matrix), joints mapped by name."""
    plant = arm.plant
    ctx = plant.CreateDefaultContext()
    iq = [plant.GetJointByName(n).position_start() for n in arm.joint_names]
    iv = [plant.GetJointByName(n).velocity_start() for n in arm.joint_names]
    forces = MultibodyForces(plant)
    out = np.empty_like(q)
    x, v, a = np.zeros(plant.num_positions()), np.zeros(plant.num_velocities()), np.zeros(plant.num_velocities())
    for k in range(len(q)):
        x[iq], v[iv], a[iv] = q[k], qd[k], qdd[k]
        plant.SetPositions(ctx, x)
        plant.SetVelocities(ctx, v)
        forces.SetZero()
        plant.CalcForceElementsContribution(ctx, forces)
        out[k] = plant.CalcInverseDynamics(ctx, a, forces)[iv]
    return out


def test_snopt_plans_the_planar_magnet_arm_within_its_motor_torques(tmp_path, capsys):
    """`qmt-drake plan thesis-ch4 --method snopt`: a feasible transfer plan (its own re-check: the moment and
    motor torques), whose motor torques by Drake at 10x the re-check rate stay within the limits and whose z,
    recomputed from them, is the plan's."""
    path = tmp_path / "p.json"
    assert main(["plan", "thesis-ch4", "--method", "snopt", "--quiet", "--json", str(path)]) == 0
    sc = load_scenario("thesis-ch4")
    plan = load_plan(path, sc)
    assert plan.feasible and plan.method == "snopt" and plan.extra["z"] < plan.extra["start_z"]
    t = np.linspace(0.0, plan.motion_time_s, int(np.ceil(plan.motion_time_s * 10 * sc.sampling.check_rate_hz)) + 1)
    q, qd, qdd = plan.sample(t)
    tau = _drake_planar_torques(sc.arm, q, qd, qdd)
    limit = sc.gear_ratio * np.asarray(sc.limits.motor_torque_limit_Nm)
    assert np.max(np.abs(tau) / limit) <= 1.0 + 1e-9
    z = plan.extra["c1"] * np.trapezoid(np.sum(tau * tau, axis=1), t) + plan.extra["c2"] * plan.motion_time_s
    assert z == pytest.approx(plan.extra["z"], rel=1e-3)


def test_snopt_and_ipopt_agree_on_the_tray_energy_time_optimum():
    sc = load_scenario("crane-tray")
    a, b = (plan_energy_time_transfer(sc, method=m) for m in ("snopt", "ipopt"))
    assert a.feasible and b.feasible
    assert a.extra["z"] == pytest.approx(b.extra["z"], rel=1e-5)
