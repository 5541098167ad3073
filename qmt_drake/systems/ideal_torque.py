"""Signals of an ideal joint torque source (actuator.kind 'ideal'): no motor, an ideal gear.

Given the joint torque actually applied over a step and the joint speed, reports what the
co-simulation monitors for a motor, with the same port names as dc_motor.AppliedMotorSignals:

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
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem


class IdealActuatorSignals(LeafSystem):
    """See the module docstring."""

    def __init__(self, gear_ratio):
        super().__init__()
        self._inv_N = (1.0 / np.asarray(gear_ratio, float)).tolist()
        n = len(self._inv_N)
        self._tau_in = self.DeclareVectorInputPort("applied_joint_torque", n)
        self._qd_in = self.DeclareVectorInputPort("joint_velocity", n)
        self.DeclareVectorOutputPort("joint_torque", n, lambda c, o: o.SetFromVector(self._tau_in.Eval(c)))
        self.DeclareVectorOutputPort("motor_torque", n, lambda c, o: o.SetFromVector(
            self._tau_in.Eval(c) * self._inv_N))
        self.DeclareVectorOutputPort("current", n, lambda c, o: o.SetFromVector(np.zeros(n)))
        self.DeclareVectorOutputPort("electrical_power", n, lambda c, o: o.SetFromVector(
            self._tau_in.Eval(c) * self._qd_in.Eval(c)))
