"""DrakeChain: the hand state of any serial arm, from Drake's own multibody algorithms.

The general backend (spatial arms, joints about non-parallel axes, prismatic joints): per sample,
the plant's `CalcJacobianSpatialVelocity` and `CalcBiasSpatialAcceleration` of the hand frame give
its velocity and acceleration, and `CalcInverseDynamics` with the force elements' contribution
(gravity) gives the joint torques, reflected rotor inertia included. It loops over samples in
Python (tens of microseconds each), so it suits TOPP-RA grids and re-checks; planar arms use the
batched PlanarChain, which is checked against this one.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces


class DrakeChain:
    def __init__(self, plant, hand_frame) -> None:
        self.plant = plant
        self.hand_frame = hand_frame
        self.n_dof = plant.num_velocities()
        self._ctx = plant.CreateDefaultContext()
        self._forces = MultibodyForces(plant)

    def _set(self, q, qd=None):
        self.plant.SetPositions(self._ctx, q)
        self.plant.SetVelocities(self._ctx, np.zeros(self.n_dof) if qd is None else qd)

    def hand_pose(self, q):
        q = np.atleast_2d(q)
        p = np.empty((q.shape[0], 3))
        R = np.empty((q.shape[0], 3, 3))
        for k, qk in enumerate(q):
            self._set(qk)
            X = self.hand_frame.CalcPoseInWorld(self._ctx)
            p[k], R[k] = X.translation(), X.rotation().matrix()
        return p, R

    def _jacobian(self):
        world = self.plant.world_frame()
        return self.plant.CalcJacobianSpatialVelocity(self._ctx, JacobianWrtVariable.kV, self.hand_frame,
                                                      np.zeros(3), world, world)

    def spatial_jacobian(self, q) -> np.ndarray:
        """(S, 6, n): rows (angular; translational) of the hand's spatial velocity in world."""
        q = np.atleast_2d(q)
        out = np.empty((q.shape[0], 6, self.n_dof))
        for k, qk in enumerate(q):
            self._set(qk)
            out[k] = self._jacobian()
        return out

    def hand_velocity(self, q, qd):
        J = self.spatial_jacobian(q)
        V = np.einsum("sij,sj->si", J, np.atleast_2d(qd))
        return V[:, 3:], V[:, :3]

    def dynamics(self, q, qd, qdd) -> dict:
        lin, ang, tau, _ = self.hand_acceleration_and_joint_torque(q, qd, qdd)
        return {"linear_acceleration_m_s2": lin, "angular_acceleration_rad_s2": ang, "joint_torque_Nm": tau}

    def hand_acceleration_and_joint_torque(self, q, qd, qdd):
        q, qd, qdd = np.atleast_2d(q), np.atleast_2d(qd), np.atleast_2d(qdd)
        S = q.shape[0]
        lin, ang, tau = np.empty((S, 3)), np.empty((S, 3)), np.empty((S, self.n_dof))
        world = self.plant.world_frame()
        for k in range(S):
            self._set(q[k], qd[k])
            A = self._jacobian() @ qdd[k]
            bias = self.plant.CalcBiasSpatialAcceleration(self._ctx, JacobianWrtVariable.kV, self.hand_frame,
                                                          np.zeros(3), world, world)
            ang[k] = A[:3] + bias.rotational()
            lin[k] = A[3:] + bias.translational()
            self._forces.SetZero()
            self.plant.CalcForceElementsContribution(self._ctx, self._forces)
            tau[k] = self.plant.CalcInverseDynamics(self._ctx, qdd[k], self._forces)
        return lin, ang, tau, {}
