"""PlanarChain: batched kinematics and dynamics of a serial arm whose joints all turn about
parallel axes (a planar arm, in a horizontal, vertical or any world coordinate plane).

The parameters are read from a finalized Drake MultibodyPlant at q = 0, in world coordinates, so
joint axis signs (+n or -n), base offsets, a yawed base, joint zero offsets and links bent out of
their x axis all come out right without assumptions about the URDF's conventions:

- the plane: the world coordinate plane whose normal is parallel to every joint axis; in-plane
  coordinates (u, v) are world (x, y) for a z normal, (x, z) for a y normal, (y, z) for an x
  normal (`plane_axes`, columns e_u, e_v; `normal` = e_u x e_v). Other planes are refused.
- joint i turns by s_i q_i about `normal` (s_i = +1 or -1: `joint_signs`); the absolute angle of
  link i is phi_i = s_1 q_1 + ... + s_i q_i, and every vector fixed in link i rotates by phi_i from
  its q = 0 direction;
- link i = every body between joint i and joint i+1 (welded bodies lumped, the carried part
  welded to the hand included), with its mass, its centre of mass and its inertia about the
  normal through its centre of mass;
- gravity: only its in-plane component (`gravity_in_plane_m_s2`) does work on such joints.

Inverse dynamics is a planar recursive Newton-Euler written on u and v components separately
(no small-array stacking: it is the hot path of planning), forward for link accelerations with the
base accelerating at -g, backward for forces and moments; joint torque tau_i = s_i * moment about
the normal + N_i^2 J_r,i qdd_i (the reflected rotor inertia, as Drake adds it). The same recursion
run on `Tangent`s (model/tangent.py: forward-mode derivatives, one tangent per entry of q, qd, qdd)
gives the exact partials d tau / d q, d qd, d qdd for gradient planners (`torque_and_derivatives`;
tested against Drake's MultibodyPlant<AutoDiffXd> in tests/test_model.py and
tests/test_energy_dynamics.py).
`ArmModel` (model/arm.py) checks all of this against Drake at load time.

Shapes: joint arrays (..., n); in-plane vectors (..., 2). Units: rad, rad/s, rad/s^2, m, m/s,
m/s^2, N*m.
"""

from __future__ import annotations

import copy

import numpy as np
from pydrake.multibody.tree import BodyIndex, RevoluteJoint

from qmt_drake.catalog import IK_BRANCHES  # noqa: F401 (re-exported)
from qmt_drake.errors import QmtInputError
from qmt_drake.model.tangent import Tangent

# World coordinate planes: normal axis index -> (in-plane axis indices u, v); normal = e_u x e_v.
_PLANES = {2: (0, 1), 1: (0, 2), 0: (1, 2)}


