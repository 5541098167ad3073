"""The spatial drives' closed-loop-aware reference (sim/spatial_reference.py, feedforward 'shaped'): the
feedforward against independent inverse dynamics (Pinocchio's RNEA), the box-shaped reference's
derivatives and limits, and the shaped reference against the plain one on a short bang-bang move."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.controllers import InverseDynamics

from qmt_drake.errors import QmtInputError
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive, check_drive
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.sim.spatial_reference import (
    BoxShapedReference,
    SampledDataReference,
    closed_loop_reference,
    drive_fit_scale,
    drive_load_ratio,
    feedforward_signals,
)
from tests.spatial_fixtures import load_or_skip

pin = pytest.importorskip("pinocchio")


class BangBang:
    """A rest-to-rest move of every joint by dq [rad] in duration_s: acceleration +a, then -a (steps at 0,
    T/2 and T); the spatial trajectory interface."""

    def __init__(self, q0, dq, duration_s):
        self.q0, self.dq, self.duration_s = np.asarray(q0, float), np.asarray(dq, float), duration_s
        self.a = 4.0 * self.dq / duration_s**2

    def sample(self, t):
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.duration_s)[:, None]
        h = self.duration_s / 2
        first = t <= h
        s = np.where(first, t, self.duration_s - t)
        q = np.where(first, self.q0 + 0.5 * self.a * s**2, self.q0 + self.dq - 0.5 * self.a * s**2)
        return q, self.a * s * 1.0, np.where(first, self.a, -self.a) * np.ones_like(t)


@pytest.fixture(scope="module")
def sc():
    return load_or_skip("ur5-suction-bins")


@pytest.fixture(scope="module")
def move(sc):
    return BangBang(sc.q_poses_rad[1], [0.10, -0.08, 0.12, -0.10, 0.08, 0.05], 0.3)


def pinocchio_model(sc):
    """The UR5 from its URDF in Pinocchio, the carried part appended to the hand frame's joint: built
    without Drake (no armature: the test adds the reflected rotor inertia itself)."""
    model = pin.buildModelFromUrdf(str(sc.urdf))
    frame = model.frames[model.getFrameId(sc.hand_frame)]
    b = sc.body
    inertia = np.asarray(b.inertia_kgm2, float)  # about the centre of mass (as sim/spatial_cosim builds the part)
    part = pin.Inertia(b.mass_kg, np.asarray(b.com_m, float), np.diag(inertia) if inertia.ndim == 1 else inertia)
    model.appendBodyToJoint(frame.parentJoint, part, frame.placement)
    names = [model.names[j] for j in range(1, model.njoints)]
    assert names == list(sc.joint_names)  # the same joint order as the scenario's, by name
    model.armature = np.zeros(model.nv)  # the rotors are added explicitly below (N^2 J_r qdd)
    return model


def test_feedforward_is_the_inverse_dynamics_through_the_motors(sc, move):
    """At sampled states of the move: the feedforward's motor current gives N eta k_t i = the joint torque,
    and that torque equals Pinocchio's RNEA (+ armature) of the arm, part and rotors to 1e-9 N m."""
    drive = SpatialMotorDrive.for_scenario(sc, move.q0, "shaped")
    t = np.array([0.0, 0.05, 0.149, 0.151, 0.27])
    tau, i, v = feedforward_signals(drive, move, t)
    mp = drive.params
    np.testing.assert_allclose(mp.gear_ratio * mp.efficiency * mp.torque_constant_Nm_per_A * i, tau, rtol=0, atol=1e-12)
    inv = InverseDynamics(drive.id_plant)  # the system the co-simulation wires: the same torque
    ctx = inv.CreateDefaultContext()
    q, qd, qdd = move.sample(t)
    for k in range(len(t)):
        inv.get_input_port_estimated_state().FixValue(ctx, np.concatenate([q[k], qd[k]]))
        inv.get_input_port_desired_acceleration().FixValue(ctx, qdd[k])
        np.testing.assert_allclose(inv.get_output_port_generalized_force().Eval(ctx), tau[k], rtol=0, atol=1e-9)
    model = pinocchio_model(sc)
    data = model.createData()
    rotors = np.asarray(sc.drive["gear_ratio"], float) ** 2 * np.asarray(sc.drive["rotor_inertia_kgm2"], float)
    for k in range(len(t)):
        ref = pin.rnea(model, data, q[k], qd[k], qdd[k]) + rotors * qdd[k]
        np.testing.assert_allclose(tau[k], ref, rtol=0, atol=1e-9)
        # the voltage: R i + k_t N qd (the motor's back-EMF at the planned speed)
        np.testing.assert_allclose(v[k], mp.resistance_ohm * i[k] + mp.torque_constant_Nm_per_A * mp.gear_ratio * qd[k],
                                   atol=1e-12)


