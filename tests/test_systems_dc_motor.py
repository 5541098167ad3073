"""DcMotorWithGear against closed forms of a DC motor: stall torque, no-load speed, limits, L/R."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from qmt_drake.systems.dc_motor import MOTOR_CATALOG, DcMotorParams, DcMotorWithGear


def _params(**kw):
    sheets = [MOTOR_CATALOG["maxon_RE30_60W_24V"], MOTOR_CATALOG["maxon_RE25_20W_24V"]]
    return DcMotorParams.from_datasheets(sheets, 100.0, **kw)


def _outputs(sys, v, qd):
    ctx = sys.CreateDefaultContext()
    sys.GetInputPort("voltage_command").FixValue(ctx, v)
    sys.GetInputPort("joint_velocity").FixValue(ctx, qd)
    return {name: sys.GetOutputPort(name).Eval(ctx) for name in
            ("joint_torque", "motor_torque", "current", "electrical_power")}


def test_catalogue_numbers_are_self_consistent():
    # A datasheet's stall torque is Kt*V/R and its no-load speed V/Ke: the two are tied by the
    # same three numbers, so a mistyped entry shows up as an implausible stall torque / speed.
    for m in MOTOR_CATALOG.values():
        assert m.nominal_torque_Nm < m.stall_torque_Nm < 30 * m.nominal_torque_Nm, m.name
        rpm = m.no_load_speed_rad_s * 60 / (2 * math.pi)
        assert 3000 < rpm < 15000, m.name


def test_stall_torque_current_and_power_closed_form():
    p = _params()
    sys = DcMotorWithGear(p)
    v = np.array([1.5, -2.0])
    out = _outputs(sys, v, np.zeros(2))
    i = v / p.resistance_ohm
    np.testing.assert_allclose(out["current"], i, rtol=1e-12)
    np.testing.assert_allclose(out["motor_torque"], p.torque_constant_Nm_per_A * i, rtol=1e-12)
    # Zero speed counts as motoring: the gear delivers N * eta * Kt * V / R.
    np.testing.assert_allclose(out["joint_torque"], 100 * 0.7 * p.torque_constant_Nm_per_A * i, rtol=1e-12)
    np.testing.assert_allclose(out["electrical_power"], v**2 / p.resistance_ohm, rtol=1e-12)


def test_no_load_speed_gives_zero_torque():
    p = _params()
    sys = DcMotorWithGear(p)
    v = np.array([3.0, 5.0])
    qd_no_load = v / (p.torque_constant_Nm_per_A * p.gear_ratio)  # joint side: V / (Ke N)
    out = _outputs(sys, v, qd_no_load)
    np.testing.assert_allclose(out["current"], 0.0, atol=1e-12)
    # Halfway to no-load speed: half the stall current.
    out = _outputs(sys, v, qd_no_load / 2)
    np.testing.assert_allclose(out["current"], v / p.resistance_ohm / 2, rtol=1e-12)


def test_voltage_and_current_limits():
    p = _params()
    sys = DcMotorWithGear(p)
    out = _outputs(sys, np.array([100.0, -100.0]), np.zeros(2))
    # 24 V on 0.611 ohm would be 39 A: the 6 A drive limit holds; RE 25 gets 24 V / 2.32 ohm = 10.3 A -> 4 A.
    np.testing.assert_allclose(out["current"], [6.0, -4.0])
    np.testing.assert_allclose(out["electrical_power"], [24.0 * 6.0, 24.0 * 4.0])


def test_back_driven_gear_uses_back_drive_efficiency():
    p = _params(efficiency=0.7)
    p.back_drive_efficiency = 0.5
    sys = DcMotorWithGear(p)
    out = _outputs(sys, np.array([-1.0, 1.0]), np.array([0.01, -0.01]))  # torque opposes motion
    np.testing.assert_allclose(out["joint_torque"], 100 * out["motor_torque"] / 0.5, rtol=1e-12)


def test_inductance_current_rises_with_time_constant_L_over_R():
    p = _params(with_inductance=True)
    sys = DcMotorWithGear(p)
    sim = Simulator(sys)
    ctx = sim.get_mutable_context()
    v = np.array([0.5, 0.5])
    sys.GetInputPort("voltage_command").FixValue(ctx, v)
    sys.GetInputPort("joint_velocity").FixValue(ctx, np.zeros(2))
    tau = p.inductance_H / p.resistance_ohm
    sim.get_mutable_integrator().set_target_accuracy(1e-8)
    for k, tk in enumerate(tau):
        ctx.SetTime(0.0)
        ctx.SetContinuousState(np.zeros(2))
        sim.Initialize()
        sim.AdvanceTo(tk)
        i = sys.GetOutputPort("current").Eval(ctx)[k]
        assert i == pytest.approx(v[k] / p.resistance_ohm[k] * (1 - math.exp(-1.0)), rel=1e-4)


def test_shape_mismatch_is_rejected():
    with pytest.raises(ValueError, match="resistance_ohm"):
        DcMotorParams([0.02, 0.02], [1.0], [100, 100], [24, 24], [5, 5], [0.7, 0.7])


def test_current_command_mode_and_its_voltage_ceiling():
    p = _params()
    sys = DcMotorWithGear(p, command="current")
    ctx = sys.CreateDefaultContext()
    sys.GetInputPort("current_command").FixValue(ctx, [2.0, -1.0])
    qd = np.array([0.0, 3.0])
    sys.GetInputPort("joint_velocity").FixValue(ctx, qd)
    i = sys.GetOutputPort("current").Eval(ctx)
    emf = p.torque_constant_Nm_per_A * p.gear_ratio * qd
    # Joint 1 at rest gets its 2 A; joint 2 turns at 3 rad/s (motor 300 rad/s, EMF 7.0 V) and can
    # be driven backwards only until the terminal voltage reaches -24 V: (-24 - 7.02) / 2.32 = -13 A,
    # so -1 A is reachable.
    np.testing.assert_allclose(i, [2.0, -1.0])
    np.testing.assert_allclose(sys.GetOutputPort("electrical_power").Eval(ctx),
                               (p.resistance_ohm * i + emf) * i, rtol=1e-12)
    sys.GetInputPort("current_command").FixValue(ctx, [2.0, 3.0])
    sys.GetInputPort("joint_velocity").FixValue(ctx, [0.0, 9.0])  # EMF 21.06 V leaves 2.94 V
    i = sys.GetOutputPort("current").Eval(ctx)
    assert i[1] == pytest.approx((24.0 - 0.0234 * 100 * 9.0) / 2.32, rel=1e-12)


def test_applied_signals_invert_the_motor_model():
    """AppliedMotorSignals reads the motor model backwards: from the joint torque a motor delivers
    (and the joint speed) back to its voltage, current, motor torque and power, motoring and
    back-driven alike, within the limits."""
    from qmt_drake.systems.dc_motor import AppliedMotorSignals, motor_signals_from_joint_torque

    p = _params()
    p.back_drive_efficiency = 0.8  # a lossy back-driven gear, so both branches differ
    forward = DcMotorWithGear(p)
    backward = AppliedMotorSignals(p)
    rng = np.random.default_rng(3)
    for _ in range(20):
        v = rng.uniform(-2.0, 2.0, 2)
        qd = rng.uniform(-0.5, 0.5, 2)
        out = _outputs(forward, v, qd)
        assert np.all(np.abs(out["current"]) < p.current_limit_A)  # unsaturated draws only
        ctx = backward.CreateDefaultContext()
        backward.GetInputPort("applied_joint_torque").FixValue(ctx, out["joint_torque"])
        backward.GetInputPort("joint_velocity").FixValue(ctx, qd)
        np.testing.assert_allclose(backward.GetOutputPort("voltage").Eval(ctx), v, rtol=1e-9, atol=1e-12)
        for name in ("joint_torque", "motor_torque", "current", "electrical_power"):
            np.testing.assert_allclose(backward.GetOutputPort(name).Eval(ctx), out[name], rtol=1e-9, atol=1e-15)
        v_f, i_f, tau_m_f, p_f = motor_signals_from_joint_torque(p, out["joint_torque"], qd)
        np.testing.assert_allclose(v_f, v, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(p_f, out["electrical_power"], rtol=1e-9, atol=1e-15)


def _holding_torque(p, qd):
    """Joint torque of a motor at a fixed positive voltage (holding a load up) at joint speed qd."""
    return _outputs(DcMotorWithGear(p), np.array([1.0, 1.0]), np.array([qd, qd]))["joint_torque"][0]


def test_switched_gain_jumps_by_one_over_eta_when_a_held_load_dithers():
    # The default (switched) model: the same motor torque gives N eta Kt i when the joint creeps
    # forward and N Kt i when it creeps back: a jump of 1/eta across qd = 0.
    p = _params(efficiency=0.7)
    eps = 1e-9
    up, down = _holding_torque(p, eps), _holding_torque(p, -eps)
    assert down / up == pytest.approx(1 / 0.7, rel=1e-6)


def test_smooth_efficiency_is_continuous_and_matches_the_switched_model_away_from_rest():
    p = _params(efficiency=0.7)
    p.back_drive_efficiency = 0.8
    p.efficiency_blend_speed_rad_s = 1e-3
    kt_i = p.torque_constant_Nm_per_A[0] * 1.0 / p.resistance_ohm[0]  # stall current at 1 V
    # continuous at rest: the mean of the motoring and back-driven gains, no jump
    eps = 1e-9
    up, down = _holding_torque(p, eps), _holding_torque(p, -eps)
    assert up == pytest.approx(down, rel=1e-5)
    assert _holding_torque(p, 0.0) == pytest.approx(100 * kt_i * (0.7 + 1 / 0.8) / 2, rel=1e-12)
    # monotone between the two gains, and the switched values beyond a few w_b
    qd = np.linspace(-5e-3, 5e-3, 41)
    g = np.array([_holding_torque(p, w) for w in qd])
    assert np.all(np.diff(g) < 0)  # more motoring (qd > 0) -> less joint torque per motor torque
    ref = _params(efficiency=0.7)
    ref.back_drive_efficiency = 0.8
    for w in (-0.02, 0.02):  # 20 w_b: tanh(20) = 1 - 8e-18
        # the back EMF differs by qd but is the same for both models: compare joint/motor torque
        o1 = _outputs(DcMotorWithGear(p), np.array([1.0, 1.0]), np.array([w, w]))
        o2 = _outputs(DcMotorWithGear(ref), np.array([1.0, 1.0]), np.array([w, w]))
        np.testing.assert_allclose(o1["joint_torque"], o2["joint_torque"], rtol=1e-12)


def test_smooth_efficiency_inverse_round_trips():
    from qmt_drake.systems.dc_motor import motor_signals_from_joint_torque
    p = _params(efficiency=0.7)
    p.back_drive_efficiency = 0.8
    p.efficiency_blend_speed_rad_s = 0.05
    for qd in (-0.1, -0.01, 0.0, 0.02, 0.3):
        v = np.array([2.0, -1.5])
        out = _outputs(DcMotorWithGear(p), v, np.array([qd, qd]))
        v2, i2, tau_m2, _ = motor_signals_from_joint_torque(p, out["joint_torque"], [qd, qd])
        np.testing.assert_allclose(i2, out["current"], rtol=1e-10)
        np.testing.assert_allclose(v2, v, rtol=1e-10)
    with pytest.raises(ValueError):
        _params(efficiency=0.7).__class__(**{**_params().__dict__, "efficiency_blend_speed_rad_s": 0.0})


@pytest.mark.parametrize("blend", [None, 0.05])
def test_primitives_are_the_python_model(blend):
    """dc_motors_as_primitives / applied_motor_signals_as_primitives (the same formulas compiled into
    SymbolicVectorSystems) against DcMotorWithGear / motor_signals_from_joint_torque on random
    inputs: saturated and not, motoring and back-driven."""
    from qmt_drake.systems.dc_motor import (
        DcMotorWithGear,
        applied_motor_signals_as_primitives,
        dc_motors_as_primitives,
        motor_signals_from_joint_torque,
    )
    p = DcMotorParams.from_datasheets([MOTOR_CATALOG["maxon_RE30_60W_24V"], MOTOR_CATALOG["maxon_RE25_20W_24V"]],
                                      [100, 100])
    p.efficiency_blend_speed_rad_s = blend
    py, prim, inv = DcMotorWithGear(p), dc_motors_as_primitives(p), applied_motor_signals_as_primitives(p)
    c1, c2, c3 = py.CreateDefaultContext(), prim.CreateDefaultContext(), inv.CreateDefaultContext()
    rng = np.random.default_rng(5)
    signs = set()
    for _ in range(200):
        v, qd, tau = rng.normal(size=2) * 20.0, rng.normal(size=2) * 0.5, rng.normal(size=2) * 2.0
        for system, c in ((py, c1), (prim, c2)):
            system.GetInputPort("voltage_command").FixValue(c, v)
            system.GetInputPort("joint_velocity").FixValue(c, qd)
        for name in ("joint_torque", "motor_torque", "current", "electrical_power"):
            np.testing.assert_allclose(prim.GetOutputPort(name).Eval(c2), py.GetOutputPort(name).Eval(c1),
                                       rtol=1e-13, atol=1e-15)
        signs.add(tuple(np.sign(py.GetOutputPort("motor_torque").Eval(c1) * qd)))
        inv.GetInputPort("applied_joint_torque").FixValue(c3, tau)
        inv.GetInputPort("joint_velocity").FixValue(c3, qd)
        expected = motor_signals_from_joint_torque(p, tau, qd)
        for name, k in (("voltage", 0), ("current", 1), ("motor_torque", 2), ("electrical_power", 3)):
            np.testing.assert_allclose(inv.GetOutputPort(name).Eval(c3), expected[k], rtol=1e-13, atol=1e-15)
        np.testing.assert_array_equal(inv.GetOutputPort("joint_torque").Eval(c3), tau)
    assert {1.0, -1.0} <= {s for pair in signs for s in pair}  # motoring and back-driven both seen