class PlanarChain:
    """See the module docstring. Build with `PlanarChain.from_plant(plant, context, joints,
    hand_frame, reflected_inertia, source)`."""

    def __init__(self, *, plane_axes, joint_signs, base_m, next_joint_m, com_m, mass_kg,
                 izz_about_com_kgm2, reflected_inertia_kgm2, gravity_in_plane_m_s2,
                 hand_normal_offset_m, hand_rotation_at_zero) -> None:
        self.plane_axes = np.asarray(plane_axes, float)  # (3, 2)
        self.normal = np.cross(self.plane_axes[:, 0], self.plane_axes[:, 1])
        self.joint_signs = np.asarray(joint_signs, float)
        self.n_dof = self.joint_signs.size
        self.base_m = np.asarray(base_m, float)  # joint 1 in plane coordinates
        self.next_joint_m = np.asarray(next_joint_m, float)  # (n, 2) joint i -> i+1 (hand) at q=0
        self.com_m = np.asarray(com_m, float)  # (n, 2) joint i -> centre of mass of link i at q=0
        self.mass_kg = np.asarray(mass_kg, float)
        self.izz_about_com_kgm2 = np.asarray(izz_about_com_kgm2, float)
        self.reflected_inertia_kgm2 = np.asarray(reflected_inertia_kgm2, float)
        self.gravity_in_plane_m_s2 = np.asarray(gravity_in_plane_m_s2, float)
        self.hand_normal_offset_m = float(hand_normal_offset_m)
        self.hand_rotation_at_zero = np.asarray(hand_rotation_at_zero, float)
        self.link_lengths_m = np.hypot(self.next_joint_m[:, 0], self.next_joint_m[:, 1])
        # Direction of each link's joint-to-joint vector at q = 0 (beta_i).
        self.link_angle_at_zero = np.arctan2(self.next_joint_m[:, 1], self.next_joint_m[:, 0])
        self._uv = [(float(a), float(b)) for a, b in self.next_joint_m]
        self._cuv = [(float(a), float(b)) for a, b in self.com_m]

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_plant(cls, plant, context, joints, hand_frame, reflected_inertia_kgm2, source: str):
        """Read the chain from `plant` at its default (q = 0) `context`. Raises QmtInputError naming
        what makes the arm non-planar."""
        world = plant.world_frame()
        axes, origins = [], []
        for j in joints:
            if not isinstance(j, RevoluteJoint):
                raise QmtInputError(f"{source}: joint '{j.name()}' is a {j.type_name()} joint; the planar "
                                    "model takes revolute joints only")
            X_WF = j.frame_on_parent().CalcPoseInWorld(context)
            axes.append(X_WF.rotation().matrix() @ np.asarray(j.revolute_axis(), float))
            origins.append(X_WF.translation())
        axes = np.array(axes)
        k = int(np.argmax(np.abs(axes[0])))
        if abs(abs(axes[0, k]) - 1.0) > 1e-9:
            raise QmtInputError(f"{source}: joint '{joints[0].name()}' turns about {np.round(axes[0], 6).tolist()} "
                                "in world; the planar model needs joint axes along a world axis (x, y or z)")
        iu, iv = _PLANES[k]
        E = np.zeros((3, 2))
        E[iu, 0] = E[iv, 1] = 1.0
        normal = np.cross(E[:, 0], E[:, 1])
        signs = axes @ normal
        bad = np.flatnonzero(np.abs(np.abs(signs) - 1.0) > 1e-9)
        if bad.size:
            j = joints[bad[0]]
            raise QmtInputError(f"{source}: joint '{j.name()}' is not parallel to joint '{joints[0].name()}' "
                                f"(axes {np.round(axes[bad[0]], 6).tolist()} and {np.round(axes[0], 6).tolist()} in "
                                "world); the planar model needs parallel joint axes (a spatial arm needs the "
                                "spatial backend)")
        signs = np.sign(signs)
        affected = [set(int(b) for b in plant.GetBodiesKinematicallyAffectedBy([j.index()])) for j in joints]
        hand_body = int(hand_frame.body().index())
        next_pts = [origins[i + 1] for i in range(len(joints) - 1)]
        next_pts.append(hand_frame.CalcPoseInWorld(context).translation())
        masses, coms, izzs = [], [], []
        for i, j in enumerate(joints):
            own = affected[i] - (affected[i + 1] if i + 1 < len(joints) else set())
            if i + 1 < len(joints):
                if not affected[i + 1] <= affected[i] or int(joints[i + 1].parent_body().index()) not in own:
                    raise QmtInputError(f"{source}: joint '{joints[i + 1].name()}' does not sit on the link moved "
                                        f"by joint '{j.name()}'; the model needs one serial chain")
            elif hand_body not in own:
                raise QmtInputError(f"{source}: the hand frame is not on the link after the last joint "
                                    f"'{j.name()}'")
            M = plant.CalcSpatialInertia(context, world, [BodyIndex(b) for b in sorted(own)])
            m = M.get_mass()
            com = np.asarray(M.get_com()) if m > 0 else origins[i]
            I_cm = M.Shift(com).CalcRotationalInertia().CopyToFullMatrix3() if m > 0 else np.zeros((3, 3))
            masses.append(m)
            coms.append(E.T @ (com - origins[i]))
            izzs.append(float(normal @ I_cm @ normal))
        g = np.asarray(plant.gravity_field().gravity_vector(), float)
        X_WH0 = hand_frame.CalcPoseInWorld(context)
        return cls(plane_axes=E, joint_signs=signs, base_m=E.T @ origins[0],
                   next_joint_m=[E.T @ (next_pts[i] - origins[i]) for i in range(len(joints))],
                   com_m=coms, mass_kg=masses, izz_about_com_kgm2=izzs,
                   reflected_inertia_kgm2=reflected_inertia_kgm2, gravity_in_plane_m_s2=E.T @ g,
                   hand_normal_offset_m=float(normal @ X_WH0.translation()),
                   hand_rotation_at_zero=X_WH0.rotation().matrix())

    # ------------------------------------------------------------------ kinematics
    def absolute_angles(self, q) -> np.ndarray:
        """phi_i = s_1 q_1 + ... + s_i q_i, (..., n) rad."""
        return np.cumsum(np.asarray(q, float) * self.joint_signs, axis=-1)

    def tool_angle(self, q) -> np.ndarray:
        """Direction of the last link (joint n -> hand) in plane coordinates, rad (the thesis's
        theta_p = q1 + q2 + q3 for its arms)."""
        return self.absolute_angles(q)[..., -1] + self.link_angle_at_zero[-1]

    def tip_position(self, q) -> np.ndarray:
        """Hand origin in plane coordinates (..., 2) m."""
        return self.joint_positions(q)[..., -1, :]

    def joint_positions(self, q) -> np.ndarray:
        """Joints 1..n and the hand in plane coordinates, (..., n+1, 2) m (for stick figures)."""
        phi = self.absolute_angles(q)
        pts = [np.broadcast_to(self.base_m, phi.shape[:-1] + (2,))]
        for i, (du, dv) in enumerate(self._uv):
            c, s = np.cos(phi[..., i]), np.sin(phi[..., i])
            pts.append(pts[-1] + np.stack([c * du - s * dv, s * du + c * dv], axis=-1))
        return np.stack(pts, axis=-2)

    def tip_velocity(self, q, qd) -> np.ndarray:
        """(..., 2) m/s."""
        return np.einsum("...ij,...j->...i", self.jacobian(q), np.asarray(qd, float))

    def tip_acceleration(self, q, qd, qdd) -> np.ndarray:
        """In-plane hand-origin acceleration (..., 2) m/s^2 (kinematics only, no gravity). Works on
        float arrays and on Drake AutoDiffXd object arrays (trajectory optimisation gradients)."""
        return np.stack(np.broadcast_arrays(*self._forward(q, qd, qdd, gravity=False)[1]), axis=-1)

    def jacobian(self, q) -> np.ndarray:
        """d(tip u, tip v)/dq, (..., 2, n)."""
        return self.tip_position_and_jacobian(q)[1]

    def tip_position_and_jacobian(self, q) -> tuple[np.ndarray, np.ndarray]:
        """(hand origin (..., 2) m, d(tip u, tip v)/dq (..., 2, n)) from one pass over the joints."""
        q = np.asarray(q, float)
        pts = self.joint_positions(q)
        r = pts[..., -1:, :] - pts[..., :-1, :]  # joint i -> hand, (..., n, 2)
        J = np.empty(q.shape[:-1] + (2, self.n_dof))
        J[..., 0, :] = -r[..., 1] * self.joint_signs
        J[..., 1, :] = r[..., 0] * self.joint_signs
        return pts[..., -1, :], J

    # ------------------------------------------------------------------ dynamics (hot path)
    def _forward(self, q, qd, qdd, gravity: bool = True):
        """Forward pass of the recursion: per link (cos, sin of its absolute angle, COM
        acceleration, angular acceleration) and the hand's acceleration (u, v). With gravity the
        base accelerates at -g (gravity enters as an inertial force) and g is added back to the
        hand's acceleration. q, qd, qdd are float arrays, Drake AutoDiffXd object arrays or
        `Tangent`s (exact derivatives, `torque_and_derivatives`)."""
        if not isinstance(q, Tangent):
            q, qd, qdd = np.asarray(q), np.asarray(qd), np.asarray(qdd)
        sg = self.joint_signs
        gx, gy = (float(v) for v in self.gravity_in_plane_m_s2) if gravity else (0.0, 0.0)
        ax, ay = -gx, -gy  # acceleration of joint i
        phi = w = al = 0.0
        links = []
        for i in range(self.n_dof):
            if sg[i] > 0:  # the usual +n axis: no sign multiplications on the hot path
                phi, w, al = phi + q[..., i], w + qd[..., i], al + qdd[..., i]
            else:
                phi, w, al = phi - q[..., i], w - qd[..., i], al - qdd[..., i]
            c, s = phi.cos_sin() if isinstance(phi, Tangent) else (np.cos(phi), np.sin(phi))
            w2 = w * w
            # Relative acceleration per metre of a point along the link's unit vector u = (c, s);
            # a point r = a u + b n (n = u turned +90 deg) accelerates by a (ex, ey) + b (-ey, ex).
            ex = -(al * s) - w2 * c
            ey = al * c - w2 * s
            acx, acy = _point(ax, ay, ex, ey, *self._cuv[i])
            links.append((c, s, acx, acy, al))
            ax, ay = _point(ax, ay, ex, ey, *self._uv[i])
        if gx or gy:
            ax, ay = ax + gx, ay + gy
        return links, (ax, ay)

    def _backward(self, links) -> list:
        """Backward pass: joint torques (without rotor inertia), one entry per joint, from the
        forces and moments each link passes to the one before it."""
        taus = [None] * self.n_dof
        fx = fy = nz = 0.0  # force and moment link i+1 takes from link i (at the next joint)
        for i in range(self.n_dof - 1, -1, -1):
            c, s, acx, acy, ali = links[i]
            m = float(self.mass_kg[i])
            mx, my = m * acx, m * acy
            (cu, cv), (du, dv) = self._cuv[i], self._uv[i]
            # Moments about joint i of m a_c at r_c and of f at r_d: r x F = a (u x F) - b (u . F)
            # for r = a u + b n, summed before the products with c and s.
            gx, gy = cu * mx + du * fx, cu * my + du * fy
            nz = float(self.izz_about_com_kgm2[i]) * ali + (c * gy - s * gx) + nz
            if cv or dv:
                hx, hy = cv * mx + dv * fx, cv * my + dv * fy
                nz = nz - (c * hx + s * hy)
            fx, fy = mx + fx, my + fy
            taus[i] = nz if self.joint_signs[i] > 0 else -nz
        return taus

    def acceleration_and_torque(self, q, qd, qdd):
        """(in-plane hand acceleration (..., 2) m/s^2, joint torque (..., n) N*m) in one pass:
        the forward pass, then forces and moments backward from the hand."""
        links, a_hand = self._forward(q, qd, qdd)
        qdd = np.asarray(qdd, float)
        tau = np.empty(np.broadcast_shapes(np.shape(q), np.shape(qd), qdd.shape))
        for i, t in enumerate(self._backward(links)):
            tau[..., i] = t
        return np.stack(np.broadcast_arrays(*a_hand), axis=-1), tau + self.reflected_inertia_kgm2 * qdd

    def torque_and_derivatives(self, q, qd, qdd):
        """Joint torque with gravity and its exact partial derivatives, batched: the same
        recursion as `acceleration_and_torque`, carried out on `Tangent`s with one tangent
        direction per entry of (q, qd, qdd).

        q, qd, qdd (S, n). Returns (tau (S, n), dtau/dq, dtau/dqd, dtau/dqdd), each Jacobian
        (S, n, n) with entry [s, i, j] = d tau_i / d x_j at sample s."""
        q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
        S, n = np.broadcast_shapes(q.shape, qd.shape, qdd.shape)
        q, qd, qdd = (np.broadcast_to(x, (S, n)) for x in (q, qd, qdd))
        seeds = np.eye(3 * n).reshape(3, n, 3 * n)  # tangent of x_j = unit vector j
        args = [Tangent(x, np.broadcast_to(seeds[k], (S, n, 3 * n))) for k, x in enumerate((q, qd, qdd))]
        taus = self._backward(self._forward(*args)[0])
        tau = np.stack([t.v for t in taus], axis=1) + self.reflected_inertia_kgm2 * qdd
        J = np.stack([t.d for t in taus], axis=1)  # (S, n, 3n)
        J[:, :, 2 * n:] += np.diag(self.reflected_inertia_kgm2)
        return tau, J[:, :, :n], J[:, :, n:2 * n], J[:, :, 2 * n:]

    def with_gravity(self, gravity_in_plane_m_s2) -> PlanarChain:
        """A copy of this chain under another in-plane gravity vector (m/s^2)."""
        other = copy.copy(self)
        other.gravity_in_plane_m_s2 = np.asarray(gravity_in_plane_m_s2, float)
        return other

    # ------------------------------------------------------------------ 3-D hand state
    def _rotation_about_normal(self, angle) -> np.ndarray:
        n = self.normal
        K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
        a = np.asarray(angle, float)[..., None, None]
        return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * (K @ K)

    def hand_pose(self, q):
        """(position (S, 3) m, rotation R_WH (S, 3, 3)) in world."""
        p2 = self.tip_position(q)
        p = p2 @ self.plane_axes.T + self.hand_normal_offset_m * self.normal
        R = self._rotation_about_normal(self.absolute_angles(q)[..., -1]) @ self.hand_rotation_at_zero
        return p, R

    def hand_velocity(self, q, qd):
        v = self.tip_velocity(q, qd) @ self.plane_axes.T
        w = np.sum(np.asarray(qd, float) * self.joint_signs, axis=-1)[..., None] * self.normal
        return v, w

    def dynamics(self, q, qd, qdd) -> dict:
        """HandState's inverse-dynamics pass: in-plane hand acceleration and joint torques."""
        a2, tau = self.acceleration_and_torque(q, qd, qdd)
        return {"planar_acceleration_m_s2": a2, "joint_torque_Nm": tau}

    def world_accelerations(self, qdd, dyn: dict) -> dict:
        """World-frame linear and angular hand accelerations from the in-plane ones."""
        alpha = np.sum(np.asarray(qdd, float) * self.joint_signs, axis=-1)[..., None] * self.normal
        return {"linear_acceleration_m_s2": dyn["planar_acceleration_m_s2"] @ self.plane_axes.T,
                "angular_acceleration_rad_s2": alpha}

    def hand_acceleration_and_joint_torque(self, q, qd, qdd):
        """(linear, angular hand acceleration in world (S, 3), joint torque (S, n), extras)."""
        d = self.dynamics(q, qd, qdd)
        d.update(self.world_accelerations(qdd, d))
        return d["linear_acceleration_m_s2"], d["angular_acceleration_rad_s2"], d["joint_torque_Nm"], d

    # ------------------------------------------------------------------ inverse kinematics
    def inverse_kinematics(self, uv, tool_angle_rad: float | None = None,
                           branch: str = "elbow_positive", what: str = "point") -> np.ndarray:
        """Analytic IK for the hand origin at `uv` (..., 2) in plane coordinates (no range check).

        2 joints: position only. 3 joints: `tool_angle_rad` (the last link's direction,
        `tool_angle`) is required. `branch`: 'elbow_positive' turns link 2 counterclockwise about
        the plane normal from link 1 (q2 > 0 on the thesis's arms), 'elbow_negative' the other way.
        Raises QmtInputError naming the point and the reach when it cannot be reached."""
        if branch not in IK_BRANCHES:
            raise QmtInputError(f"unknown IK branch '{branch}'; use one of {IK_BRANCHES}")
        uv = np.asarray(uv, dtype=float)
        L = self.link_lengths_m
        beta = self.link_angle_at_zero
        rel = uv - self.base_m
        if self.n_dof == 2:
            wrist = rel
        elif self.n_dof == 3:
            if tool_angle_rad is None:
                raise QmtInputError("a 3-joint arm needs task.tool_angle_rad (direction of the last link)")
            wrist = rel - L[2] * np.stack(np.broadcast_arrays(np.cos(tool_angle_rad) + 0 * rel[..., 0],
                                                              np.sin(tool_angle_rad) + 0 * rel[..., 0]), -1)
        else:
            raise QmtInputError(f"analytic IK supports 2 or 3 joints, not {self.n_dof}")
        r = np.hypot(wrist[..., 0], wrist[..., 1])
        r_min, r_max = abs(L[0] - L[1]), L[0] + L[1]
        bad = (r > r_max * (1 + 1e-12)) | (r < r_min * (1 - 1e-12))
        if np.any(bad):
            k = np.flatnonzero(np.atleast_1d(bad))[0]
            p = np.atleast_2d(uv)[k]
            raise QmtInputError(
                f"{what} ({p[0]:.4f}, {p[1]:.4f}) m is unreachable: its wrist lies "
                f"{np.atleast_1d(r)[k]:.4f} m from the base, the reach is "
                f"[{r_min:.4f}, {r_max:.4f}] m (links {', '.join(f'{v:.3f}' for v in L)} m)")
        c2 = np.clip((r**2 - L[0] ** 2 - L[1] ** 2) / (2 * L[0] * L[1]), -1.0, 1.0)
        elbow = np.arccos(c2) * (1.0 if branch == "elbow_positive" else -1.0)
        psi1 = np.arctan2(wrist[..., 1], wrist[..., 0]) - np.arctan2(L[1] * np.sin(elbow),
                                                                      L[0] + L[1] * np.cos(elbow))
        phis = [psi1 - beta[0], psi1 + elbow - beta[1]]
        if self.n_dof == 3:
            phis.append(tool_angle_rad - beta[2] + 0 * psi1)
        phi = np.stack(phis, axis=-1)
        q = np.diff(phi, axis=-1, prepend=0.0) * self.joint_signs
        # Wrap to (-pi, pi] so a range check sees the same angle as the thesis's figures.
        return (q + np.pi) % (2 * np.pi) - np.pi

    def joint_motion_on_tip_path(self, p, v, a, tool_angle_rad=None, branch="elbow_positive"):
        """q, qd, qdd (S, n) that move the hand origin with position p, velocity v and acceleration
        a (S, 2) (plane coordinates) and hold the tool angle constant (3 joints): IK for q, then
        J_aug qd = [v, 0] and J_aug qdd = [a - Jdot qd, 0], J_aug = tip Jacobian plus, for 3
        joints, the row d(tool angle)/dq = joint signs."""
        q = self.inverse_kinematics(p, tool_angle_rad, branch)
        J = self.jacobian(q)
        rhs_v, rhs_a = np.asarray(v, float), None
        if self.n_dof == 3:
            J = np.concatenate([J, np.broadcast_to(self.joint_signs, q.shape)[..., None, :]], axis=-2)
            rhs_v = np.concatenate([rhs_v, np.zeros(rhs_v.shape[:-1] + (1,))], axis=-1)
        qd = solve_small(J, rhs_v)
        bias = self.tip_acceleration(q, qd, np.zeros_like(qd))
        rhs_a = np.asarray(a, float) - bias
        if self.n_dof == 3:
            rhs_a = np.concatenate([rhs_a, np.zeros(rhs_a.shape[:-1] + (1,))], axis=-1)
        return q, qd, solve_small(J, rhs_a)


