"""A held law's feedforward evaluated for the coming hold (issue 29 item 2; joint_tracking.HoldCompensatedReference,
sim/spatial_actuation hold_compensation). Closed forms: a feedforward ramp of slope s held by a zero-order hold from
each sample is s T/2 short on average over the hold; on the plan's mean over the hold it is exact."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Demultiplexer, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive
from qmt_drake.sim.spatial_cosim import build_spatial_cosim, simulate_spatial
from qmt_drake.systems.dc_motor import DcMotorParams
from qmt_drake.systems.joint_tracking import (
    HoldCompensatedReference,
    JointPidController,
    PidGains,
    pd_voltage,
)
from tests.spatial_fixtures import load_or_skip, shipped_toppra

STEP_S = 1e-3


def _plan(q_of_t, qd_of_t, t_end=0.1):
    """A one-joint plan as the co-simulation's reference polynomials (spatial_cosim._reference): positions as a
    CubicHermite through the plant steps, acceleration as their first-order hold (from the closed form)."""
    t = np.arange(0.0, t_end + 1e-12, STEP_S)
    q, qd = q_of_t(t), qd_of_t(t)
    return PiecewisePolynomial.CubicHermite(t, q[None, :], qd[None, :]), t


def _ahead(pp, acc, period_s, mode, t):
    ref = HoldCompensatedReference(pp, acc, period_s, STEP_S, mode)
    ctx = ref.CreateDefaultContext()
    ctx.SetTime(t)
    return ref.GetOutputPort("desired_state").Eval(ctx), ref.GetOutputPort("desired_acceleration").Eval(ctx)


@pytest.mark.parametrize("mode", ["mean", "midpoint"])
def test_a_ramp_is_seen_at_the_middle_of_the_hold(mode):
    """q = a t^3 / 6: speed a t^2 / 2, acceleration a t (a ramp). Held from t over m = T/h plant steps, the
    every-step law would see the acceleration at t + j h, j < m: its mean is a (t + (T - h)/2), what both modes
    give for a ramp; the speed's mean over those steps is a/2 (mean of (t + j h)^2) ("mean"), the midpoint's
    a/2 (t + (T - h)/2)^2, short by a/2 of the steps' variance h^2 (m^2 - 1)/12."""
    a, T, t = 3.0, 8e-3, 0.031
    pp, _ = _plan(lambda s: a * s**3 / 6, lambda s: a * s**2 / 2)
    x, qdd = _ahead(pp, pp.derivative(2), T, mode, t)
    m = round(T / STEP_S)
    assert qdd[0] == pytest.approx(a * (t + (T - STEP_S) / 2), rel=1e-9)
    mid = t + (T - STEP_S) / 2
    variance = STEP_S**2 * (m**2 - 1) / 12
    assert x[1] == pytest.approx(a / 2 * (mid**2 + (variance if mode == "mean" else 0.0)), rel=1e-9)
    q_mean = a / 6 * np.mean((t + np.arange(m) * STEP_S) ** 3)
    assert x[0] == pytest.approx(q_mean if mode == "mean" else a / 6 * mid**3, rel=1e-9)


def test_an_acceleration_jump_inside_the_hold_is_averaged():
    """A TOPP-RA switch: qdd = 0 before t_j, 2 after (the reference's acceleration a first-order hold through the
    steps, as spatial_cosim builds it). Held over 8 steps from t_j - 3 ms, the steps see 0 at 3 of them, 2 at 5:
    mean 1.25; the midpoint (t_j + 0.5 ms) sees 2 for the whole hold."""
    tj, T = 0.05, 8e-3
    pp, t = _plan(lambda s: np.maximum(s - tj, 0.0) ** 2, lambda s: 2 * np.maximum(s - tj, 0.0))
    acc = PiecewisePolynomial.FirstOrderHold(t, 2.0 * (t >= tj - 1e-12)[None, :])
    _, mean = _ahead(pp, acc, T, "mean", tj - 3e-3)
    _, mid = _ahead(pp, acc, T, "midpoint", tj - 3e-3)
    assert mean[0] == pytest.approx(2.0 * 5 / 8, rel=1e-9)
    assert mid[0] == pytest.approx(2.0, rel=1e-9)


def _held_back_emf_voltage(period_s, compensated: bool, slope=2.0, t_end=0.06):
    """A one-joint JointPidController (no P/D: only the back-EMF feedforward K_e N qd_des) held at period_s (None:
    every step) on 1 ms steps, on the plan q = slope t^2 / 2 (speed ramp slope t); the voltage at every step, and K_e N."""
    mp = DcMotorParams(torque_constant_Nm_per_A=[0.05], resistance_ohm=[1.0], gear_ratio=[10.0],
                       voltage_limit_V=[1e3], current_limit_A=[1e3], efficiency=[1.0], names=["j"])
    pp, _ = _plan(lambda s: slope * s**2 / 2, lambda s: slope * s, t_end + 0.1)
    b = DiagramBuilder()
    pid = b.AddSystem(JointPidController(PidGains([0.0], [0.0], [0.0]), [10.0], [1e3], control_period_s=STEP_S,
                                         motor=mp, back_emf_feedforward=True, hold_period_s=period_s,
                                         feedforward_velocity_port=compensated))  # period_s None: every step
    src = b.AddSystem(TrajectorySource(pp, output_derivative_order=1))
    b.Connect(src.get_output_port(), pid.GetInputPort("desired_state"))
    b.Connect(b.AddSystem(ConstantVectorSource([0.0, 0.0])).get_output_port(), pid.GetInputPort("estimated_state"))
    if compensated:
        ahead = b.AddSystem(HoldCompensatedReference(pp, pp.derivative(2), period_s, STEP_S))
        split = b.AddSystem(Demultiplexer([1, 1]))
        b.Connect(ahead.GetOutputPort("desired_state"), split.get_input_port())
        b.Connect(split.get_output_port(1), pid.GetInputPort("feedforward_velocity"))
    log = LogVectorOutput(pid.GetOutputPort("voltage_command"), b, STEP_S)
    sim = Simulator(b.Build())
    sim.AdvanceTo(t_end)
    data = log.FindLog(sim.get_context())
    return data.sample_times(), data.data()[0], 0.05 * 10.0


