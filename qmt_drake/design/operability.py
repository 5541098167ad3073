"""Operability of a manipulator for a task (seed 003, eq. 2-8), batched.

Eq. 2: A_j = (1/m) rdot_j^T (J J^T)^-1 rdot_j for the unit velocity rdot_j along task axis j
       (x, y, z in m/s; alpha, beta, gamma about x, y, z in rad/s), i.e. the mean squared joint rate
       (rad^2/s^2) that produces it; for a square, regular J this is |J^-1 e_j|^2 / m.
Eq. 3: mu_j = exp(-A_j).
Eq. 4/5: w (c) = mean of mu_j over the work (constrained) directions, 0 if there are none.
Eq. 6: mu = w (a w + (1 - a)(1 - c)).
Eq. 7: task fitness mu_bar = mean over the k unit tasks (unreachable ones count 0).
Eq. 8: E = mu_bar / sum(L_j) * P_k / k   [1/m], P_k = number of reachable unit tasks.

J must be the Jacobian of the tool point in the TASK frame (rows vx vy vz wx wy wz). At a singular J
a direction outside the range of J cannot be produced at all: A_j = inf, mu_j = 0; inside the range
the least-norm joint rate (pseudo-inverse) is used, the limit of eq. 2 there.
"""

from __future__ import annotations

import numpy as np

AXES = ("x", "y", "z", "alpha", "beta", "gamma")
SINGULAR_DET = 1e-12   # |det J| below this (units m^3 for the 6x6 J): use the pseudo-inverse path
RANGE_TOL = 1e-9


def joint_rate_cost(J: np.ndarray) -> np.ndarray:
    """A (N, 6): eq. 2 for each task axis, from task-frame Jacobians J (N, 6, m)."""
    J = np.asarray(J, dtype=float)
    N, n, m = J.shape
    A = np.empty((N, n))
    if n == m:
        det = np.linalg.det(J)
        reg = np.abs(det) > SINGULAR_DET
        if reg.any():
            Jinv = np.linalg.inv(J[reg])
            A[reg] = np.sum(Jinv ** 2, axis=1) / m  # column j of J^-1 is the joint rate for e_j
        rest = np.flatnonzero(~reg)
    else:
        rest = np.arange(N)
    if rest.size:
        Jp = np.linalg.pinv(J[rest], rcond=1e-10)                 # (r, m, n)
        Ar = np.sum(Jp ** 2, axis=1) / m
        reach = np.einsum("rij,rjk->rik", J[rest], Jp)            # J J^+ e_j should equal e_j
        miss = np.linalg.norm(reach - np.eye(n), axis=1) > 1e-6
        Ar[miss] = np.inf
        A[rest] = Ar
    return A


def direction_ease(J: np.ndarray) -> np.ndarray:
    """mu_j (N, 6) = exp(-A_j), eq. 3."""
    return np.exp(-joint_rate_cost(J))


def operability(mu_dir: np.ndarray, work_mask: np.ndarray, constrained_mask: np.ndarray,
                a) -> np.ndarray:
    """Eq. 4-6. mu_dir (N, 6); work_mask, constrained_mask (N, 6) or (6,) booleans; a (N,) or
    scalar in [0, 1]. Returns mu (N,)."""
    mu_dir = np.asarray(mu_dir, dtype=float)
    wm = np.broadcast_to(np.asarray(work_mask, bool), mu_dir.shape)
    cm = np.broadcast_to(np.asarray(constrained_mask, bool), mu_dir.shape)
    kw, kc = wm.sum(axis=1), cm.sum(axis=1)
    w = np.where(kw > 0, np.sum(np.where(wm, mu_dir, 0.0), axis=1) / np.maximum(kw, 1), 0.0)
    c = np.where(kc > 0, np.sum(np.where(cm, mu_dir, 0.0), axis=1) / np.maximum(kc, 1), 0.0)
    a = np.asarray(a, dtype=float)
    return w * (a * w + (1 - a) * (1 - c))


def task_frame_jacobian(J_base: np.ndarray, R_task: np.ndarray) -> np.ndarray:
    """Express base-frame Jacobians (N, 6, m) (rows v; w) in task frames R_task (N, 3, 3) or (3, 3)
    (columns = task axes in the base frame)."""
    Rt = np.swapaxes(np.broadcast_to(R_task, (J_base.shape[0], 3, 3)), -1, -2)
    return np.concatenate([Rt @ J_base[:, :3], Rt @ J_base[:, 3:]], axis=1)


def task_fitness(mu_units: np.ndarray) -> np.ndarray:
    """Eq. 7: mu_bar (K,) from per-unit-task operabilities (K, k), unreachable units already 0."""
    return np.mean(mu_units, axis=-1)


def fitness_E(mu_units: np.ndarray, reachable: np.ndarray, total_length_m: np.ndarray) -> np.ndarray:
    """Eq. 8: E (K,) [1/m] from mu (K, k) (any value where unreachable), reachable (K, k) bools and
    the sum of link lengths (K,). A design of total length 0 reaches nothing: E = 0."""
    mu = np.where(reachable, mu_units, 0.0)
    k = mu.shape[-1]
    Pk = reachable.sum(axis=-1)
    L = np.asarray(total_length_m, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        E = task_fitness(mu) / L * Pk / k
    return np.where(L > 0, E, 0.0)