def _point(ax, ay, ex, ey, a: float, b: float):
    """Acceleration of the point a u + b n of a link whose joint accelerates at (ax, ay)."""
    if b == 0.0:
        return ax + a * ex, ay + a * ey
    return ax + a * ex - b * ey, ay + a * ey + b * ex


def solve_small(A, b) -> np.ndarray:
    """Batched solve of 2x2 or 3x3 systems A x = b by Cramer's rule (closed form, no LAPACK call
    per system); A (..., k, k), b (..., k)."""
    k = A.shape[-1]
    if k == 2:
        det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
        x0 = (A[..., 1, 1] * b[..., 0] - A[..., 0, 1] * b[..., 1]) / det
        x1 = (-A[..., 1, 0] * b[..., 0] + A[..., 0, 0] * b[..., 1]) / det
        return np.stack([x0, x1], axis=-1)
    if k == 3:
        c0, c1, c2 = A[..., :, 0], A[..., :, 1], A[..., :, 2]
        det = np.einsum("...i,...i->...", c0, np.cross(c1, c2))
        return np.stack([np.einsum("...i,...i->...", b, np.cross(c1, c2)),
                         np.einsum("...i,...i->...", c0, np.cross(b, c2)),
                         np.einsum("...i,...i->...", c0, np.cross(c1, b))], axis=-1) / det[..., None]
    return np.linalg.solve(A, b[..., None])[..., 0]
