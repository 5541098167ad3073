"""Joint speed limit: |qd_i| <= fraction * v_i (the URDF's velocity limits, or the actuators'
no-load speeds), a ratio column per joint; its TOPP-RA form bounds qd_i^2."""

from __future__ import annotations

import numpy as np

from qmt_drake.limits.base import LimitTerm, RowOptions


class JointSpeedTerm(LimitTerm):
    name = "joint_speed"
    kind = "ratio"
    scaling = "none"  # lam times slower divides it by lam, not lam^2

    def __init__(self, arm, fraction: float = 1.0, speed_limit_rad_s=None) -> None:
        if not fraction > 0:
            raise ValueError(f"joint speed fraction {fraction} must be positive")
        v = (np.array([j.velocity_upper_limits()[0] for j in arm.joints], float) if speed_limit_rad_s is None
             else np.asarray(speed_limit_rad_s, float))
        if not np.all(np.isfinite(v) & (v > 0)):
            raise ValueError("the URDF declares no finite joint velocity limits")
        self.limit_rad_s = fraction * v
        self.column_names = tuple(f"joint_speed[{n}]" for n in arm.joint_names)

    def columns(self, state) -> np.ndarray:
        return np.abs(state.qd) / self.limit_rad_s

    def toppra_w(self, state):
        return (state.qd / self.limit_rad_s) ** 2

    def toppra_rows(self, options: RowOptions):
        n = self.limit_rad_s.size
        return np.eye(n), np.ones(n)
