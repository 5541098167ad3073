"""Signals of an ideal joint torque source (actuator.kind 'ideal'): no motor, an ideal gear.

Given the joint torque actually applied over a step and the joint speed, reports what the
co-simulation monitors for a motor, with the same port names as the motors' applied signals
(dc_motor.applied_motor_signals_as_primitives):

    joint_torque      (n,) [N*m]  the applied joint torque, passed through
    motor_torque      (n,) [N*m]  tau / N: motor-side torque behind an ideal (lossless) gear of ratio N
    current           (n,) [A]    zeros (no motor)
    electrical_power  (n,) [W]    tau * qd: the MECHANICAL power delivered to the joints (the energy
                                  the monitor integrates is then the net mechanical work)

Ports
    inputs
        applied_joint_torque  (n,) [N*m]
        joint_velocity        (n,) [rad/s]
    outputs as listed above.

Needs: the applied torque of the step (sim.actuation.add_ideal_torque_actuation latches it).
A Diagram of Drake primitives (no Python per evaluation; a plain Diagram, which pydrake frees).
"""

from __future__ import annotations

import numpy as np
from pydrake import symbolic
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, MatrixGain, Multiplexer, PassThrough

from qmt_drake.systems.scalar_ops import symbolic_law


def ideal_actuator_signals(gear_ratio):
    """The module docstring's signals for joints behind ideal gears of ratio gear_ratio (n,)."""
    inv_N = 1.0 / np.asarray(gear_ratio, float).reshape(-1)
    n = len(inv_N)
    b = DiagramBuilder()
    tau = b.AddNamedSystem("applied_joint_torque", PassThrough(n))
    qd = b.AddNamedSystem("joint_velocity", PassThrough(n))
    motor = b.AddNamedSystem("motor_torque", MatrixGain(np.diag(inv_N)))
    t = [symbolic.Variable(f"tau_{k}") for k in range(n)]
    w = [symbolic.Variable(f"qd_{k}") for k in range(n)]
    both = b.AddNamedSystem("inputs", Multiplexer([n, n]))
    power = b.AddNamedSystem("electrical_power", symbolic_law(t + w, [a * v for a, v in zip(t, w)]))
    zero = b.AddNamedSystem("current", ConstantVectorSource(np.zeros(n)))
    b.Connect(tau.get_output_port(), motor.get_input_port())
    b.Connect(tau.get_output_port(), both.get_input_port(0))
    b.Connect(qd.get_output_port(), both.get_input_port(1))
    b.Connect(both.get_output_port(), power.get_input_port())
    b.ExportInput(tau.get_input_port(), "applied_joint_torque")
    b.ExportInput(qd.get_input_port(), "joint_velocity")
    b.ExportOutput(tau.get_output_port(), "joint_torque")
    b.ExportOutput(motor.get_output_port(), "motor_torque")
    b.ExportOutput(zero.get_output_port(), "current")
    b.ExportOutput(power.get_output_port(), "electrical_power")
    diagram = b.Build()
    diagram.set_name("ideal_actuator_signals")
    return diagram