@pytest.mark.parametrize("period_s", [4e-3, 8e-3])
def test_held_feedforward_lags_by_half_the_period_and_the_compensation_removes_it(period_s):
    """The every-step law (hold_period_s None) applies K_e N slope t_n at each step t_n. Held uncompensated, the
    voltage averaged over a whole hold is K_e N slope (T - h)/2 short of it (the ramp at the sample instant against
    its mean over the hold's steps; T/2 as h -> 0); compensated, the two averages are equal."""
    slope = 2.0
    t0, every, _ = _held_back_emf_voltage(None, False, slope)
    for compensated, expected in ((False, -(period_s - STEP_S) / 2), (True, 0.0)):
        t, v, ke_n = _held_back_emf_voltage(period_s, compensated, slope)
        np.testing.assert_allclose(t, t0)
        n_hold = int(round(period_s / STEP_S))
        whole = (len(t) // n_hold) * n_hold
        per_hold = (v[:whole] - every[:whole]).reshape(-1, n_hold).mean(axis=1)
        np.testing.assert_allclose(per_hold, ke_n * slope * expected, atol=1e-12)
    np.testing.assert_allclose(every, ke_n * slope * t0, rtol=1e-12, atol=1e-15)


def test_the_compiled_law_refuses_a_separate_feedforward_speed():
    mp = DcMotorParams(torque_constant_Nm_per_A=[0.05], resistance_ohm=[1.0], gear_ratio=[10.0],
                       voltage_limit_V=[1e3], current_limit_A=[1e3], efficiency=[1.0], names=["j"])
    pid = JointPidController(PidGains([1.0], [0.0], [0.0]), [10.0], [1e3], motor=mp, back_emf_feedforward=True,
                             hold_period_s=4e-3, feedforward_velocity_port=True)
    with pytest.raises(ValueError, match="feedforward_velocity_port"):
        pd_voltage(pid, [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="nothing reads it"):
        JointPidController(PidGains([1.0], [0.0], [0.0]), [10.0], [1e3], motor=mp, feedforward_velocity_port=True)


@pytest.fixture(scope="module")
def panda():
    sc = load_or_skip("panda-tray-cup")
    return sc, shipped_toppra(sc.name).trajectory


def test_a_held_drive_compensates_by_default_and_tracks_like_the_every_step_law(panda):
    """Panda tray, TOPP-RA plan, full feedforward, law held at 8 ms behind a voltage amplifier (the feedforward
    voltage's lag is that law's): the default compensation ("mean") tracks within 1.5x of the every-step law's RMS error; the uncompensated law ('none') is several times worse
    (studies/held_feedforward: 7.1e-5 rad every step, 4.3e-4 uncompensated, 5.2e-5 compensated). Only the held
    drive has the compensating reference in its diagram."""
    sc, traj = panda
    q0 = traj.sample([0.0])[0][0]
    every = simulate_spatial(sc, traj, actuator="dc_motor", feedforward="full")
    default = SpatialMotorDrive.for_scenario(sc, q0, "full", control_period_s=8e-3, amplifier="voltage")
    assert default.hold_compensation == "mean"
    held = simulate_spatial(sc, traj, actuator="dc_motor", feedforward="full", drive=default)
    none = simulate_spatial(sc, traj, actuator="dc_motor", feedforward="full",
                            drive=SpatialMotorDrive.for_scenario(sc, q0, "full", control_period_s=8e-3,
                                                                 hold_compensation="none", amplifier="voltage"))
    assert held["rms_tracking_error_rad"] < 1.5 * every["rms_tracking_error_rad"]
    assert none["rms_tracking_error_rad"] > 3.0 * held["rms_tracking_error_rad"]
    names = {s.get_name() for s in build_spatial_cosim(sc, traj, drive=default).diagram.GetSystems()}
    assert "hold_compensated_reference" in names
    names = {s.get_name() for s in build_spatial_cosim(sc, traj, actuator="dc_motor").diagram.GetSystems()}
    assert "hold_compensated_reference" not in names


def test_an_unknown_hold_compensation_is_refused_in_one_line(panda):
    sc, traj = panda
    with pytest.raises(QmtInputError, match="hold compensation 'ahead': choose one of mean, midpoint, none") as e:
        SpatialMotorDrive.for_scenario(sc, traj.sample([0.0])[0][0], "full", control_period_s=4e-3,
                                       hold_compensation="ahead")
    assert "\n" not in str(e.value)
