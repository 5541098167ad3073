"""Dynamixel position servo: gain conversion, units, saturation, and the closed loop against the
datasheet (no-load speed) and a continuous second-order model (step overshoot)."""

import math

import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RevoluteJoint, SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Demultiplexer, LogVectorOutput

from qmt_drake.errors import QmtInputError
from qmt_drake.systems.dc_motor import DcMotorWithGear
from qmt_drake.systems.dynamixel_servo import (
    PULSES_PER_RAD,
    PWM_FULL_SCALE,
    XM430_W350,
    XM540_W270,
    DynamixelPositionServo,
    ServoGains,
    motor_params,
)


def test_gain_conversion_follows_the_e_manual():
    kpp, kpi, kpd = ServoGains((800,), (150,), (200,)).firmware()
    assert kpp[0] == 800 / 128 and kpi[0] == 150 / 65536 and kpd[0] == 200 / 16


def test_motor_params_reproduce_the_datasheet():
    for s, lossless in ((XM540_W270, True), (XM430_W350, True), (XM540_W270, False), (XM430_W350, False)):
        p = motor_params([s], lossless_equivalent=lossless)
        stall = (p.gear_ratio[0] * p.efficiency[0] * p.torque_constant_Nm_per_A[0] * s.supply_voltage_V
                 / p.resistance_ohm[0])
        assert stall == pytest.approx(s.stall_torque_Nm, rel=1e-12)
        w0 = s.supply_voltage_V / (p.torque_constant_Nm_per_A[0] * p.gear_ratio[0])
        assert w0 == pytest.approx(s.no_load_speed_rpm * 2 * math.pi / 60, rel=1e-12)
        assert 0.5 < p.efficiency[0] <= 1.0
        # the voltage, not the current limit, sets the stall torque
        assert p.current_limit_A[0] > s.supply_voltage_V / p.resistance_ohm[0]


def _servo_output(gains, goal, pos, steps=1, period=1e-3):
    servo = DynamixelPositionServo([XM430_W350], gains, control_period_s=period)
    ctx = servo.CreateDefaultContext()
    servo.GetInputPort("goal_position").FixValue(ctx, [goal])
    servo.GetInputPort("joint_position").FixValue(ctx, [pos])
    for _ in range(steps):
        state = servo.EvalUniquePeriodicDiscreteUpdate(ctx)
        ctx.SetDiscreteState(state.value())
    return servo.GetOutputPort("voltage_command").Eval(ctx)[0], servo.GetOutputPort("pwm").Eval(ctx)[0]


def test_p_term_units_and_quantisation():
    e_pulses = 100
    v, pwm = _servo_output(ServoGains((800,), (0,), (0,)), e_pulses / PULSES_PER_RAD, 0.0)
    assert pwm == pytest.approx(800 / 128 * e_pulses)
    assert v == pytest.approx(pwm / PWM_FULL_SCALE * 12.0)
    # below half a pulse of error the encoder sees nothing
    v_small, _ = _servo_output(ServoGains((800,), (0,), (0,)), 0.4 / PULSES_PER_RAD, 0.0)
    assert v_small == 0.0


def test_saturation_and_integral_clamp():
    v, pwm = _servo_output(ServoGains((16000,), (16000,), (0,)), 1.0, 0.0, steps=50)
    assert pwm == PWM_FULL_SCALE and v == pytest.approx(12.0)
    v_neg, _ = _servo_output(ServoGains((16000,), (0,), (0,)), -1.0, 0.0)
    assert v_neg == pytest.approx(-12.0)
    with pytest.raises(QmtInputError):
        ServoGains((-1,), (0,), (0,))


def _one_joint_loop(J_kgm2, gains, goal_rad, t_end, period=1e-3):
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultibodyPlant(1e-3))
    body = plant.AddRigidBody("disc", SpatialInertia.MakeFromCentralInertia(
        1.0, np.zeros(3), UnitInertia(J_kgm2, J_kgm2, J_kgm2)))
    joint = plant.AddJoint(RevoluteJoint("j", plant.world_frame(), body.body_frame(), [0, 0, 1]))
    plant.AddJointActuator("a", joint)
    plant.mutable_gravity_field().set_gravity_vector([0, 0, 0])
    plant.Finalize()
    servo = builder.AddSystem(DynamixelPositionServo([XM430_W350], gains, control_period_s=period))
    params = motor_params([XM430_W350])  # lossless equivalent: linear, the closed form applies
    motor = builder.AddSystem(DcMotorWithGear(params))
    split = builder.AddSystem(Demultiplexer([1, 1]))
    goal = builder.AddSystem(ConstantVectorSource([goal_rad]))
    builder.Connect(plant.get_state_output_port(), split.get_input_port())
    builder.Connect(goal.get_output_port(), servo.GetInputPort("goal_position"))
    builder.Connect(split.get_output_port(0), servo.GetInputPort("joint_position"))
    builder.Connect(servo.GetOutputPort("voltage_command"), motor.GetInputPort("voltage_command"))
    builder.Connect(split.get_output_port(1), motor.GetInputPort("joint_velocity"))
    builder.Connect(motor.GetOutputPort("joint_torque"), plant.get_actuation_input_port())
    log = LogVectorOutput(plant.get_state_output_port(), builder, 1e-3)
    diagram = builder.Build()
    sim = Simulator(diagram)
    sim.AdvanceTo(t_end)
    data = log.FindLog(sim.get_context()).data()
    return data[0], data[1]


def test_large_step_runs_at_the_datasheet_no_load_speed():
    # Light disc (b h / J < 0.1: the explicit motor torque is stable), huge step: the PWM
    # saturates and the joint cruises at V / Ke = 46 rpm.
    q, qd = _one_joint_loop(1e-2, ServoGains((800,), (0,), (0,)), 3.0, 0.5)
    assert np.max(qd) == pytest.approx(46 * 2 * math.pi / 60, rel=0.01)


def test_small_step_overshoot_matches_the_continuous_second_order_loop():
    # P-only loop on an inertia J with a lossless gear (the model's motoring loss makes the loop
    # asymmetric): J qdd = Ke/R (kp (g - q)) - Ke^2/R qd below saturation.
    J = 0.03
    gains = ServoGains((800,), (0,), (0,))
    q, _ = _one_joint_loop(J, gains, 0.05, 1.5)
    s = XM430_W350
    kp = gains.continuous_equivalent([s])["kp_V_per_rad"][0]
    g = s.stall_torque_Nm / s.supply_voltage_V  # joint torque per volt at standstill
    k, b = g * kp, g * s.back_emf_V_s_per_rad
    zeta = b / (2 * math.sqrt(k * J))
    overshoot_pred = math.exp(-math.pi * zeta / math.sqrt(1 - zeta**2))
    overshoot_sim = (np.max(q) - 0.05) / 0.05
    assert 0.05 < overshoot_pred < 0.9
    assert overshoot_sim == pytest.approx(overshoot_pred, abs=0.04)
    assert abs(q[-1] - 0.05) < 2.5 / PULSES_PER_RAD  # settles within the encoder's quantisation
