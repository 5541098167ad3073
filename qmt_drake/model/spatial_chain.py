"""SpatialChain: the batched hand state of a serial revolute arm, in one numpy pass over samples.

Read once from a finalized Drake MultibodyPlant (see model/urdf_check.py `load_arm_plant`): for each
movable joint, base first, the constant transform from the previous moving frame to the joint's
frame, and the composite inertia of every body welded to its child link. Each joint frame is turned
so the joint axis is its z axis (frame K_i = the joint's child frame times a constant rotation E_i
with E_i e_z = axis), so every joint rotation is about z.

Then for S samples of (q, qd, qdd), shape (S, n), one pass loops over the n joints only (each step
vectorised over samples, arrays laid out (3, S)):

- forward: world pose of K_i, angular velocity/acceleration, velocity and classical acceleration of
  its origin; the hand frame H (welded to the last link) from them;
- backward (Newton-Euler, world frame): joint torques with gravity from a vector `gravity_m_s2`,
  the reflected rotor inertia N^2 J_r qdd (per joint, joint side) and the carried body (mass,
  centre of mass and central inertia in the hand frame, added to the last link's composite).

Joint damping, friction and limits are not forces here (as in `CalcInverseDynamics` with only
gravity applied). Units SI: m, rad, s, kg, N m. Checked against Drake (inverse dynamics, frame
poses, body spatial accelerations) and Pinocchio's RNEA in tests/test_spatial_chain.py.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.tree import JointIndex

from qmt_drake.errors import QmtInputError


def _cross(a, b):
    """Row-wise cross product of (3, S) arrays."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _rot_vec(R, v):
    """(3, 3, S) times (3, S) -> (3, S)."""
    return np.einsum("ijs,js->is", R, v)


def _rot_t_vec(R, v):
    """R^T v for (3, 3, S), (3, S) -> (3, S)."""
    return np.einsum("jis,js->is", R, v)


