"""ArmModel: a planar serial arm on a Drake MultibodyPlant, with a batched evaluator for planning.

The plant (continuous-time, parsed from the URDF) is the reference model. Planning evaluates
thousands of candidate trajectories at thousands of samples each, so the class also extracts the
planar link parameters from the plant once and evaluates kinematics and inverse dynamics for whole
arrays of states with numpy (planar recursive Newton-Euler). `tests/test_arm.py` checks the batched
results against Drake's `CalcInverseDynamics` and frame accelerations on random states.

Shapes: joint arrays are (..., n) with any leading dimensions; tip quantities are (..., 2) in the
world x-y plane. Units: rad, rad/s, rad/s^2, m, m/s, m/s^2, N*m.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JointIndex, MultibodyForces, RevoluteJoint

from qmt_drake.errors import QmtInputError

IK_BRANCHES = ("elbow_positive", "elbow_negative")


@dataclass(frozen=True)
class PlanarLink:
    """One moving link in its own joint frame (x along the link)."""

    name: str
    mass_kg: float
    com_m: np.ndarray  # (2,) centre of mass in the link frame
    izz_about_com_kgm2: float
    next_joint_m: np.ndarray  # (2,) where the next joint (or the hand) sits in this link frame


class ArmModel:
    """A horizontal-plane serial arm with revolute joints about +z, built from a URDF.

    Attributes: `plant` (finalized continuous MultibodyPlant), `n_dof`, `links` (PlanarLink),
    `link_lengths_m` (joint-to-joint, last one joint-to-hand), `gear_ratio`, `rotor_inertia_kgm2`
    (motor side), `reflected_inertia_kgm2` (N^2 * rotor inertia, joint side),
    `joint_lower_rad`, `joint_upper_rad`, `effort_limit_Nm` (joint side, the drive's maximum).
    """

    def __init__(self, plant: MultibodyPlant, hand_frame: str = "hand", source: str = "") -> None:
        self.plant = plant
        self.source = source
        self._context = plant.CreateDefaultContext()
        self.hand_frame_name = hand_frame
        if not plant.HasFrameNamed(hand_frame):
            names = sorted({plant.get_frame(i).name() for i in _frame_indices(plant)})
            raise QmtInputError(
                f"arm model {source or '(plant)'} has no frame named '{hand_frame}'; "
                f"set arm.hand_frame to one of: {', '.join(names)}")
        self.hand_frame = plant.GetFrameByName(hand_frame)
        joints = [plant.get_joint(JointIndex(i)) for i in range(plant.num_joints())]
        self.joints = [j for j in joints if j.num_velocities() > 0]
        for j in self.joints:
            if not isinstance(j, RevoluteJoint) or not np.allclose(np.abs(j.revolute_axis()), [0, 0, 1]):
                raise QmtInputError(
                    f"joint '{j.name()}' in {source} is not a revolute joint about z; "
                    "ArmModel handles planar (horizontal) serial arms only")
        self.n_dof = len(self.joints)
        if plant.num_positions() != self.n_dof:
            raise QmtInputError(f"{source}: the arm must be welded to the world (found "
                                f"{plant.num_positions()} positions for {self.n_dof} joints)")
        self._extract_planar_parameters()
        actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
        by_joint = {a.joint().index(): a for a in actuators}
        missing = [j.name() for j in self.joints if j.index() not in by_joint]
        if missing:
            raise QmtInputError(f"{source}: joints {missing} have no actuator; add a "
                                "<transmission> with <actuator> for each joint")
        acts = [by_joint[j.index()] for j in self.joints]
        self.actuator_names = [a.name() for a in acts]
        self.gear_ratio = np.array([a.default_gear_ratio() for a in acts])
        self.rotor_inertia_kgm2 = np.array([a.default_rotor_inertia() for a in acts])
        self.reflected_inertia_kgm2 = self.gear_ratio**2 * self.rotor_inertia_kgm2
        self.effort_limit_Nm = np.array([a.effort_limit() for a in acts])
        self.joint_lower_rad = np.array([j.position_lower_limits()[0] for j in self.joints])
        self.joint_upper_rad = np.array([j.position_upper_limits()[0] for j in self.joints])
        self.joint_names = [j.name() for j in self.joints]

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_urdf(cls, urdf_path: str | Path, hand_frame: str = "hand") -> "ArmModel":
        path = Path(urdf_path)
        if not path.is_file():
            raise QmtInputError(f"URDF file not found: {path}; check arm.urdf in the scenario "
                                "(relative paths are taken from the scenario file's folder)")
        plant = MultibodyPlant(time_step=0.0)
        Parser(plant).AddModels(str(path))
        plant.Finalize()
        return cls(plant, hand_frame=hand_frame, source=str(path))

    def _extract_planar_parameters(self) -> None:
        plant = self.plant
        links = []
        for i, joint in enumerate(self.joints):
            if not joint.frame_on_child().GetFixedPoseInBodyFrame().IsExactlyIdentity():
                raise QmtInputError(f"joint '{joint.name()}': the child link frame must coincide "
                                    "with the joint frame (URDF convention)")
            body = joint.child_body()
            if i + 1 < self.n_dof:
                nxt = self.joints[i + 1]
                if nxt.parent_body().index() != body.index():
                    raise QmtInputError("ArmModel needs a serial chain: joint "
                                        f"'{nxt.name()}' is not on link '{body.name()}'")
                X = nxt.frame_on_parent().GetFixedPoseInBodyFrame()
            else:
                X = plant.CalcRelativeTransform(self._context, body.body_frame(), self.hand_frame)
            _check_planar_rotation(X, joint.name())
            spatial = body.CalcSpatialInertiaInBodyFrame(self._context)
            mass = spatial.get_mass()
            com = spatial.get_com()
            izz_origin = spatial.CalcRotationalInertia().CopyToFullMatrix3()[2, 2]
            izz_com = izz_origin - mass * (com[0] ** 2 + com[1] ** 2)
            links.append(PlanarLink(body.name(), mass, np.array(com[:2]), izz_com,
                                    np.array(X.translation()[:2])))
        self.links = links
        self.link_lengths_m = np.array([np.hypot(*lk.next_joint_m) for lk in links])
        # Angle of each link's next-joint offset in its own frame (0 for a straight link).
        self._offset_angle = np.array([np.arctan2(lk.next_joint_m[1], lk.next_joint_m[0])
                                       for lk in links])

    # ------------------------------------------------------------------ batched kinematics
    def _chain(self, q, qd, qdd):
        """Planar forward recursion. Returns per-link lists of absolute angle, rate, accel,
        joint position, joint acceleration, and the hand's position/acceleration."""
        q = np.asarray(q, dtype=float)
        phi = np.cumsum(q, axis=-1)
        w = np.cumsum(qd, axis=-1) if qd is not None else None
        al = np.cumsum(qdd, axis=-1) if qdd is not None else None
        shape = q.shape[:-1]
        p = np.zeros(shape + (2,))
        a = np.zeros(shape + (2,)) if al is not None else None
        v = np.zeros(shape + (2,)) if w is not None else None
        out = []
        for i, lk in enumerate(self.links):
            c, s = np.cos(phi[..., i]), np.sin(phi[..., i])
            out.append((c, s, p, v, a))
            d = _rotate(c, s, lk.next_joint_m)
            p = p + d
            if v is not None:
                v = v + w[..., i, None] * _perp(d)
            if a is not None:
                a = a + al[..., i, None] * _perp(d) - (w[..., i] ** 2)[..., None] * d
        return phi, w, al, out, p, v, a

    def tip_position(self, q) -> np.ndarray:
        """Hand-frame origin in the x-y plane, m, shape (..., 2)."""
        return self._chain(q, None, None)[4]

    def tool_angle(self, q) -> np.ndarray:
        """Absolute angle of the last link (hand), rad."""
        return np.sum(np.asarray(q, dtype=float), axis=-1)

    def tip_velocity(self, q, qd) -> np.ndarray:
        """Hand-frame origin velocity, m/s, shape (..., 2)."""
        return self._chain(q, qd, None)[5]

    def tip_acceleration(self, q, qd, qdd) -> np.ndarray:
        """Hand-frame origin acceleration in the plane, m/s^2, shape (..., 2)."""
        return self._chain(q, qd, qdd)[6]

    def joint_torque(self, q, qd, qdd) -> np.ndarray:
        """Inverse dynamics at the joints, N*m, including reflected rotor inertia N^2*J_r*qdd.

        Planar recursive Newton-Euler: gravity is along -z and does no work on z-axis joints.
        """
        return self.tip_acceleration_and_joint_torque(q, qd, qdd)[1]

    def tip_acceleration_and_joint_torque(self, q, qd, qdd):
        """(tip acceleration (..., 2) m/s^2, joint torque (..., n) N*m) from one pass.

        The hot path of planning: planar recursive Newton-Euler written on x and y components
        separately (no stacking of small arrays), forward for link accelerations, backward for
        forces and moments."""
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        qdd = np.asarray(qdd, dtype=float)
        n = self.n_dof
        ax = ay = 0.0  # acceleration of joint i, world
        phi = w = al = 0.0  # absolute angle, rate and angular acceleration of link i
        links = []
        for i, lk in enumerate(self.links):
            phi, w, al = phi + q[..., i], w + qd[..., i], al + qdd[..., i]
            c, s = np.cos(phi), np.sin(phi)
            wi2, ali = w * w, al
            rcx = c * lk.com_m[0] - s * lk.com_m[1]  # joint -> COM
            rcy = s * lk.com_m[0] + c * lk.com_m[1]
            dx = c * lk.next_joint_m[0] - s * lk.next_joint_m[1]  # joint -> next joint
            dy = s * lk.next_joint_m[0] + c * lk.next_joint_m[1]
            acx = ax - ali * rcy - wi2 * rcx
            acy = ay + ali * rcx - wi2 * rcy
            links.append((rcx, rcy, dx, dy, acx, acy, ali))
            ax = ax - ali * dy - wi2 * dx
            ay = ay + ali * dx - wi2 * dy
        a_tip = np.stack(np.broadcast_arrays(ax, ay), axis=-1)
        tau = np.empty(np.broadcast_shapes(q.shape, qd.shape, qdd.shape))
        fx = fy = nz = 0.0  # force and moment link i+1 takes from link i (at the next joint)
        for i in range(n - 1, -1, -1):
            lk = self.links[i]
            rcx, rcy, dx, dy, acx, acy, ali = links[i]
            mx, my = lk.mass_kg * acx, lk.mass_kg * acy
            nz = lk.izz_about_com_kgm2 * ali + rcx * my - rcy * mx + nz + dx * fy - dy * fx
            fx, fy = mx + fx, my + fy
            tau[..., i] = nz
        return a_tip, tau + self.reflected_inertia_kgm2 * qdd

    def motor_torque(self, q, qd, qdd) -> np.ndarray:
        """Motor-side torque, N*m: joint torque / gear ratio (eq. 2-34)."""
        return self.joint_torque(q, qd, qdd) / self.gear_ratio

    def jacobian(self, q) -> np.ndarray:
        """d(tip x, tip y)/dq, shape (..., 2, n)."""
        q = np.asarray(q, dtype=float)
        _, _, _, per_link, tip, _, _ = self._chain(q, None, None)
        J = np.empty(q.shape[:-1] + (2, self.n_dof))
        for i in range(self.n_dof):
            r = tip - per_link[i][2]
            J[..., 0, i] = -r[..., 1]
            J[..., 1, i] = r[..., 0]
        return J

    # ------------------------------------------------------------------ inverse kinematics
    def inverse_kinematics(self, xy, tool_angle_rad: float | None = None,
                           branch: str = "elbow_positive", check_range: bool = True,
                           what: str = "point") -> np.ndarray:
        """Analytic planar IK for the hand origin at `xy` (..., 2).

        2 joints: position only. 3 joints: `tool_angle_rad` (absolute angle of the last link,
        theta_p = q1+q2+q3, eq. 2-2) is required. `branch` picks the sign of the elbow joint q2:
        'elbow_positive' (q2 > 0) or 'elbow_negative'. Raises QmtInputError naming the point and
        the reach when it cannot be reached, or the joint range it leaves.
        """
        if branch not in IK_BRANCHES:
            raise QmtInputError(f"unknown IK branch '{branch}'; use one of {IK_BRANCHES}")
        if any(abs(a) > 1e-12 for a in self._offset_angle):
            raise QmtInputError("analytic IK needs straight links (next joint on the link's x axis)")
        xy = np.asarray(xy, dtype=float)
        L = self.link_lengths_m
        if self.n_dof == 2:
            wrist = xy
        elif self.n_dof == 3:
            if tool_angle_rad is None:
                raise QmtInputError("a 3-joint arm needs task.tool_angle_rad (theta_p = q1+q2+q3)")
            wrist = xy - L[2] * np.stack([np.cos(tool_angle_rad) * np.ones(xy.shape[:-1]),
                                          np.sin(tool_angle_rad) * np.ones(xy.shape[:-1])], -1)
        else:
            raise QmtInputError(f"analytic IK supports 2 or 3 joints, not {self.n_dof}")
        r = np.hypot(wrist[..., 0], wrist[..., 1])
        r_min, r_max = abs(L[0] - L[1]), L[0] + L[1]
        bad = (r > r_max * (1 + 1e-12)) | (r < r_min * (1 - 1e-12))
        if np.any(bad):
            k = np.flatnonzero(np.atleast_1d(bad))[0]
            p = np.atleast_2d(xy)[k]
            raise QmtInputError(
                f"{what} ({p[0]:.4f}, {p[1]:.4f}) m is unreachable: its wrist lies "
                f"{np.atleast_1d(r)[k]:.4f} m from the base, the reach is "
                f"[{r_min:.4f}, {r_max:.4f}] m (links {', '.join(f'{v:.3f}' for v in L)} m)")
        c2 = np.clip((r**2 - L[0] ** 2 - L[1] ** 2) / (2 * L[0] * L[1]), -1.0, 1.0)
        q2 = np.arccos(c2) * (1.0 if branch == "elbow_positive" else -1.0)
        q1 = np.arctan2(wrist[..., 1], wrist[..., 0]) - np.arctan2(L[1] * np.sin(q2),
                                                                    L[0] + L[1] * np.cos(q2))
        qs = [q1, q2]
        if self.n_dof == 3:
            qs.append(tool_angle_rad - q1 - q2)
        q = np.stack(qs, axis=-1)
        # Wrap to (-pi, pi] so a range check sees the same angle as the thesis's figures.
        q = (q + np.pi) % (2 * np.pi) - np.pi
        if check_range:
            self.check_joint_range(q, what=f"IK solution of {what} (branch {branch})")
        return q

    def check_joint_range(self, q, what: str = "joint trajectory") -> None:
        q = np.atleast_2d(q)
        lo_bad = q < self.joint_lower_rad - 1e-12
        hi_bad = q > self.joint_upper_rad + 1e-12
        if np.any(lo_bad | hi_bad):
            k, j = np.argwhere(lo_bad | hi_bad)[0]
            raise QmtInputError(
                f"{what}: joint {self.joint_names[j]} = {q[k, j]:.4f} rad leaves its range "
                f"[{self.joint_lower_rad[j]:.4f}, {self.joint_upper_rad[j]:.4f}] rad; choose the "
                "other IK branch or widen the joint limits in the URDF")

    # ------------------------------------------------------------------ Drake reference
    def drake_inverse_dynamics(self, q, qd, qdd) -> np.ndarray:
        """Joint torques from Drake's CalcInverseDynamics at one state (reference, slow)."""
        plant, ctx = self.plant, self._context
        plant.SetPositions(ctx, q)
        plant.SetVelocities(ctx, qd)
        return plant.CalcInverseDynamics(ctx, qdd, MultibodyForces(plant))

    def drake_tip_acceleration(self, q, qd, qdd) -> np.ndarray:
        """In-plane acceleration of the hand origin from Drake (J*qdd + Jdot*qd), one state."""
        from pydrake.multibody.tree import JacobianWrtVariable
        plant, ctx = self.plant, self._context
        plant.SetPositions(ctx, q)
        plant.SetVelocities(ctx, qd)
        world = plant.world_frame()
        J = plant.CalcJacobianTranslationalVelocity(ctx, JacobianWrtVariable.kV, self.hand_frame,
                                                    np.zeros(3), world, world)
        bias = plant.CalcBiasTranslationalAcceleration(ctx, JacobianWrtVariable.kV,
                                                       self.hand_frame, np.zeros(3), world, world)
        return (J @ qdd + bias[:, 0])[:2]

    def drake_tip_position(self, q) -> np.ndarray:
        plant, ctx = self.plant, self._context
        plant.SetPositions(ctx, q)
        X: RigidTransform = self.hand_frame.CalcPoseInWorld(ctx)
        return X.translation()[:2]


def _frame_indices(plant):
    from pydrake.multibody.tree import FrameIndex
    return [FrameIndex(i) for i in range(plant.num_frames())]


def _check_planar_rotation(X: RigidTransform, name: str) -> None:
    R = X.rotation().matrix()
    if abs(R[2, 2] - 1.0) > 1e-9:
        raise QmtInputError(f"the frame after joint '{name}' is tilted out of the x-y plane; "
                            "ArmModel handles horizontal planar arms only")
    if abs(R[1, 0]) > 1e-12:
        raise QmtInputError(f"the frame after joint '{name}' is rotated about z; give joint "
                            "angles a zero offset (put the rotation into the joint angle)")


def _rotate(c, s, v) -> np.ndarray:
    """Rotate a fixed 2-vector v by angle (c=cos, s=sin arrays); returns (..., 2)."""
    return np.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]], axis=-1)


def _perp(v) -> np.ndarray:
    """z x v for a planar vector v (..., 2)."""
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def _cross(a, b) -> np.ndarray:
    """z-component of a x b for planar vectors."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
