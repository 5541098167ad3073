"""The link-length design problem of one arm type for one task (seed 003, sec. 3), on the project's
Problem protocol (INTERFACES.md): genes = the lengths L1, L2, L3, L4, L6 in m (L5 = 0: spherical
wrist), evaluate() batched over candidates -> cost = -E (eq. 8, 1/m), violation 0, fitness = E.

Per unit task every IK branch is computed (ik.solve) and labelled (ik.branch_label: the sign of the
positioning Jacobian's determinant and of d rho^2 / d q2, four labels, the wrist flip not labelled
because it changes neither operability nor collision); branches whose links touch the work or an
obstacle are dropped. Branch choice (`branch`):

- "task" (default, the seed's sec. 4.1: "every joint solution is evaluated and the joint solution
  giving the maximum fitness over the whole task is chosen"): one label for all unit tasks; E is
  computed per label with units where that label is unreachable or colliding counted 0 (eq. 8),
  and the best label wins.
- "point": the best collision-free branch at each unit task separately (an upper bound of "task";
  equal when one label is best everywhere). Kept to show what the task-wide choice costs.

`confirm(genes)` re-evaluates one design independently with Drake: the tool pose at each chosen
branch from the MultibodyPlant, the spatial Jacobian from CalcJacobianSpatialVelocity, collisions
from SceneGraph signed distances, and requires the same E.
"""

from __future__ import annotations

import hashlib

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable

from qmt_drake.design import ik
from qmt_drake.design.arm_types import (
    LEVEL_STEP_M,
    N_LEVELS,
    arm_type,
    build_plant,
    forward,
    gene_from_levels,
    jacobian,
)
from qmt_drake.design.operability import direction_ease, fitness_E, operability, task_frame_jacobian
from qmt_drake.design.tasks import Task
from qmt_drake.errors import QmtInputError
from qmt_drake.problem import Evaluation

GENE_NAMES = ("L1_m", "L2_m", "L3_m", "L4_m", "L6_m")
CHUNK_ROWS = 60_000  # IK rows (candidates x units x starts) per numpy pass: bounds memory


def _evaluation(cost: np.ndarray, violation: np.ndarray) -> Evaluation:
    return Evaluation(cost=cost, violation=violation)


def lengths6(genes: np.ndarray) -> np.ndarray:
    """(K, 5) genes -> (K, 6) lengths with L5 = 0."""
    g = np.atleast_2d(np.asarray(genes, dtype=float))
    return np.concatenate([g[:, :4], np.zeros((g.shape[0], 1)), g[:, 4:5]], axis=1)


def genes_from_levels(levels6) -> np.ndarray:
    """Six levels (..., 6) (L5 must be 0) -> genes in m (..., 5)."""
    lv = np.asarray(levels6)
    return np.concatenate([lv[..., :4], lv[..., 5:6]], axis=-1) * LEVEL_STEP_M


def hex_gene(genes) -> str:
    """Genes in m (5,) -> the seed's six-digit hex gene (L5 digit 0)."""
    lv = np.rint(np.asarray(lengths6(genes))[0] / LEVEL_STEP_M).astype(int)
    return gene_from_levels(lv)


BRANCH_MODES = ("task", "point")