def test_box_shaped_reference_is_consistent_and_keeps_the_plan(move):
    """q_s, qd_s, qdd_s are derivatives of one another, start and end at rest on the plan's ends, and the
    acceleration stays within the plan's (a moving average)."""
    w = 0.04
    ref = BoxShapedReference(move, w)
    assert ref.duration_s == pytest.approx(move.duration_s + w)
    t = np.linspace(0.0, ref.duration_s, 3401)
    q, qd, qdd = ref.sample(t)
    h = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(q, h, axis=0)[1:-1], qd[1:-1], atol=2e-6)
    np.testing.assert_allclose(np.gradient(qd, h, axis=0)[1:-1], qdd[1:-1], atol=2e-3 * np.abs(move.a).max())
    np.testing.assert_allclose(q[0], move.q0, atol=1e-12)
    np.testing.assert_allclose(q[-1], move.q0 + move.dq, atol=1e-9)
    assert np.abs(qd[[0, -1]]).max() < 1e-12 and np.abs(qdd[[0, -1]]).max() < 1e-12
    assert np.all(np.abs(qdd) <= np.abs(move.a) * (1 + 1e-9))
    # the start is jerk-limited: qdd ramps over w (at most max|qdd jump| / w)
    assert np.abs(np.diff(qdd, axis=0) / h).max() <= 2.0 * np.abs(move.a).max() / w * (1 + 1e-6)


def test_shaped_option_is_refused_or_taken_in_one_line(sc):
    check_drive(sc, "ideal", "shaped")
    check_drive(sc, "dc_motor", "shaped")
    with pytest.raises(QmtInputError, match="choose one of none, back-emf, full, shaped"):
        check_drive(sc, "dc_motor", "smooth")
    assert closed_loop_reference("plan", "full") == "plan"  # not shaped: the plan itself


def test_drive_fit_scale_slows_a_plan_the_motors_cannot_follow(sc, move):
    drive = SpatialMotorDrive.for_scenario(sc, move.q0, "shaped")
    assert drive_load_ratio(drive, move) < 1.0 and drive_fit_scale(drive, move) == 1.0
    fast = BangBang(move.q0, move.dq, 0.06)  # 25x the acceleration: beyond the current limit
    k = drive_fit_scale(drive, fast)
    assert k > 1.0
    assert drive_load_ratio(drive, TimeScaled(fast, k)) <= 1.0 < drive_load_ratio(drive, TimeScaled(fast, k / 1.01))


def test_shaped_reference_carries_a_bang_bang_move_the_plain_one_loses():
    """ur5-magnet-part through the DC motors with the full feedforward: a 0.4 s bang-bang move whose own hand
    ratio is 0.64 rings the 30 g part on its weld at each acceleration step past its limit (detached); the
    shaped reference (the same feedforward on the box-averaged, jerk-limited motion) carries it near the
    plan's ratio, with a smaller tracking error."""
    mag = load_or_skip("ur5-magnet-part")
    move = BangBang(mag.q_poses_rad[1], 0.02 * np.array([1.0, -1.0, 1.0, -1.0, 1.0, 1.0]), 0.4)
    q, qd, qdd = move.sample(np.linspace(0.0, move.duration_s, 2001))
    planned = float(np.max(mag.hand_term().columns(mag.chain.evaluate(q, qd, qdd))))
    assert 0.5 < planned < 0.8
    plain = simulate_spatial(mag, move, actuator="dc_motor", feedforward="full")
    shaped = simulate_spatial(mag, move, actuator="dc_motor", feedforward="shaped")
    assert plain["outcome"] == "detached" and plain["max_grip_ratio_while_held"] > 1.0
    assert shaped["outcome"] == "carried" and shaped["max_grip_ratio_while_held"] <= planned
    assert shaped["max_tracking_error_rad"] < 0.5 * plain["max_tracking_error_rad"]
    assert shaped["final_goal_error_rad"] < 1e-6


def test_sampled_data_reference_is_what_the_discrete_plant_integrates(move):
    """Semi-implicit Euler at h (v+ = v + h a, q+ = q + h v+, as the discrete plant steps) from the reference's
    samples reproduces its next samples: velocity exactly, position to the trapezoid rule's h^3/12 max|jerk|
    (the box of 20 ms turns the move's acceleration jump of 2a into a jerk of at most 2a / 20 ms)."""
    h = 1e-3
    ref = SampledDataReference(BoxShapedReference(move, 0.02), h)
    t = np.arange(0.0, ref.duration_s - h, h)
    q, qd, qdd = ref.sample(t)
    np.testing.assert_allclose(qd[:-1] + h * qdd[:-1], qd[1:], rtol=0, atol=1e-12)
    jerk = 2.0 * np.abs(move.a).max() / 0.02
    np.testing.assert_allclose(q[:-1] + h * qd[1:], q[1:], rtol=0, atol=h**3 / 12 * jerk * 1.001)
