"""JointPidController: closed-loop poles against a numerical linearisation of the Drake loop,
the thesis-gain reading, anti-windup and the feedforward voltage."""

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Demultiplexer

from qmt_drake.systems.dc_motor import DcMotorParams, DcMotorWithGear
from qmt_drake.systems.joint_tracking import JointPidController, PidGains, effective_joint_gains
from qmt_drake.transfer_scenario import load_scenario

Q0 = np.array([0.56, 0.72])


def _loop(urdf, gains, motor):
    b = DiagramBuilder()
    plant = b.AddSystem(MultibodyPlant(0.0))
    Parser(plant).AddModels(str(urdf))
    plant.Finalize()
    n = plant.num_positions()
    ref = b.AddSystem(ConstantVectorSource(np.concatenate([Q0, np.zeros(n)])))
    pid = b.AddSystem(JointPidController(gains, motor.gear_ratio, motor.voltage_limit_V))
    mot = b.AddSystem(DcMotorWithGear(motor))
    split = b.AddSystem(Demultiplexer([n, n]))
    b.Connect(ref.get_output_port(), pid.GetInputPort("desired_state"))
    b.Connect(plant.get_state_output_port(), pid.GetInputPort("estimated_state"))
    b.Connect(plant.get_state_output_port(), split.get_input_port())
    b.Connect(split.get_output_port(1), mot.GetInputPort("joint_velocity"))
    b.Connect(pid.GetOutputPort("voltage_command"), mot.GetInputPort("voltage_command"))
    b.Connect(mot.GetOutputPort("joint_torque"), plant.get_actuation_input_port())
    return b.Build(), plant


def _numerical_A(diagram, x0, h=1e-7):
    ctx = diagram.CreateDefaultContext()
    nx = len(x0)
    A = np.zeros((nx, nx))
    for j in range(nx):
        cols = []
        for s in (+1, -1):
            x = x0.copy()
            x[j] += s * h
            ctx.SetContinuousState(x)
            cols.append(diagram.EvalTimeDerivatives(ctx).CopyToVector())
        A[:, j] = (cols[0] - cols[1]) / (2 * h)
    return A


def test_poles_of_drake_loop_match_closed_form():
    sc = load_scenario("thesis-ch4")
    gains = PidGains.from_thesis(sc.control["kp"], sc.control["ki"], sc.control["kd"])
    # Lossless gear so the loop is linear around rest (the efficiency switches with the power's sign).
    motor = DcMotorParams.for_rated_torques(sc.limits.motor_torque_limit_Nm, sc.gear_ratio, efficiency=1.0)
    diagram, plant = _loop(sc.urdf_path, gains, motor)
    A = _numerical_A(diagram, np.concatenate([Q0, np.zeros(2)]))
    eig_drake = np.sort_complex(np.linalg.eigvals(A))
    # Closed form: det(M s^2 + D s + K) = 0 with M from the plant (incl. N^2 rotor inertia).
    pc = plant.CreateDefaultContext()
    plant.SetPositions(pc, Q0)
    M = plant.CalcMassMatrix(pc)
    K, D = effective_joint_gains(gains, motor)
    Minv = np.linalg.inv(M)
    companion = np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ np.diag(K), -Minv @ np.diag(D)]])
    eig_closed = np.sort_complex(np.linalg.eigvals(companion))
    np.testing.assert_allclose(eig_drake, eig_closed, rtol=1e-5)
    assert np.all(eig_drake.real < 0)


def test_thesis_gains_literal_si_reading_has_a_slow_pole_the_adopted_one_does_not():
    sc = load_scenario("thesis-ch4")
    kp, kd = np.array(sc.control["kp"]), np.array(sc.control["kd"])
    plant = sc.arm.plant
    pc = plant.CreateDefaultContext()
    plant.SetPositions(pc, Q0)
    M = plant.CalcMassMatrix(pc)

    def poles(K, D):
        Minv = np.linalg.inv(M)
        return np.linalg.eigvals(np.block([[np.zeros((2, 2)), np.eye(2)],
                                           [-Minv @ np.diag(K), -Minv @ np.diag(D)]]))

    literal = poles(kp, kd)  # N*m/rad and N*m*s/rad at the joint
    slowest = np.min(np.abs(literal.real))
    assert slowest == pytest.approx(np.min(kp / kd), rel=0.05)  # ~0.29 rad/s: 3.5 s time constant
    motor = DcMotorParams.for_rated_torques(sc.limits.motor_torque_limit_Nm, sc.gear_ratio)
    K, D = effective_joint_gains(PidGains.from_thesis(kp, None, kd), motor)
    adopted = poles(K, D)
    assert np.min(np.abs(adopted.real)) > 50.0  # every mode faster than 20 ms
    zeta = -adopted.real / np.abs(adopted)
    assert np.all(zeta > 0.5)  # well damped


def _pid_alone(ki, vmax, err):
    gains = PidGains([1.0], [ki], [0.0])
    pid = JointPidController(gains, [1.0], [vmax], control_period_s=1e-3)
    sim = Simulator(pid)
    ctx = sim.get_mutable_context()
    pid.GetInputPort("desired_state").FixValue(ctx, [err, 0.0])
    pid.GetInputPort("estimated_state").FixValue(ctx, [0.0, 0.0])
    sim.AdvanceTo(1.0)
    return ctx.get_discrete_state_vector().GetAtIndex(0), pid.GetOutputPort("voltage_command").Eval(ctx)[0]


def test_integral_clamps_under_saturation():
    z_free, v_free = _pid_alone(ki=2.0, vmax=100.0, err=0.5)
    assert z_free == pytest.approx(0.5 * 1.0, rel=2e-3)  # integral of a constant error over 1 s
    assert v_free == pytest.approx(0.5 + 2.0 * z_free, rel=1e-9)
    z_sat, v_sat = _pid_alone(ki=2.0, vmax=0.4, err=0.5)  # P alone already saturates
    assert z_sat == 0.0
    assert v_sat == 0.4


def test_torque_feedforward_through_motor_gives_the_torque_back():
    sc = load_scenario("thesis-ch4")
    motor = DcMotorParams.for_rated_torques(sc.limits.motor_torque_limit_Nm, sc.gear_ratio)
    gains = PidGains.from_thesis(sc.control["kp"], None, sc.control["kd"])
    pid = JointPidController(gains, motor.gear_ratio, motor.voltage_limit_V, motor=motor, torque_feedforward=True)
    mot = DcMotorWithGear(motor)
    pc, mc = pid.CreateDefaultContext(), mot.CreateDefaultContext()
    tau = np.array([0.8, -0.3])
    pid.GetInputPort("desired_state").FixValue(pc, np.zeros(4))
    pid.GetInputPort("estimated_state").FixValue(pc, np.zeros(4))
    pid.GetInputPort("feedforward_torque").FixValue(pc, tau)
    mot.GetInputPort("voltage_command").FixValue(mc, pid.GetOutputPort("voltage_command").Eval(pc))
    mot.GetInputPort("joint_velocity").FixValue(mc, np.zeros(2))
    np.testing.assert_allclose(mot.GetOutputPort("joint_torque").Eval(mc), tau, rtol=1e-12)
