"""Seed 001's steepest-descent search over the trajectory vector x = (a_ij, b_ij, T) (section 2):

I.   start: theta0 from the start-posture rule; the initial a_ij, b_ij and T (the caller's x0) are
     made to satisfy (4) and (6) by step III below ("T sufficiently large": the paper uses T = 1 s).
II.  dz/dx (exact, objective.py) is projected onto the tangent space of the constraints
         sum_j j b_ij = 0                      (eq. 6, second line: qdd(0) = qdd(T) = 0)
         FK(theta0 - T sum_j a_ij) = X(T)      (eq. 4 at t = T; eq. 6 first line defines theta_T)
     and x moves against it.
III. the end point drifts off (4) along the curved constraint; a minimum-norm correction of the
     a_ij (Gauss-Newton, to 1e-12 m) puts it back. (6) is linear and stays exact.
IV.  stop when the mean over the genes of |x_k^{new} - x_k| / |x_k| is below 1e-4 five times in a row
     (the paper's rule; genes with |x_k| < 1e-12, e.g. frozen zeros, are left out of the mean since
     their relative change is undefined), or after `max_iter` iterations (reported as not converged).

metric="euclidean" is the paper's plain gradient. It is badly conditioned here (T and the
coefficients differ in scale by orders of magnitude) and creeps: see the study. metric="diagonal"
(an addition, not the paper's) measures steepness in the Jacobi metric D = diag of the
Gauss-Newton Hessian of z (objective.gauss_newton_diagonal, refreshed every iteration): the
direction is -D^-1 g projected in the D-metric, still a first-order steepest-descent method.

The paper does not give its step-size rule. Here: backtracking (Armijo, sufficient decrease 1e-4)
from twice the last accepted step, starting at a step that changes x by 1 % of |x|. Every trial
point is corrected by step III before its z is compared, so each accepted iterate is feasible.
Iterations count accepted steps (the paper's k).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from qmt_drake.energy.kinematics import tip_jacobian, tip_position
from qmt_drake.energy.problem import T_MIN_S, EnergyProblem
from qmt_drake.errors import QmtInputError

PAPER_REL_TOL = 1e-4   # step IV: mean relative change of the trajectory vector ...
PAPER_STREAK = 5       # ... below 1e-4 five times in a row


@dataclass
class SteepestResult:
    x: np.ndarray
    z: float
    iterations: int
    evaluations: int
    converged: bool
    wall_s: float
    stop_reason: str
    history_z: list = field(default_factory=list)
    history_rel: list = field(default_factory=list)   # the paper's mean relative change per step
    history_decrease: list = field(default_factory=list)  # -g.d / z per step (first-order decrease)
    paper_rule_iteration: int | None = None   # where the paper's rule (1e-4 x 5) fired, if it did
    paper_rule_z: float | None = None
    paper_rule_x: np.ndarray | None = None


def _free_mask(problem: EnergyProblem) -> np.ndarray:
    """Genes of x the search may change (frozen joints and a fixed T stay put)."""
    F = problem.family
    n, m = F.n, F.m
    free = np.ones(F.n_genes, dtype=bool)
    if problem.fixed_T_s is not None:
        free[-1] = False
    if problem.moving_joints is not None:
        for i in set(range(n)) - set(problem.moving_joints):
            free[i * m:(i + 1) * m] = False
            free[n * m + i * m:n * m + (i + 1) * m] = False
    return free


def constraint_jacobian(problem: EnergyProblem, x) -> np.ndarray:
    """(n + 2, 2nm+1): rows d(sum_j j b_ij)/dx, then d FK(theta_T(x))/dx."""
    F = problem.family
    n, m = F.n, F.m
    a, _, T = F.unpack(x)
    C = np.zeros((n + 2, F.n_genes))
    for i in range(n):
        C[i, n * m + i * m:n * m + (i + 1) * m] = np.arange(1, m + 1)
    Jfk = tip_jacobian(problem.arm, F.end_posture(x))  # (2, n)
    for i in range(n):
        C[n:, i * m:(i + 1) * m] = -T * Jfk[:, i:i + 1]   # theta_Ti = theta_0i - T sum_j a_ij
    C[n:, -1] = Jfk @ (-a.sum(axis=1))
    return C


def restore_endpoint(problem: EnergyProblem, x, free=None, tol_m: float = 1e-12, max_newton: int = 30):
    """Step III: minimum-norm change of the free a_ij so that FK(theta_T) = X(T). Returns x or
    None if Gauss-Newton does not get there."""
    F = problem.family
    n, m = F.n, F.m
    x = np.array(x, dtype=float)
    free = _free_mask(problem) if free is None else free
    cols = np.array([k for k in range(n * m) if free[k]])
    for _ in range(max_newton):
        r = tip_position(problem.arm, F.end_posture(x)) - problem.XT
        if np.linalg.norm(r) < tol_m:
            return x
        A = constraint_jacobian(problem, x)[n:, cols]
        # minimum-norm least-squares step: also right when only some joints move (rank < 2)
        x[cols] -= np.linalg.lstsq(A, r, rcond=None)[0]
    r = tip_position(problem.arm, F.end_posture(x)) - problem.XT
    return x if np.linalg.norm(r) < tol_m else None


def enforce_accel_condition(problem: EnergyProblem, x) -> np.ndarray:
    """Minimum-norm change of the b_ij so that sum_j j b_ij = 0 (eq. 6)."""
    F = problem.family
    a, b, T = F.unpack(x)
    j = np.arange(1, F.m + 1)
    b = b - np.outer(b @ j, j) / (j @ j)
    return F.pack(a, b, T)


def steepest_descent(problem: EnergyProblem, x0, max_iter: int = 20000, rel_tol: float = PAPER_REL_TOL,
                     streak: int = PAPER_STREAK, max_wall_s: float = 120.0,
                     metric: str = "euclidean") -> SteepestResult:
    """rel_tol = 1e-4 and streak = 5 are the paper's stopping rule; a smaller rel_tol is a stricter
    rule of the same kind (the result then also says where the paper's rule would have stopped:
    `paper_rule_iteration`, `paper_rule_z`, `paper_rule_x`; the iterates are the same up to there)."""
    if metric not in ("euclidean", "diagonal"):
        raise QmtInputError(f"steepest-descent metric '{metric}' must be 'euclidean' or 'diagonal'")
    obj = problem.objective
    free = _free_mask(problem)
    t0 = time.perf_counter()
    x = enforce_accel_condition(problem, np.asarray(x0, dtype=float))
    if problem.fixed_T_s is not None:
        x[-1] = problem.fixed_T_s
    x = restore_endpoint(problem, x, free)
    if x is None:
        raise QmtInputError("the initial trajectory vector cannot be corrected onto the end point "
                            "X(T) (step III failed); give an initial vector closer to it")
    ev0 = obj.evaluations
    z, g = obj.value_and_gradient(x)
    hist = [z]
    hist_rel = []
    hist_dec = []
    paper_good, paper_it, paper_z, paper_x = 0, None, None, None
    step = None
    good = 0
    it = 0
    reason = "max_iter"
    while it < max_iter:
        if time.perf_counter() - t0 > max_wall_s:
            reason = "max_wall_s"
            break
        C = constraint_jacobian(problem, x)[:, free]
        gf = g[free]
        if metric == "diagonal":
            Dinv = 1.0 / np.maximum(obj.gauss_newton_diagonal(x)[free], 1e-12)
        else:
            Dinv = np.ones(gf.size)
        # project onto the null space of the constraint rows in the metric D (least squares:
        # robust at rank loss)
        CD = C * Dinv
        lam = np.linalg.lstsq(CD @ C.T, CD @ gf, rcond=None)[0]
        d = np.zeros_like(x)
        d[free] = -Dinv * (gf - C.T @ lam)
        slope = float(g @ d)
        hist_dec.append(-slope / abs(z))
        if not slope < 0.0:
            reason = "stationary"
            break
        if step is None:
            step = 0.01 * np.linalg.norm(x[free]) / np.linalg.norm(d)
        else:
            step *= 2.0
        accepted = False
        for _ in range(60):
            xt = x + step * d
            if xt[-1] >= T_MIN_S:
                xt = restore_endpoint(problem, xt, free)
                if xt is not None:
                    zt = obj.value(xt)
                    if zt <= z + 1e-4 * step * slope:
                        accepted = True
                        break
            step *= 0.5
        if not accepted:
            reason = "line_search"
            break
        it += 1
        big = (np.abs(x) > 1e-12) & free
        rel = float(np.mean(np.abs(xt[big] - x[big]) / np.abs(x[big]))) if big.any() else 0.0
        x = xt
        z, g = obj.value_and_gradient(x)
        hist.append(z)
        hist_rel.append(rel)
        good = good + 1 if rel < rel_tol else 0
        paper_good = paper_good + 1 if rel < PAPER_REL_TOL else 0
        if paper_it is None and paper_good >= PAPER_STREAK:
            paper_it, paper_z, paper_x = it, z, x.copy()
        if good >= streak:
            reason = "converged"
            break
    return SteepestResult(x, z, it, obj.evaluations - ev0, reason == "converged",
                          time.perf_counter() - t0, reason, hist, hist_rel, hist_dec,
                          paper_it, paper_z, paper_x)