class SpatialChain:
    """Attributes: n_dof, joint_names, velocity_index (the plant's velocity index of each chain
    joint), reflected_inertia_kgm2 (n,), gravity_m_s2 (3,), and per joint the constants read from
    the plant (R_prev_J, p_prev_J, mass_kg, com_m, inertia_com_kgm2 in frame K_i)."""

    def __init__(self, plant, hand_frame, *, reflected_inertia_kgm2=None, gravity_m_s2=None,
                 carried=None) -> None:
        if isinstance(hand_frame, str):
            hand_frame = plant.GetFrameByName(hand_frame)
        self.hand_frame = hand_frame
        ctx = plant.CreateDefaultContext()
        plant.SetPositions(ctx, np.zeros(plant.num_positions()))
        joints = self._chain(plant, hand_frame.body())
        self.n_dof = len(joints)
        self.joint_names = [j.name() for j in joints]
        self.velocity_index = np.array([j.velocity_start() for j in joints])
        self._permute = not np.array_equal(self.velocity_index, np.arange(self.n_dof))
        world = plant.world_frame()
        self.R_prev_J, self.p_prev_J = [], []
        self.mass_kg, self.com_m, self.inertia_com_kgm2 = [], [], []
        X_W_Kprev = None  # pose of the previous moving frame at q = 0
        for j in joints:
            E = RotationMatrix.MakeFromOneVector(np.asarray(j.revolute_axis(), float), 2)
            X_W_J = plant.CalcRelativeTransform(ctx, world, j.frame_on_parent()).multiply(_pose(E))
            X = X_W_J if X_W_Kprev is None else X_W_Kprev.InvertAndCompose(X_W_J)
            self.R_prev_J.append(X.rotation().matrix())
            self.p_prev_J.append(X.translation())
            X_W_K = plant.CalcRelativeTransform(ctx, world, j.frame_on_child()).multiply(_pose(E))
            m, h, I_o = 0.0, np.zeros(3), np.zeros((3, 3))
            for b in plant.GetBodiesWeldedTo(j.child_body()):
                X_KB = X_W_K.InvertAndCompose(b.body_frame().CalcPoseInWorld(ctx))
                M = b.default_spatial_inertia().ReExpress(X_KB.rotation()).Shift(-X_KB.translation())
                m += M.get_mass()
                h += M.get_mass() * M.get_com()
                I_o += M.CalcRotationalInertia().CopyToFullMatrix3()
            self._add_composite(m, h, I_o)
            X_W_Kprev = X_W_K
        X_KH = X_W_Kprev.InvertAndCompose(hand_frame.CalcPoseInWorld(ctx))
        self.R_K_H, self.p_K_H = X_KH.rotation().matrix(), X_KH.translation()
        if carried is not None:
            self._add_carried(carried)
        if reflected_inertia_kgm2 is None:
            by_joint = {plant.get_joint_actuator(a).joint().index(): plant.get_joint_actuator(a)
                        for a in plant.GetJointActuatorIndices()}
            reflected_inertia_kgm2 = [by_joint[j.index()].default_gear_ratio() ** 2
                                      * by_joint[j.index()].default_rotor_inertia()
                                      if j.index() in by_joint else 0.0 for j in joints]
        self.reflected_inertia_kgm2 = np.asarray(reflected_inertia_kgm2, float).reshape(self.n_dof)
        g = plant.gravity_field().gravity_vector() if gravity_m_s2 is None else gravity_m_s2
        self.gravity_m_s2 = np.asarray(g, float).reshape(3)

    @staticmethod
    def _chain(plant, hand_body):
        movable = [plant.get_joint(JointIndex(i)) for i in range(plant.num_joints())]
        movable = [j for j in movable if j.num_velocities() > 0]
        for j in movable:
            if j.type_name() != "revolute":
                raise QmtInputError(f"joint {j.name()!r} is {j.type_name()}; SpatialChain takes revolute "
                                    "joints from a fixed base only (weld the base, lock other joints)")
        welded = {b.index(): {w.index() for w in plant.GetBodiesWeldedTo(b)} for b in
                  (plant.get_body(j.child_body().index()) for j in movable)}
        chain, body = [], hand_body
        world_set = {w.index() for w in plant.GetBodiesWeldedTo(plant.world_body())}
        while body.index() not in world_set:
            inboard = [j for j in movable if body.index() in welded[j.child_body().index()]]
            if len(inboard) != 1:
                raise QmtInputError(f"body {body.name()!r} is not moved by exactly one joint; the arm must be a "
                                    "serial chain from a fixed base")
            chain.append(inboard[0])
            body = inboard[0].parent_body()
        if len(chain) != len(movable) or plant.num_positions() != len(chain):
            raise QmtInputError(f"the plant has {len(movable)} movable joints but {len(chain)} lie on the chain "
                                "to the hand; lock the others")
        return chain[::-1]

    def _add_composite(self, m, h, I_o):
        c = h / m if m > 0 else np.zeros(3)
        self.mass_kg.append(m)
        self.com_m.append(c)
        self.inertia_com_kgm2.append(I_o - m * (c @ c * np.eye(3) - np.outer(c, c)))

    def _add_carried(self, carried):
        """Merge the carried body (mass_kg, com_m and inertia_kgm2 about its centre, hand frame)
        into the last link's composite."""
        m2 = float(carried["mass_kg"])
        c2 = self.p_K_H + self.R_K_H @ np.asarray(carried["com_m"], float)
        I2 = self.R_K_H @ np.asarray(carried["inertia_kgm2"], float) @ self.R_K_H.T
        m1, c1, I1 = self.mass_kg.pop(), self.com_m.pop(), self.inertia_com_kgm2.pop()

        def about_origin(m, c, inertia):
            return inertia + m * (c @ c * np.eye(3) - np.outer(c, c))

        self._add_composite(m1 + m2, m1 * c1 + m2 * c2, about_origin(m1, c1, I1) + about_origin(m2, c2, I2))

    # ------------------------------------------------------------------ passes
    def _columns(self, a):
        a = np.atleast_2d(np.asarray(a, float))
        if a.shape[1] != self.n_dof:
            raise ValueError(f"expected (S, {self.n_dof}) joint arrays, got {a.shape}")
        return (a[:, self.velocity_index] if self._permute else a).T

    def _forward(self, q, qd=None, qdd=None):
        """Lists over joints of R_WK (3, 3, S), p (3, S), z (3, S), w, alpha, v, a (3, S) or None."""
        S = q.shape[1]
        R = np.broadcast_to(np.eye(3)[:, :, None], (3, 3, S))
        p = np.zeros((3, S))
        zero = np.zeros((3, S))
        w = al = v = a = zero
        c, s = np.cos(q), np.sin(q)
        out = {"R": [], "p": [], "z": [], "w": [], "al": [], "v": [], "a": []}
        for i in range(self.n_dof):
            r = _rot_vec(R, np.broadcast_to(self.p_prev_J[i][:, None], (3, S)))
            RJ = np.matmul(R.transpose(0, 2, 1), self.R_prev_J[i]).transpose(0, 2, 1)  # (3, 3, S)
            z = RJ[:, 2]
            RK = np.empty_like(RJ)
            RK[:, 0] = c[i] * RJ[:, 0] + s[i] * RJ[:, 1]
            RK[:, 1] = c[i] * RJ[:, 1] - s[i] * RJ[:, 0]
            RK[:, 2] = z
            if qd is not None:
                wr = _cross(w, r)
                v_new = v + wr
                w_new = w + z * qd[i]
                if qdd is not None:
                    a = a + _cross(al, r) + _cross(w, wr)
                    al = al + z * qdd[i] + _cross(w, z) * qd[i]
                    out["al"].append(al)
                    out["a"].append(a)
                v, w = v_new, w_new
                out["w"].append(w)
                out["v"].append(v)
            R, p = RK, p + r
            out["R"].append(R)
            out["p"].append(p)
            out["z"].append(z)
        return out

    def _hand(self, fw, S):
        R, p = fw["R"][-1], fw["p"][-1]
        r = _rot_vec(R, np.broadcast_to(self.p_K_H[:, None], (3, S)))
        RH = np.matmul(R.transpose(0, 2, 1), self.R_K_H).transpose(0, 2, 1)
        res = {"position_m": (p + r).T, "rotation": RH.transpose(2, 0, 1), "r": r}
        if fw["w"]:
            w, v = fw["w"][-1], fw["v"][-1]
            wr = _cross(w, r)
            res["angular_velocity_rad_s"], res["linear_velocity_m_s"] = w.T, (v + wr).T
            if fw["al"]:
                al, a = fw["al"][-1], fw["a"][-1]
                res["angular_acceleration_rad_s2"] = al.T
                res["linear_acceleration_m_s2"] = (a + _cross(al, r) + _cross(w, wr)).T
        return res

    def evaluate(self, q, qd, qdd, gravity_m_s2=None) -> dict:
        """Everything in one pass: position_m (S, 3), rotation (S, 3, 3) = R_WH,
        angular_velocity_rad_s, linear_velocity_m_s (of H's origin), angular_acceleration_rad_s2,
        linear_acceleration_m_s2 (classical, of H's origin), all in world, and joint_torque_Nm (S, n)."""
        q, qd, qdd = self._columns(q), self._columns(qd), self._columns(qdd)
        g = self.gravity_m_s2 if gravity_m_s2 is None else np.asarray(gravity_m_s2, float).reshape(3)
        S = q.shape[1]
        fw = self._forward(q, qd, qdd)
        res = self._hand(fw, S)
        n = self.n_dof
        tau = np.empty((n, S))
        F = N = None  # force and moment (about K_i's origin) from link i+1 onwards
        for i in range(n - 1, -1, -1):
            R, w, al, a = fw["R"][i], fw["w"][i], fw["al"][i], fw["a"][i]
            m = self.mass_kg[i]
            c = _rot_vec(R, np.broadcast_to(self.com_m[i][:, None], (3, S)))
            wl = _rot_t_vec(R, w)
            Iw = self.inertia_com_kgm2[i] @ wl
            n_loc = self.inertia_com_kgm2[i] @ _rot_t_vec(R, al) + _cross(wl, Iw)
            f = m * (a + _cross(al, c) + _cross(w, _cross(w, c)) - g[:, None])
            Ni = _rot_vec(R, n_loc) + _cross(c, f)
            if F is not None:
                Ni = Ni + N + _cross(fw["p"][i + 1] - fw["p"][i], F)
                f = f + F
            F, N = f, Ni
            tau[i] = np.einsum("is,is->s", fw["z"][i], N)
        tau += self.reflected_inertia_kgm2[:, None] * qdd
        tau = tau.T
        if self._permute:
            out = np.empty_like(tau)
            out[:, self.velocity_index] = tau
            tau = out
        res["joint_torque_Nm"] = tau
        del res["r"]
        return res

    # ------------------------------------------------ the HandState backend interface
    def hand_pose(self, q):
        qc = self._columns(q)
        h = self._hand(self._forward(qc), qc.shape[1])
        return h["position_m"], h["rotation"]

    def hand_velocity(self, q, qd):
        qc = self._columns(q)
        h = self._hand(self._forward(qc, self._columns(qd)), qc.shape[1])
        return h["linear_velocity_m_s"], h["angular_velocity_rad_s"]

    def dynamics(self, q, qd, qdd) -> dict:
        r = self.evaluate(q, qd, qdd)
        return {k: r[k] for k in ("linear_acceleration_m_s2", "angular_acceleration_rad_s2", "joint_torque_Nm")}

    def spatial_jacobian(self, q) -> np.ndarray:
        """(S, 6, n): rows (angular; translational) of the hand's spatial velocity in world, columns
        in the plant's velocity order."""
        qc = self._columns(q)
        fw = self._forward(qc)
        pH = self._hand(fw, qc.shape[1])["position_m"].T
        J = np.empty((qc.shape[1], 6, self.n_dof))
        for i in range(self.n_dof):
            col = self.velocity_index[i]
            J[:, :3, col] = fw["z"][i].T
            J[:, 3:, col] = _cross(fw["z"][i], pH - fw["p"][i]).T
        return J


def _pose(R: RotationMatrix) -> RigidTransform:
    return RigidTransform(R, np.zeros(3))