class DesignProblem:
    def __init__(self, task: Task, type_name: str, relations: dict | None = None,
                 branch: str = "task") -> None:
        if branch not in BRANCH_MODES:
            raise QmtInputError(f"branch choice {branch!r}: use one of {', '.join(BRANCH_MODES)}")
        self.branch = branch
        self.task = task
        self.relations = relations
        self.type = arm_type(type_name, relations)
        self.name = f"design-{self.type.name}-{task.name}"
        self.gene_names = GENE_NAMES
        self.lower = np.zeros(len(GENE_NAMES))
        self.upper = np.full(len(GENE_NAMES), (N_LEVELS - 1) * LEVEL_STEP_M)
        self.evaluations = 0          # candidates
        self.unit_evaluations = 0     # candidate x unit task pairs (the seed's count)
        self._P, self._R, self._W, self._C, self._a = task.arrays()

    # ------------------------------------------------------------------ protocol
    def evaluate(self, genes: np.ndarray, exact: bool = False):
        """exact is accepted for the protocol; this evaluation is always exact."""
        E = self.fitness_E(genes)
        return _evaluation(-E, np.zeros_like(E))

    def fitness(self, ev) -> np.ndarray:
        return np.maximum(-np.asarray(ev.cost), 0.0)

    def confirm(self, genes: np.ndarray) -> bool:
        rep = self.confirm_report(genes)
        return bool(rep["ok"])

    def fingerprint(self) -> str:
        """Identifies type, level step and every number of the task (for GA checkpoints)."""
        h = hashlib.sha256(f"{self.type.name}|{self.relations}|{LEVEL_STEP_M}|{self.task.link_radius_m}|"
                           f"{self.task.tool_radius_m}|{self.branch}".encode())
        for arr in (self._P, self._R, self._W, self._C, self._a):
            h.update(np.ascontiguousarray(arr, dtype=float).tobytes())
        for c, sz in self.task.boxes:
            h.update(np.concatenate([c, sz]).tobytes())
        return h.hexdigest()[:16]

    # ------------------------------------------------------------------ batched core
    def fitness_E(self, genes: np.ndarray) -> np.ndarray:
        """E (K,) of candidates genes (K, 5) in m."""
        return self._choose(genes)[0]

    def _choose(self, genes: np.ndarray, keep_q: bool = False):
        """E (K,), mu (K, k), reach (K, k), the chosen label (K,) (-1 for "point") and, with keep_q,
        the joint angles (K, k, 6) at the chosen branches (nan where unreachable)."""
        mu_l, reach_l, q_l = self._units(genes, keep_q)          # (K, k, NL), (K, k, NL, 6)
        L = lengths6(genes).sum(axis=1)
        K, k, NL = mu_l.shape
        if self.branch == "point":
            lab = np.where(reach_l, mu_l, -1.0).argmax(axis=2)          # (K, k)
            label = np.full(K, -1)
        else:
            # E of each label over the whole task (eq. 8), the best label wins
            EL = np.stack([fitness_E(mu_l[:, :, b], reach_l[:, :, b], L) for b in range(NL)], axis=1)
            label = EL.argmax(axis=1)
            lab = np.repeat(label[:, None], k, axis=1)
        ii, jj = np.meshgrid(np.arange(K), np.arange(k), indexing="ij")
        mu, reach = mu_l[ii, jj, lab], reach_l[ii, jj, lab]
        q = q_l[ii, jj, lab] if keep_q else None
        if keep_q:
            q[~reach] = np.nan
        return fitness_E(mu, reach, L), mu, reach, label, q

    def _units(self, genes: np.ndarray, keep_q: bool = False):
        """Per candidate, unit task and branch label: the best collision-free operability mu
        (K, k, N_LABELS) (0 where none), reachable (K, k, N_LABELS) and optionally its joint angles
        (K, k, N_LABELS, 6)."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        K, k, NL = g.shape[0], len(self.task.units), ik.N_LABELS
        S = ik.N_START ** 2
        per = max(1, CHUNK_ROWS // (k * S))
        mu = np.zeros((K, k, NL))
        reach = np.zeros((K, k, NL), dtype=bool)
        qbest = np.full((K, k, NL, 6), np.nan) if keep_q else None
        for s in range(0, K, per):
            gs = g[s:s + per]
            m, r, qb = self._units_chunk(gs, keep_q)
            mu[s:s + per], reach[s:s + per] = m, r
            if keep_q:
                qbest[s:s + per] = qb
        self.evaluations += K
        self.unit_evaluations += K * k
        return mu, reach, qbest

    def _units_chunk(self, g, keep_q):
        K, k, NL = g.shape[0], len(self.task.units), ik.N_LABELS
        o = self.type.origins(lengths6(g))                     # (K, 7, 3)
        orep = np.repeat(o, k, axis=0)                           # (K k, 7, 3)
        p = np.tile(self._P, (K, 1))
        R = np.tile(self._R, (K, 1, 1))
        sol = ik.solve(self.type, orep, p, R)
        N, B = sol.ok.shape
        mu = np.full(N * B, -1.0)                                # -1: no valid branch in this slot
        idx = np.flatnonzero(sol.ok.ravel())
        if idx.size:
            n_of = idx // B
            pose = forward(self.type, orep[n_of], sol.q.reshape(-1, 6)[idx])
            free = ~ik.collides(pose.points, self.task.boxes, self.task.link_radius_m,
                                self.task.tool_radius_m)
            J = task_frame_jacobian(jacobian(pose), R[n_of])
            unit = n_of % k
            m = operability(direction_ease(J), self._W[unit], self._C[unit], self._a[unit])
            mu[idx] = np.where(free, m, -1.0)
        mu = mu.reshape(N, B)
        # best slot of each label (several slots share a label only on degenerate arms)
        mlab = np.where(sol.label[:, :, None] == np.arange(NL), mu[:, :, None], -1.0)   # (N, B, NL)
        best = mlab.argmax(axis=1)                                                         # (N, NL)
        mub = np.take_along_axis(mlab, best[:, None, :], axis=1)[:, 0]                     # (N, NL)
        reach = mub >= 0.0
        mub = np.where(reach, mub, 0.0)
        qb = None
        if keep_q:
            qb = sol.q[np.arange(N)[:, None], best].reshape(K, k, NL, 6)
        return mub.reshape(K, k, NL), reach.reshape(K, k, NL), qb

    # ------------------------------------------------------------------ reporting / checks
    def details(self, genes) -> dict:
        g = np.atleast_2d(np.asarray(genes, dtype=float))[:1]
        E, mu, reach, label, q = self._choose(g, keep_q=True)
        L = lengths6(g)
        return {"type": self.type.name, "gene": hex_gene(g[0]), "lengths_m": L[0].tolist(),
                "E_per_m": float(E[0]), "branch": self.branch, "branch_label": int(label[0]),
                "units": [{"name": u.name, "reachable": bool(reach[0, i]), "mu": float(mu[0, i]),
                           "q_rad": q[0, i].tolist()} for i, u in enumerate(self.task.units)]}

    def breakdown(self, genes) -> list[dict]:
        """Per unit task of one design, at the branch the evaluation chose: mu_j of the six task
        axes (eq. 3), w, c (eq. 4-5) and mu (eq. 6); None where unreachable."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))[:1]
        _, _, reach, _, q = self._choose(g, keep_q=True)
        o = self.type.origins(lengths6(g))[0]
        out = []
        for i, u in enumerate(self.task.units):
            if not reach[0, i]:
                out.append(None)
                continue
            pose = forward(self.type, o, q[0, i][None])
            md = direction_ease(task_frame_jacobian(jacobian(pose), u.rotation))[0]
            w = md[u.work].mean() if u.work.any() else 0.0
            c = md[u.constrained].mean() if u.constrained.any() else 0.0
            out.append({"name": u.name, "mu_dir": md.tolist(), "w": float(w), "c": float(c),
                        "mu": float(w * (u.a * w + (1 - u.a) * (1 - c)))})
        return out

    def confirm_report(self, genes) -> dict:
        """Independent re-check of one design with Drake (plant kinematics, spatial Jacobian,
        SceneGraph collision) at the branches the batched evaluation chose."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))[:1]
        det = self.details(g)
        L = lengths6(g)[0]
        arm = build_plant(self.type.name, L, boxes=self.task.boxes,
                          link_radius_m=self.task.link_radius_m, tool_radius_m=self.task.tool_radius_m,
                          relations=self.relations)
        plant = arm.plant
        dctx = arm.diagram.CreateDefaultContext()
        ctx = plant.GetMyMutableContextFromRoot(dctx)
        mus, reach, min_dist, pose_err = [], [], [], 0.0
        for i, u in enumerate(self.task.units):
            q = np.asarray(det["units"][i]["q_rad"])
            if not det["units"][i]["reachable"]:
                mus.append(0.0)
                reach.append(False)
                continue
            plant.SetPositions(ctx, q)
            X = arm.tool_frame.CalcPoseInWorld(ctx)
            pose_err = max(pose_err, np.abs(X.translation() - u.position_m).max(),
                           np.abs(X.rotation().matrix() - u.rotation).max())
            Jd = plant.CalcJacobianSpatialVelocity(ctx, JacobianWrtVariable.kQDot, arm.tool_frame,
                                                   np.zeros(3), plant.world_frame(), plant.world_frame())
            J = task_frame_jacobian(np.vstack([Jd[3:], Jd[:3]])[None], u.rotation)
            m = operability(direction_ease(J), u.work, u.constrained, u.a)[0]
            dmin = arm.min_env_distance(ctx)
            min_dist.append(dmin)
            ok = dmin > 0.0
            mus.append(m if ok else 0.0)
            reach.append(ok)
        mu = np.array([mus])
        r = np.array([reach])
        E = float(fitness_E(mu, r, np.array([L.sum()]))[0])
        ok = (pose_err < 1e-6) and abs(E - det["E_per_m"]) <= 1e-9 * max(1.0, abs(E))
        return {"ok": bool(ok), "E_drake_per_m": E, "E_numpy_per_m": det["E_per_m"],
                "pose_error": float(pose_err), "min_env_distance_m": min_dist, "details": det}
