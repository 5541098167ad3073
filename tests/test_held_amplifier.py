"""A held DC law behind a current amplifier (issue 29 item 2; sim/spatial_actuation amplifier, systems/held_loop).

The cause it fixes, in closed form: a held VOLTAGE V drives the current (V - K_e N qd)/R, which falls over the hold
as the joint speeds up, by K_e N qdd (T - h) / R per hold; on the UR5 and Panda motors, whose back-EMF damping
dominates the joint inertia, that saws the arm's acceleration and lost the UR5 suction box within 50 ms at 4 ms
and slid the Panda's cup at 2 ms. A current amplifier (the drive's current loop) keeps the current at the held
command over the hold."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_actuation import HELD_AMPLIFIERS, SpatialMotorDrive
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.sweep.spatial_cases import drawn_drive
from qmt_drake.systems.dc_motor import DcMotorParams, dc_motors_as_primitives
from qmt_drake.systems.held_loop import HELD_MIN_DAMPING, held_loop_poles, least_damping
from qmt_drake.systems.joint_tracking import JointPidController, PidGains
from tests.spatial_fixtures import load_or_skip, shipped_toppra

STEP_S = 1e-3
KT, R, N = 0.1, 0.35, 101.0


def _current_over_holds(current_loop: bool, period_s=4e-3, qdd=5.0, t_end=0.04):
    """One joint tracking a speed ramp qd = qdd t exactly, 1/N rad behind in position: a P law (Kp 1 V/rad: 1 V)
    held at period_s, with the back-EMF feedforward K_e N qd_des at the sample (held voltage) or behind the current
    loop (which cancels the measured speed's back EMF), into the DC motor model (dc_motors_as_primitives); the
    motor current at every 1 ms step."""
    mp = DcMotorParams(torque_constant_Nm_per_A=[KT], resistance_ohm=[R], gear_ratio=[N], voltage_limit_V=[1e3],
                       current_limit_A=[1e3], efficiency=[1.0], names=["j"])
    b = DiagramBuilder()
    pid = b.AddSystem(JointPidController(PidGains([1.0], [0.0], [0.0]), [N], [1e3], control_period_s=STEP_S, motor=mp,
                                         hold_period_s=period_s, back_emf_feedforward=not current_loop,
                                         current_loop=current_loop))
    t = np.arange(0.0, t_end + 0.1, STEP_S)
    src = {k: b.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, np.vstack(rows))))
           for k, rows in (("desired", [0.0 * t, qdd * t]), ("measured", [0.0 * t - 1.0 / N, qdd * t]),
                           ("speed", [qdd * t]))}
    b.Connect(src["desired"].get_output_port(), pid.GetInputPort("desired_state"))
    b.Connect(src["measured"].get_output_port(), pid.GetInputPort("estimated_state"))
    motors = b.AddSystem(dc_motors_as_primitives(mp))
    b.Connect(pid.GetOutputPort("voltage_command"), motors.GetInputPort("voltage_command"))
    b.Connect(src["speed"].get_output_port(), motors.GetInputPort("joint_velocity"))
    log = LogVectorOutput(motors.GetOutputPort("current"), b, STEP_S)
    sim = Simulator(b.Build())
    sim.AdvanceTo(t_end)
    data = log.FindLog(sim.get_context())
    return data.sample_times(), data.data()[0]


def test_a_held_voltage_saws_the_current_and_a_current_loop_holds_it():
    """Held voltage: within each hold the current falls by K_e N qdd h / R per plant step (closed form), a sawtooth
    of K_e N qdd (T - h) / R per hold. Current loop: the current is the held command (u / R) at every step."""
    qdd, T = 5.0, 4e-3
    m = round(T / STEP_S)
    t, i_v = _current_over_holds(False, T, qdd)
    steps = np.diff(i_v).reshape(-1)
    within = np.arange(1, len(i_v)) % m != 0  # steps inside a hold (not onto a sample)
    np.testing.assert_allclose(steps[within], -KT * N * qdd * STEP_S / R, rtol=1e-6)
    np.testing.assert_allclose(i_v[::m], 1.0 / R, rtol=1e-9)  # at each sample: the P term's 1 V over R
    _, i_c = _current_over_holds(True, T, qdd)
    np.testing.assert_allclose(i_c, 1.0 / R, rtol=1e-9)  # the held command at every step


@pytest.fixture(scope="module")
def suction():
    sc = load_or_skip("ur5-suction-bins")
    return sc, TimeScaled(shipped_toppra(sc.name).trajectory, 1.05)


def _run(sc, traj, period_s, amplifier, feedforward="shaped"):
    drive = SpatialMotorDrive.for_scenario(sc, traj.sample([0.0])[0][0], feedforward, control_period_s=period_s,
                                           amplifier=amplifier)
    return simulate_spatial(sc, traj, actuator="dc_motor", feedforward=feedforward, drive=drive)


def test_ur5_suction_held_at_4_ms_is_carried_behind_a_current_amplifier(suction):
    """TOPP-RA x1.05, shaped, law held at 4 ms: the held voltage loses the box within 50 ms (its torque sawtooth
    lifts the hand ratio from 0.95 to over 1); behind the current amplifier (the default) it is carried with the
    every-step law's hand ratio (0.946 there; docs/spatial_drives.md)."""
    sc, traj = suction
    voltage = _run(sc, traj, 4e-3, "voltage")
    assert voltage["outcome"] == "detached" and voltage["lost_at_s"] < 0.05
    current = _run(sc, traj, 4e-3, HELD_AMPLIFIERS[0])
    assert HELD_AMPLIFIERS[0] == "current"
    assert current["outcome"] == "carried"
    assert current["max_grip_ratio_while_held"] < 0.96
    assert current["max_tracking_error_rad"] < 1e-4


def test_panda_cup_held_at_2_ms_stays_put_behind_a_current_amplifier():
    """Panda tray, TOPP-RA, shaped, law held at 2 ms: the held voltage's sawtooth takes the cup's contact ratio over
    1 (the cup slides microns); behind the current amplifier the ratio stays at the every-step law's 0.970."""
    sc = load_or_skip("panda-tray-cup")
    traj = shipped_toppra(sc.name).trajectory
    voltage = _run(sc, traj, 2e-3, "voltage")
    assert voltage["contact_ratio_first_above_1_s"] is not None
    current = _run(sc, traj, 2e-3, "current")
    assert current["outcome"] == "carried" and current["contact_ratio_first_above_1_s"] is None
    assert current["max_grip_ratio_while_held"] < 0.975
    assert current["max_slide_m"] < 1e-6


def test_held_loop_map_tends_to_the_zero_order_hold_closed_form():
    """One joint, no plant damping: held over m steps of h = T/m, the one-hold map tends (m -> inf) to the
    zero-order-hold double integrator's Phi = [[1, T], [0, 1]], Gamma = [T^2/2M, T/M] closed by tau = -K q - D v;
    with m = 1 it is the semi-implicit Euler step, char. polynomial z^2 - (2 - hD/M - h^2 K/M) z + 1 - hD/M."""
    M, K, D, T = 0.4, 360.0, 24.0, 8e-3
    phi = np.array([[1.0, T], [0.0, 1.0]]) - np.outer([T * T / (2 * M), T / M], [K, D])
    exact = np.sort_complex(np.linalg.eigvals(phi))
    np.testing.assert_allclose(np.sort_complex(held_loop_poles([[M]], [K], [D], T / 4000, 4000)), exact, atol=2e-4)
    h = 1e-3
    euler = np.sort_complex(np.roots([1.0, -(2 - h * D / M - h * h * K / M), 1 - h * D / M]))
    np.testing.assert_allclose(np.sort_complex(held_loop_poles([[M]], [K], [D], h, 1)), euler, atol=1e-12)


def test_held_current_gains_are_slowed_for_the_period_only_where_needed():
    """Panda at its start: the 30 rad/s joint loops held at 8 ms keep least damping 0.11 (coupled modes lighter than
    the diagonal, and the hold's delay) and at 10 ms are unstable; the drive's held current law is slowed until
    HELD_MIN_DAMPING holds. At 2 ms it needs no slowing. A sweep's drawn kp/kd scales carry over."""
    sc = load_or_skip("panda-tray-cup")
    q0 = shipped_toppra(sc.name).trajectory.sample([0.0])[0][0]
    Mj = None
    for period_s, slowed in ((2e-3, False), (8e-3, True), (10e-3, True)):
        d = SpatialMotorDrive.for_scenario(sc, q0, "full", control_period_s=period_s)
        g = d.law_gains(STEP_S)
        per_kp = d.params.gear_ratio * d.params.efficiency * d.params.torque_constant_Nm_per_A / d.params.resistance_ohm
        K, D = per_kp * d.params.gear_ratio * g.kp_V_per_rad, per_kp * d.params.gear_ratio * g.kd_V_s_per_rad
        M = d.mass_matrix
        Mj = np.diag(M)
        m = round(period_s / STEP_S)
        assert least_damping(held_loop_poles(M, K, D, STEP_S, m)) >= HELD_MIN_DAMPING
        unslowed = least_damping(held_loop_poles(M, 900.0 * Mj, 60.0 * Mj, STEP_S, m))
        assert (unslowed < HELD_MIN_DAMPING) == slowed
        np.testing.assert_allclose(K[-1] < 900.0 * Mj[-1] * (1 - 1e-9), slowed)
    assert least_damping(held_loop_poles(M, 900.0 * Mj, 60.0 * Mj, STEP_S, 10)) < 0.0  # unstable unslowed at 10 ms
    drawn = drawn_drive(d, sc, sc, {"kp_scale": 1.1, "kd_scale": 0.9, "loop_period_s": 10e-3})
    np.testing.assert_allclose(drawn.law_gains(STEP_S).kp_V_per_rad, 1.1 * g.kp_V_per_rad, rtol=1e-12)
    np.testing.assert_allclose(drawn.law_gains(STEP_S).kd_V_s_per_rad, 0.9 * g.kd_V_s_per_rad, rtol=1e-12)


def test_an_unknown_amplifier_is_refused_in_one_line():
    sc = load_or_skip("panda-tray-cup")
    with pytest.raises(QmtInputError, match="amplifier 'torque': choose one of current, voltage") as e:
        SpatialMotorDrive.for_scenario(sc, sc.q_poses_rad[0], "full", control_period_s=4e-3, amplifier="torque")
    assert "\n" not in str(e.value)


def test_a_held_current_law_without_its_mass_matrix_is_refused_in_one_line():
    """A drive composed by hand (no for_scenario) has no mass matrix to design the held current law on."""
    sc = load_or_skip("panda-tray-cup")
    d = SpatialMotorDrive.for_scenario(sc, sc.q_poses_rad[0], "full", control_period_s=4e-3)
    bare = dataclasses.replace(d, mass_matrix=None)
    with pytest.raises(QmtInputError, match="mass matrix at the plan's start") as e:
        bare.law_gains(STEP_S)
    assert "\n" not in str(e.value)
    assert bare.law_gains(4e-3).kp_V_per_rad is d.gains.kp_V_per_rad  # not held at its own period: the nominal gains
