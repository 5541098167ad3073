"""SpatialIK: joint positions for hand poses of a spatial arm, checked by forward kinematics.

A target is a hand position (m, world) and either the hand's face normal (the unit vector the hand
frame's `face_axis` must point along, default its z axis) or a full rotation R_WH. Each target is
solved by Drake's `InverseKinematics` (SNOPT or IPOPT, joint limits imposed) from a seed, with a
quadratic cost on the distance to the seed so the solver stays on the seed's branch (elbow up or
down, wrist flip; for a redundant arm, the nearest posture); a path is solved point by point, each
seeded from the previous solution. The solution is then polished on the SpatialChain Jacobian (the
solver stops at its feasibility tolerance, about 1e-6): a Gauss-Newton step where it lowers the pose
error, else Levenberg-Marquardt (damped least-squares) steps with the damping raised until one does;
every step is projected onto the joint limits and a step that makes the pose worse is never taken, so
the polish never leaves the limits and never returns a pose worse than the solver's (near a singular
orientation, e.g. a 5-joint arm's roll axis along its pan axis with the cup facing down, plain
Gauss-Newton steps through the tiny singular values diverged to a joint at -194 rad). The result is
checked by Drake's forward kinematics (`Frame.CalcPoseInWorld`): position within 1e-6 m and
orientation (normal or rotation) within 1e-6 rad, joint limits held. A target that fails is refused
with one line naming it, the residual and the reason (too few joints for the constraint, a joint at
its limit, a singular orientation, or out of reach) (QmtInputError). A face normal leaves the spin
about it free (what a suction cup or a magnet needs); a rotation fixes it. `max_joint_step_rad` on a
path refuses a jump between neighbouring points (a branch change) instead of returning a
discontinuous joint path. Without a seed (`seed=None`), a path is tried from several starts
(`starts`: the middle of the joint ranges, then deterministic draws inside them) and the solution with
the least joint motion along the path is kept, so a user need not know the arm's IK branches.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve
from scipy.spatial.transform import Rotation, Slerp

from qmt_drake.errors import QmtInputError
from qmt_drake.model.spatial_chain import SpatialChain

POSITION_TOL_M = 1e-6
ANGLE_TOL_RAD = 1e-6
LM_DAMPING0 = 1e-9  # first damping (m^2 / rad^2 scale of J J^T) after a rejected Gauss-Newton step
LM_DAMPING_MAX = 1e3  # beyond this the step is ~ J^T e / lambda, too small to matter: stop
LM_MAX_REJECTED = 40
N_STARTS = 12  # seedless path: starts tried (the ranges' middle + draws); the first 3 that succeed are compared
N_SUCCESSES = 3
UNBOUNDED_HALF_RANGE_RAD = np.pi  # a start for a joint without a finite range is drawn in [-pi, pi]
SINGULAR_REL = 1e-6  # a singular value below this x the largest: the constraint's Jacobian loses rank


class SpatialIK:
    def __init__(self, plant, hand_frame, *, face_axis=(0.0, 0.0, 1.0), name: str = "arm") -> None:
        self.plant = plant
        self.hand = plant.GetFrameByName(hand_frame) if isinstance(hand_frame, str) else hand_frame
        self.chain = SpatialChain(plant, self.hand)
        self.face_axis = np.asarray(face_axis, float) / np.linalg.norm(face_axis)
        self.name = name
        self.lower = plant.GetPositionLowerLimits()
        self.upper = plant.GetPositionUpperLimits()
        self._ctx = plant.CreateDefaultContext()

    # ------------------------------------------------------------------ checks
    def pose(self, q):
        """Drake's forward kinematics: (p_WH (3,), R_WH (3, 3))."""
        self.plant.SetPositions(self._ctx, q)
        X = self.hand.CalcPoseInWorld(self._ctx)
        return X.translation(), X.rotation().matrix()

    def errors(self, q, position_m, normal=None, rotation=None):
        """(position error m, orientation error rad) of q for a target, by Drake's kinematics."""
        p, R = self.pose(q)
        ep = float(np.linalg.norm(p - position_m))
        if rotation is not None:
            ea = float(RotationMatrix(rotation.T @ R).ToAngleAxis().angle())
        elif normal is not None:
            n = R @ self.face_axis
            ea = float(np.arctan2(np.linalg.norm(np.cross(n, normal)), n @ normal))
        else:
            ea = 0.0
        return ep, ea

    # ------------------------------------------------------------------ solving
    def solve(self, position_m, *, normal=None, rotation=None, seed, what: str = "task point") -> np.ndarray:
        """q (n,) reaching the target, on the seed's branch; QmtInputError naming `what` if none."""
        p = np.asarray(position_m, float).reshape(3)
        n_t, R_t = _target_orientation(normal, rotation, what)
        seed = np.asarray(seed, float).reshape(self.chain.n_dof)
        q_solver = self._drake_ik(p, n_t, R_t, seed)
        q = self._polish(q_solver, p, n_t, R_t)
        ep, ea = self.errors(q, p, n_t, R_t)
        if ep > POSITION_TOL_M or ea > ANGLE_TOL_RAD or not self._inside(q):
            self._refuse(q, p, n_t, R_t, what)
        return q

    def _inside(self, q) -> bool:
        return bool(np.all(q >= self.lower - 1e-9) and np.all(q <= self.upper + 1e-9))

    def _refuse(self, q, p, n_t, R_t, what: str) -> None:
        """One line: the target, the residual of the best pose found and why it is not reached."""
        ep, ea = self.errors(q, p, n_t, R_t)
        orient = ("" if n_t is None and R_t is None else
                  f" with normal {np.round(n_t, 4).tolist()}" if n_t is not None else " with the given rotation")
        need = 6 if R_t is not None else 5 if n_t is not None else 3
        n = self.chain.n_dof
        names = self.chain.joint_names
        at_limit = [names[j] for j in range(n) if q[j] <= self.lower[j] + 1e-7 or q[j] >= self.upper[j] - 1e-7]
        rows, _ = self._linearised(q, p, n_t, R_t)
        sv = np.linalg.svd(rows, compute_uv=False)
        rank = int(np.sum(sv > SINGULAR_REL * sv[0])) if sv.size and sv[0] > 0 else 0
        if n < need:
            reason = (f"too few joints: {n} joints for a {need}-DOF target"
                      + ("; let the spin about the face normal free (task.free_spin_about_normal: true)"
                         if R_t is not None else ""))
        elif not self._inside(q):
            reason = "the best pose found is outside the joint limits"
        elif at_limit:
            reason = (f"outside the joint limits: the best pose has {', '.join(at_limit)} at its limit (from this "
                      "seed the target needs it beyond; another seed_rad may reach it)")
        elif rank < min(need, n):
            reason = (f"singular orientation: the constraint's Jacobian has rank {rank} < {min(need, n)} there "
                      "(e.g. the roll axis along the pan axis)")
        else:
            reason = "out of reach"
        raise QmtInputError(f"{what} at {np.round(p, 4).tolist()} m{orient} is not reached by {self.name}: "
                            f"residual {ep:.3g} m, {ea:.3g} rad; {reason}; move the point or change its "
                            "orientation")

    def starts(self, count: int = N_STARTS) -> np.ndarray:
        """(count, n) IK starts for a seedless path: the middle of each joint's range (0 for a joint
        without a finite range), then uniform draws inside the ranges from a fixed generator (the same
        starts every run, so a scenario's joint path and plan identity are reproducible)."""
        lo = np.where(np.isfinite(self.lower), self.lower, -UNBOUNDED_HALF_RANGE_RAD)
        hi = np.where(np.isfinite(self.upper), self.upper, UNBOUNDED_HALF_RANGE_RAD)
        mid = np.where(np.isfinite(self.lower) & np.isfinite(self.upper), 0.5 * (lo + hi), 0.0)
        draws = np.random.default_rng(0).uniform(lo, hi, size=(count - 1, len(lo)))
        return np.vstack([mid, draws])

    def solve_path(self, positions_m, *, normals=None, rotations=None, seed, max_joint_step_rad=None,
                   what: str = "path point") -> np.ndarray:
        """(K, n) joint positions along K targets, point k seeded from point k-1 (the first from
        `seed`); a joint step above max_joint_step_rad between neighbours is refused. seed=None tries
        the paths from `starts()` and keeps the one with the least joint motion (sum of |dq| over the
        path's steps); if none succeeds, the refusal is the middle start's, saying no start reached it."""
        if seed is None:
            found, first_error = [], None
            for start in self.starts():
                try:
                    found.append(self.solve_path(positions_m, normals=normals, rotations=rotations, seed=start,
                                                 max_joint_step_rad=max_joint_step_rad, what=what))
                except QmtInputError as e:
                    first_error = first_error or e
                if len(found) == N_SUCCESSES:
                    break
            if not found:
                raise QmtInputError(str(first_error)
                                    .replace("another seed_rad may reach it", f"none of {N_STARTS} IK starts "
                                             "reached it; give task.seed_rad near a posture that does")
                                    .replace("or choose another seed", f"(from each of {N_STARTS} IK starts)"))
            return min(found, key=lambda q: (float(np.abs(np.diff(q, axis=0)).sum()), float(np.abs(q[0]).sum())))
        P = np.atleast_2d(np.asarray(positions_m, float))
        out = np.empty((len(P), self.chain.n_dof))
        prev = np.asarray(seed, float)
        for k, p in enumerate(P):
            q = self.solve(p, normal=None if normals is None else normals[k],
                           rotation=None if rotations is None else rotations[k], seed=prev, what=f"{what} {k}")
            if max_joint_step_rad is not None and k > 0:
                step = float(np.abs(q - prev).max())
                if step > max_joint_step_rad:
                    raise QmtInputError(f"{what} {k} at {np.round(p, 4).tolist()} m: the joints jump by {step:.3g} rad "
                                        f"from point {k - 1} (a branch change; max {max_joint_step_rad} rad); add "
                                        "points in between or choose another seed")
            out[k] = prev = q
        return out

    def follow(self, positions_m, normals, q_start, *, rotations=None, what: str = "path point") -> np.ndarray:
        """(K, n) joint positions along closely spaced targets (face normals, or full rotations when
        given) by continuation: q_start must reach target 0; each next target is reached by minimum-norm
        Gauss-Newton steps from the previous solution (the redundant joints move least), or by `solve`
        seeded there when that fails; every point is checked by Drake's forward kinematics and the
        joint limits like `solve`'s."""
        P = np.atleast_2d(np.asarray(positions_m, float))
        out = np.empty((len(P), self.chain.n_dof))
        out[0] = prev = np.asarray(q_start, float)
        for k in range(1, len(P)):
            n_k, R_k = (None, rotations[k]) if rotations is not None else (normals[k], None)
            q = self._polish(prev, P[k], n_k, R_k, iterations=20)
            ep, ea = self.errors(q, P[k], n_k, R_k)
            if ep > POSITION_TOL_M or ea > ANGLE_TOL_RAD or not self._inside(q):
                q = self.solve(P[k], normal=n_k, rotation=R_k, seed=prev, what=f"{what} {k}")
            out[k] = prev = q
        return out

    def _drake_ik(self, p, n_t, R_t, seed):
        ik = InverseKinematics(self.plant, with_joint_limits=True)
        W = self.plant.world_frame()
        ik.AddPositionConstraint(self.hand, np.zeros(3), W, p, p)
        if R_t is not None:
            ik.AddOrientationConstraint(W, RotationMatrix(R_t), self.hand, RotationMatrix(), 0.0)
        elif n_t is not None:
            ik.AddAngleBetweenVectorsConstraint(W, n_t, self.hand, self.face_axis, 0.0, 1e-9)
        prog = ik.get_mutable_prog()
        prog.AddQuadraticErrorCost(np.eye(len(seed)), seed, ik.q())
        prog.SetInitialGuess(ik.q(), np.clip(seed, self.lower, self.upper))
        result = Solve(prog)
        return result.GetSolution(ik.q())

    def _linearised(self, q, p, n_t, R_t):
        """(rows, err): the pose error's Jacobian rows and the error (rotation vector rad; position m)."""
        pos, R = self.chain.hand_pose(q[None])
        pos, R = pos[0], R[0]
        J = self.chain.spatial_jacobian(q[None])[0]
        e_p = p - pos
        if R_t is not None:
            aa = RotationMatrix(R_t @ R.T).ToAngleAxis()
            return J, np.concatenate([aa.axis() * aa.angle(), e_p])
        if n_t is not None:
            n = R @ self.face_axis
            e_w = np.cross(n, n_t)  # small rotation taking n to n_t
            P = np.eye(3) - np.outer(n, n)  # spin about n does not move the normal
            return np.vstack([P @ J[:3], J[3:]]), np.concatenate([P @ e_w, e_p])
        return J[3:], e_p

    def _polish(self, q, p, n_t, R_t, iterations: int = 8):
        """Pose-error polish inside the joint limits (module docstring): a Gauss-Newton step (minimum
        norm, so a redundant arm moves least) when it lowers |err|, else damped least-squares steps
        J^T (J J^T + lambda I)^-1 err with lambda raised tenfold until one does; each candidate is
        projected onto the limits; a step that does not lower |err| is never taken."""
        q = np.clip(np.array(q, float), self.lower, self.upper)
        rows, err = self._linearised(q, p, n_t, R_t)
        cost = float(err @ err)
        lam, rejected, taken = 0.0, 0, 0
        while taken < iterations and rejected < LM_MAX_REJECTED:
            if np.abs(err).max() < 1e-13:
                break
            if lam == 0.0:
                step = np.linalg.lstsq(rows, err, rcond=1e-10)[0]
            else:
                step = rows.T @ np.linalg.solve(rows @ rows.T + lam * np.eye(len(err)), err)
            q_new = np.clip(q + step, self.lower, self.upper)
            rows_new, err_new = self._linearised(q_new, p, n_t, R_t)
            cost_new = float(err_new @ err_new)
            if np.isfinite(cost_new) and cost_new < cost:
                q, rows, err, cost, taken = q_new, rows_new, err_new, cost_new, taken + 1
                lam = 0.0 if lam <= LM_DAMPING0 else lam / 10.0
            else:
                rejected += 1
                lam = LM_DAMPING0 if lam == 0.0 else lam * 10.0
                if lam > LM_DAMPING_MAX:
                    break
        return q


