"""Seed 001's trajectory family: each joint velocity a truncated Fourier series (eq. 5)

    qd_i(t) = sum_{j=1..m} [ a_ij (cos(2 pi j t / T) - 1) + b_ij sin(2 pi j t / T) ]

so qd(0) = qd(T) = 0 by construction. Integrated exactly (no numerical quadrature, unlike the
paper's step III which corrects accumulated integration error):

    q_i(t) = theta_i0 + sum_j [ a_ij (T/(2 pi j) sin(2 pi j t/T) - t) + b_ij T/(2 pi j) (1 - cos(2 pi j t/T)) ]
    qdd_i(t) = sum_j (2 pi j / T) [ -a_ij sin(2 pi j t/T) + b_ij cos(2 pi j t/T) ]

Boundary conditions (eq. 6): qdd(0) = qdd(T) = 0 <=> sum_j j b_ij = 0, and q(T) = theta_T <=>
T sum_j a_ij = theta_i0 - theta_iT. The end point (eq. 4, FK(theta_T) = X(T)) is a constraint.

Two gene vectors:
- the paper's "trajectory vector" x = (a (n x m, row-major), b (n x m), T), size 2nm + 1, used by
  steepest descent (which keeps (6) and (4) by projection, as the paper does);
- the reduced vector y = (theta_T (n), a_{i,2..m}, b_{i,2..m}, T), size 2nm + 1 - n, used by the
  NLP: a_i1 = (theta_i0 - theta_iT)/T - sum_{j>=2} a_ij and b_i1 = -sum_{j>=2} j b_ij make (2) and
  (6) hold exactly for every y; only FK(theta_T) = X(T) remains an equality constraint.

On a grid in normalised time s = t/T every basis value is independent of T, which makes the
T-derivatives simple (`basis`). Units: rad, rad/s, rad/s^2, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qmt_drake.config.registry import ENERGY_TIME, FAMILIES, FamilyPlugin
from qmt_drake.errors import QmtInputError
from qmt_drake.trajectory import JointTrajectory

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class Basis:
    """Per-coefficient basis columns (S, m) at normalised times s (S,).
    q = theta0 + T (Pa a' + Pb b'), qd = Va a' + Vb b', qdd = (Aa a' + Ab b') / T."""

    s: np.ndarray
    Pa: np.ndarray
    Pb: np.ndarray
    Va: np.ndarray
    Vb: np.ndarray
    Aa: np.ndarray
    Ab: np.ndarray


def basis(s, m: int) -> Basis:
    s = np.asarray(s, dtype=float).reshape(-1, 1)
    w = TWO_PI * np.arange(1, m + 1)
    sn, cs = np.sin(w * s), np.cos(w * s)
    return Basis(s.ravel(), sn / w - s, (1.0 - cs) / w, cs - 1.0, sn, -w * sn, w * cs)


class FourierVelocityFamily:
    """Eq. (5) for n joints and m terms, starting at theta0 (n,)."""

    def __init__(self, theta0, m: int) -> None:
        if int(m) != m or m < 1:
            raise QmtInputError(f"number of Fourier terms m = {m} must be an integer >= 1")
        self.theta0 = np.asarray(theta0, dtype=float)
        self.n = self.theta0.size
        self.m = int(m)
        self.n_genes = 2 * self.n * self.m + 1
        self.n_reduced = self.n_genes - self.n

    # ------------------------------------------------------------------ paper's vector x
    def unpack(self, x):
        x = np.asarray(x, dtype=float)
        nm = self.n * self.m
        return x[:nm].reshape(self.n, self.m), x[nm:2 * nm].reshape(self.n, self.m), float(x[-1])

    def pack(self, a, b, T) -> np.ndarray:
        return np.concatenate([np.ravel(a), np.ravel(b), [float(T)]])

    def gene_names(self) -> list[str]:
        r = range(1, self.n + 1), range(1, self.m + 1)
        return ([f"a{i}{j}" for i in r[0] for j in r[1]] + [f"b{i}{j}" for i in r[0] for j in r[1]]
                + ["T"])

    def end_posture(self, x) -> np.ndarray:
        a, _, T = self.unpack(x)
        return self.theta0 - T * a.sum(axis=1)

    def accel_residual(self, x) -> np.ndarray:
        """sum_j j b_ij (eq. 6, second line): zero when qdd(0) = qdd(T) = 0."""
        _, b, _ = self.unpack(x)
        return b @ np.arange(1, self.m + 1)

    def evaluate_s(self, x, s, B: Basis | None = None):
        """q, qd, qdd (S, n) at normalised times s in [0, 1]."""
        a, b, T = self.unpack(x)
        B = B or basis(s, self.m)
        q = self.theta0 + T * (B.Pa @ a.T + B.Pb @ b.T)
        qd = B.Va @ a.T + B.Vb @ b.T
        qdd = (B.Aa @ a.T + B.Ab @ b.T) / T
        return q, qd, qdd

    def sample(self, x, t_s):
        """q, qd, qdd (S, n) at times t (s); after T the arm rests at theta_T."""
        T = self.unpack(x)[2]
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        q, qd, qdd = self.evaluate_s(x, np.clip(t / T, 0.0, 1.0))
        rest = t > T
        qd[rest] = 0.0
        qdd[rest] = 0.0
        return q, qd, qdd

    # ------------------------------------------------------------------ batched, like TrajectoryFamily
    def motion_time_s(self, genes) -> np.ndarray:
        return np.atleast_2d(np.asarray(genes, dtype=float))[:, -1].copy()

    def breakpoints_s(self, genes) -> np.ndarray:
        T = self.motion_time_s(genes)
        return np.stack([np.zeros_like(T), T], axis=1)

    def evaluate(self, genes, candidate, t_s, t_piece_s=None):
        """q, qd, qdd (S, n) for sample s of candidate `candidate[s]` (rows of genes (K, 2nm+1))
        at time t_s[s], the signature of qmt_drake.families.TrajectoryFamily.evaluate."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        c = np.asarray(candidate, dtype=int)
        t = np.asarray(t_s, dtype=float)
        nm = self.n * self.m
        a = g[c, :nm].reshape(-1, self.n, self.m)
        b = g[c, nm:2 * nm].reshape(-1, self.n, self.m)
        T = g[c, -1]
        B = basis(np.clip(t / T, 0.0, 1.0), self.m)
        q = self.theta0 + T[:, None] * (np.einsum("sm,snm->sn", B.Pa, a) + np.einsum("sm,snm->sn", B.Pb, b))
        qd = np.einsum("sm,snm->sn", B.Va, a) + np.einsum("sm,snm->sn", B.Vb, b)
        qdd = (np.einsum("sm,snm->sn", B.Aa, a) + np.einsum("sm,snm->sn", B.Ab, b)) / T[:, None]
        rest = t > T
        qd[rest] = 0.0
        qdd[rest] = 0.0
        return q, qd, qdd

    # ------------------------------------------------------------------ reduced vector y
    def reduced_to_full(self, y):
        """x (2nm+1,) and dx/dy (2nm+1, 2nm+1-n) for reduced genes y."""
        y = np.asarray(y, dtype=float)
        n, m = self.n, self.m
        k = m - 1
        thT = y[:n]
        ar = y[n:n + n * k].reshape(n, k)
        br = y[n + n * k:n + 2 * n * k].reshape(n, k)
        T = float(y[-1])
        jj = np.arange(2, m + 1)
        a = np.concatenate([((self.theta0 - thT) / T - ar.sum(axis=1))[:, None], ar], axis=1)
        b = np.concatenate([(-(br @ jj))[:, None], br], axis=1)
        x = self.pack(a, b, T)
        J = np.zeros((self.n_genes, self.n_reduced))
        nm = n * m
        for i in range(n):
            ia1 = i * m
            J[ia1, i] = -1.0 / T
            J[ia1, -1] = -(self.theta0[i] - thT[i]) / T ** 2
            for jk in range(k):
                col = n + i * k + jk
                J[ia1 + 1 + jk, col] = 1.0
                J[ia1, col] = -1.0
                colb = n + n * k + i * k + jk
                J[nm + ia1 + 1 + jk, colb] = 1.0
                J[nm + ia1, colb] = -(jk + 2.0)
        J[-1, -1] = 1.0
        return x, J

    def full_to_reduced(self, x) -> np.ndarray:
        a, b, T = self.unpack(x)
        return np.concatenate([self.end_posture(x), a[:, 1:].ravel(), b[:, 1:].ravel(), [T]])

    def reduced_names(self) -> list[str]:
        n, m = self.n, self.m
        return ([f"thetaT{i}" for i in range(1, n + 1)]
                + [f"a{i}{j}" for i in range(1, n + 1) for j in range(2, m + 1)]
                + [f"b{i}{j}" for i in range(1, n + 1) for j in range(2, m + 1)] + ["T"])

    def initial_genes(self, theta_T, T: float) -> np.ndarray:
        """The simplest member: a_i1 = (theta_i0 - theta_iT)/T, all other coefficients 0."""
        a = np.zeros((self.n, self.m))
        a[:, 0] = (self.theta0 - np.asarray(theta_T, dtype=float)) / T
        return self.pack(a, np.zeros((self.n, self.m)), T)

    def trajectory(self, x) -> FourierTrajectory:
        return FourierTrajectory(self, x)


class FourierTrajectory(JointTrajectory):
    """One gene vector as a qmt_drake JointTrajectory (exact formulas; breakpoints 0 and T)."""

    def __init__(self, family: FourierVelocityFamily, x) -> None:
        self.family = family
        self.x = np.asarray(x, dtype=float).copy()
        self.duration_s = family.unpack(self.x)[2]
        self.breakpoints_s = np.array([0.0, self.duration_s])
        self.n_dof = family.n

    def evaluate(self, t_s, t_piece_s=None):
        return self.family.sample(self.x, t_s)
    # to_piecewise_polynomial: JointTrajectory's (the cubic Hermite through q and the exact qd at rate_hz;
    # pydrake 1.51 has no quintic Hermite)


# seed 001 eq. 5; the energy problem builds it from the start posture and m (energy/problem.py)
FAMILIES.register(FamilyPlugin("fourier_velocity", FourierVelocityFamily, scenario_kind=ENERGY_TIME))
