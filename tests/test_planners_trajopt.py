"""Trajectory optimization: the AutoDiff-ready tip acceleration equals the ArmModel's; the B-spline
weights reproduce Drake's evaluation; a chapter-3 solve meets its endpoints, keeps the limits on the
re-check, cannot beat the double-integrator bound 2*sqrt(L/A) and beats the thesis's trapezoid
family; via points are passed at their times; infeasible limits give infeasible plans."""

import numpy as np
import pytest

from qmt_drake.planners.baselines.paths import task_joint_points
from qmt_drake.planners.baselines.trajopt_plan import basis_weights, plan_trajopt
from qmt_drake.transfer_scenario import load_scenario

QUICK = {"num_control_points": 10, "constraint_samples": 40}


@pytest.fixture(scope="module")
def sc3():
    return load_scenario("thesis-ch3")


@pytest.mark.parametrize("name", ["thesis-ch2", "thesis-ch3"])
def test_generic_tip_acceleration_matches_arm(name):
    from pydrake.autodiffutils import AutoDiffXd
    arm = load_scenario(name).arm
    rng = np.random.default_rng(1)
    for _ in range(5):
        q, qd, qdd = rng.normal(size=(3, arm.n_dof))
        np.testing.assert_allclose(arm.tip_acceleration(q, qd, qdd),
                                   arm.drake_tip_acceleration(q, qd, qdd), atol=1e-12)
    # AutoDiff: the derivative wrt qdd is the Jacobian.
    qdd_ad = np.array([AutoDiffXd(v, np.eye(arm.n_dof)[i]) for i, v in enumerate(qdd)])
    a = arm.tip_acceleration(q, qd, qdd_ad)
    J = np.array([ai.derivatives() for ai in a])
    np.testing.assert_allclose(J, arm.jacobian(q), atol=1e-12)


def test_basis_weights_reproduce_bspline():
    from pydrake.math import BsplineBasis
    from pydrake.trajectories import BsplineTrajectory
    basis = BsplineBasis(4, 9)
    rng = np.random.default_rng(2)
    P = rng.normal(size=(2, 9))
    traj = BsplineTrajectory(basis, [P[:, [i]] for i in range(9)])
    for s in (0.0, 0.13, 0.5, 0.77, 1.0):
        idx, W = basis_weights(basis, s)
        np.testing.assert_allclose(P[:, idx] @ W[0], traj.value(s)[:, 0], atol=1e-12)
        np.testing.assert_allclose(P[:, idx] @ W[2], traj.EvalDerivative(s, 2)[:, 0], atol=1e-9)


def test_ch3_free_path(sc3):
    plan = plan_trajopt(sc3, **QUICK)
    assert plan.extra["solver"]["success"]
    assert plan.feasible
    qk = task_joint_points(sc3)
    q, qd, _ = plan.sample([0.0, plan.motion_time_s])
    np.testing.assert_allclose(plan.trajectory.evaluate([0.0], [0.0])[0][0], qk[0], atol=1e-6)
    end = plan.trajectory.evaluate([plan.motion_time_s], [plan.motion_time_s * (1 - 1e-9)])
    np.testing.assert_allclose(end[0][0], qk[-1], atol=1e-6)
    np.testing.assert_allclose(end[1][0], 0.0, atol=1e-6)
    A = sc3.limits.moment_limit_Nm / sc3.moment_per_accel_kgm
    L = float(np.hypot(*(sc3.task.points_m[1] - sc3.task.points_m[0])))
    assert plan.motion_time_s >= 2 * np.sqrt(L / A)  # no path beats the double integrator
    assert plan.motion_time_s < sc3.reported["motion_time_s"]
    # The raw solver output is on record; the final plan is at most a hair slower than it.
    raw = plan.extra["raw_check"]
    assert plan.motion_time_s == pytest.approx(
        raw["motion_time_s"] * np.sqrt(max(1.0, raw["peak_moment_ratio"],
                                           raw["peak_motor_torque_ratio"])), rel=1e-6)


def test_ch4_passes_the_vias_at_their_times():
    sc = load_scenario("thesis-ch4")
    plan = plan_trajopt(sc, **QUICK)
    assert plan.feasible
    sv = np.array(plan.extra["via_normalized_times"])
    q, _, _ = plan.sample(sv * plan.motion_time_s)
    np.testing.assert_allclose(sc.arm.tip_position(q), sc.task.points_m[1:-1], atol=1e-6)


def test_infeasible_limits_give_infeasible_plans():
    weak = load_scenario("thesis-ch3", overrides={"limits": {"motor_torque_limit_Nm": [1e-7, 1e-7]}})
    p = plan_trajopt(weak, major_iterations=50, **QUICK)
    assert not p.feasible and "too tight" in p.extra["infeasible"]
    far = load_scenario("thesis-ch3", overrides={"task": {"points_m": [[0.22, 0.15], [0.5, 0.5]]}})
    p = plan_trajopt(far, **QUICK)
    assert not p.feasible and "unreachable" in p.extra["infeasible"]


def test_a_point_snopt_stops_on_within_every_constraint_is_a_plan():
    """SNOPT stopped by its iteration limit on a point meeting every constraint within 1e-6 is a trajectory of the
    program (trajopt_core.TrajoptResult.usable, the spatial trajopt's rule): planned and re-checked, not proven
    minimal; stopped earlier, on a point that breaks the moment rows, it stays an infeasible plan naming them.
    Checked independently: the tip through the vias at their times and the moment and motor torque by Drake's
    own kinematics and inverse dynamics on 20 kHz samples, twice the re-check's rate."""
    sc = load_scenario("thesis-ch4")
    p = plan_trajopt(sc, major_iterations=12, **QUICK)  # SNOPT's kIterationLimit on a point within every row
    assert p.extra["solution_result"].endswith("kIterationLimit") and p.extra["proven_optimal"] is False
    assert p.feasible
    sv = np.array(p.extra["via_normalized_times"])
    np.testing.assert_allclose(sc.arm.tip_position(p.sample(sv * p.motion_time_s)[0]), sc.task.points_m[1:-1],
                               atol=1e-6)
    q, qd, qdd = p.sample(np.linspace(0.0, p.motion_time_s, int(20000 * p.motion_time_s)))
    lin, _, tau, _ = sc.arm.drake_chain.hand_acceleration_and_joint_torque(q, qd, qdd)
    A = sc.limits.moment_limit_Nm / sc.moment_per_accel_kgm
    assert np.linalg.norm(lin, axis=1).max() / A <= 1.0 + 1e-6
    motor = np.abs(tau / sc.arm.gear_ratio) / sc.limits.motor_torque_limit_Nm
    assert motor.max() <= 1.0 + 1e-6
    early = plan_trajopt(sc, major_iterations=8, **QUICK)
    assert early.extra["proven_optimal"] is False and not early.feasible
    assert "its point breaks 2 constraints (moment s=" in early.extra["infeasible"]