def _target_orientation(normal, rotation, what):
    if normal is not None and rotation is not None:
        raise QmtInputError(f"{what}: give either a face normal or a rotation, not both")
    if rotation is not None:
        R = np.asarray(rotation, float).reshape(3, 3)
        if np.abs(R @ R.T - np.eye(3)).max() > 1e-9 or np.linalg.det(R) < 0:
            raise QmtInputError(f"{what}: the rotation is not a proper rotation matrix (R R^T = I, det R = 1 "
                                "to 1e-9); give an orthonormal right-handed matrix")
        return None, R
    if normal is not None:
        n = np.asarray(normal, float).reshape(3)
        if not np.isfinite(n).all() or np.linalg.norm(n) < 1e-12:
            raise QmtInputError(f"{what}: the face normal {n.tolist()} has no direction; give a nonzero vector")
        return n / np.linalg.norm(n), None
    return None, None


def slerp_rotations(Ra, Rb, u) -> np.ndarray:
    """(len(u), 3, 3) rotations from Ra (u = 0) to Rb (u = 1) about one fixed axis at a constant rate
    (quaternion slerp, scipy's Slerp)."""
    u = np.atleast_1d(np.asarray(u, float))
    return Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([Ra, Rb])))(np.clip(u, 0.0, 1.0)).as_matrix()


def slerp_unit(a, b, u) -> np.ndarray:
    """(len(u), 3) unit vectors from a (u = 0) to b (u = 1) along the great circle at constant angular
    rate (slerp); a and b unit, not opposite."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    u = np.atleast_1d(np.asarray(u, float))[:, None]
    angle = float(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b))
    if angle < 1e-12:
        return np.repeat(a[None], len(u), axis=0)
    return (np.sin((1 - u) * angle) * a + np.sin(u * angle) * b) / np.sin(angle)
