"""Joint ranges from the URDF: columns q - upper and lower - q (rad), held while <= 0."""

from __future__ import annotations

import numpy as np

from qmt_drake.limits.base import LimitTerm


class JointRangeTerm(LimitTerm):
    name = "joint_range"
    kind = "excess"
    scaling = "invariant"

    def __init__(self, arm) -> None:
        self.lower_rad = np.asarray(arm.joint_lower_rad, float)
        self.upper_rad = np.asarray(arm.joint_upper_rad, float)
        self.column_names = tuple(f"above[{j}]" for j in arm.joint_names) + tuple(
            f"below[{j}]" for j in arm.joint_names)

    def columns(self, state) -> np.ndarray:
        return np.concatenate([state.q - self.upper_rad, self.lower_rad - state.q], axis=1)
