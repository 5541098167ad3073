"""HandState: what the limits need to know about the hand, for many samples at once.

A HandState is made by an arm's kinematics/dynamics backend (model/planar.py for arms whose joints
all turn about parallel axes, model/drake_chain.py for any serial arm) from joint positions,
velocities and accelerations q, qd, qdd of shape (S, n). Fields are computed on first use and then
kept, so a limit that needs only the joint torques never pays for orientations.

World-frame quantities of the hand frame H (origin and axes), SI units:
    position_m (S, 3), rotation (S, 3, 3) = R_WH, linear_velocity_m_s (S, 3),
    angular_velocity_rad_s (S, 3), linear_acceleration_m_s2 (S, 3), angular_acceleration_rad_s2 (S, 3),
    joint_torque_Nm (S, n): inverse dynamics with gravity, the reflected rotor inertia N^2 J_r qdd and
        the carried part (welded to the hand in the planning plant).
Planar backends also give planar_acceleration_m_s2 (S, 2): the hand acceleration in the arm's plane
coordinates (`PlanarChain.plane_axes`).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np


class HandState:
    def __init__(self, backend, q, qd, qdd) -> None:
        self.backend = backend
        self.q = np.atleast_2d(q)
        self.qd = np.atleast_2d(qd)
        self.qdd = np.atleast_2d(qdd)

    @property
    def n_samples(self) -> int:
        return self.q.shape[0]

    @cached_property
    def _pose(self):
        return self.backend.hand_pose(self.q)

    @property
    def position_m(self) -> np.ndarray:
        return self._pose[0]

    @property
    def rotation(self) -> np.ndarray:
        return self._pose[1]

    @cached_property
    def _velocity(self):
        return self.backend.hand_velocity(self.q, self.qd)

    @property
    def linear_velocity_m_s(self) -> np.ndarray:
        return self._velocity[0]

    @property
    def angular_velocity_rad_s(self) -> np.ndarray:
        return self._velocity[1]

    @cached_property
    def _dynamics(self) -> dict:
        """One inverse-dynamics pass (the backend's `dynamics`); world-frame accelerations are
        added on first use (planar backends compute them from the in-plane ones)."""
        return self.backend.dynamics(self.q, self.qd, self.qdd)

    def _world_accelerations(self):
        d = self._dynamics
        if "linear_acceleration_m_s2" not in d:
            d.update(self.backend.world_accelerations(self.qdd, d))
        return d

    @property
    def linear_acceleration_m_s2(self) -> np.ndarray:
        return self._world_accelerations()["linear_acceleration_m_s2"]

    @property
    def angular_acceleration_rad_s2(self) -> np.ndarray:
        return self._world_accelerations()["angular_acceleration_rad_s2"]

    @property
    def joint_torque_Nm(self) -> np.ndarray:
        return self._dynamics["joint_torque_Nm"]

    @property
    def planar_acceleration_m_s2(self) -> np.ndarray:
        """(S, 2) in-plane hand acceleration (planar backends only)."""
        return self._dynamics["planar_acceleration_m_s2"]
