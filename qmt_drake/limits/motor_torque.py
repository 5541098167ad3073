"""Motor torques (seed 000, eq. 2-34): |tau_i / N_i| <= the motor's limit, one column per motor.

tau is the joint torque of inverse dynamics with gravity, the reflected rotor inertia N^2 J_r qdd
and the carried part (HandState.joint_torque_Nm). Purely inertial (scaling lam^-2) only when
gravity does no work on the joints (horizontal arms)."""

from __future__ import annotations

import numpy as np

from qmt_drake.limits.base import LimitTerm, RowOptions


class MotorTorqueTerm(LimitTerm):
    name = "motor_torque"
    kind = "ratio"

    def __init__(self, arm, motor_torque_limit_Nm) -> None:
        self.limit_Nm = np.asarray(motor_torque_limit_Nm, float)
        self.gear_ratio = np.asarray(arm.gear_ratio, float)
        self.joint_limit_Nm = self.gear_ratio * self.limit_Nm
        self.column_names = tuple(f"motor_torque[{name}]" for name in arm.joint_names)
        self.scaling = "inverse_square" if arm.gravity_does_no_work else "none"

    def motor_torque_Nm(self, state) -> np.ndarray:
        return state.joint_torque_Nm / self.gear_ratio

    def columns(self, state) -> np.ndarray:
        return np.abs(state.joint_torque_Nm) / self.joint_limit_Nm

    def toppra_w(self, state):
        return state.joint_torque_Nm / self.joint_limit_Nm

    def toppra_rows(self, options: RowOptions):
        n = self.limit_Nm.size
        return np.concatenate([np.eye(n), -np.eye(n)]), np.ones(2 * n)
