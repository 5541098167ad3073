"""Chapter 4: one joint-space cubic per segment through N >= 0 via points (eq. 4-1..4-30).

N vias give N+1 segments with times T1..T_{N+1} (the genes; T0 is their sum). Conditions:
position at every knot (2 per segment), zero joint velocity at start and goal, velocity and
acceleration continuous at each via: 4N+4 equations for 4N+4 coefficients per joint. The thesis
derives closed forms for N = 2 and suggests elimination for general N; the system is solved here
numerically, batched over candidates (`tests/test_families.py` checks it against the thesis's
closed form eq. 4-15..4-30). Acceleration jumps from rest at t = 0 and back to rest at T0.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.families.base import TrajectoryFamily


class ViaCubic(TrajectoryFamily):
    def __init__(self, scenario) -> None:
        n_seg = len(scenario.task.points_m) - 1
        self.expected_genes = tuple(f"T{i + 1}" for i in range(n_seg))
        super().__init__(scenario)
        self.n_segments = n_seg

    def motion_time_s(self, genes):
        return np.atleast_2d(genes).sum(axis=1)

    def breakpoints_s(self, genes):
        g = np.atleast_2d(genes)
        return np.concatenate([np.zeros((g.shape[0], 1)), np.cumsum(g, axis=1)], axis=1)

    def coefficients(self, genes) -> np.ndarray:
        """Cubic coefficients (K, n_segments, 4, n_dof): theta = a0 + a1*tau + a2*tau^2 + a3*tau^3
        with tau the time since the segment's start."""
        T = np.atleast_2d(np.asarray(genes, dtype=float))
        K, m = T.shape
        M = 4 * m
        A = np.zeros((K, M, M))
        rhs = np.zeros((K, M, self.n_dof))
        pts = self.joint_points
        row = 0

        def put(seg, powers_coef):
            for p, c in powers_coef:
                A[:, row, 4 * seg + p] = c

        for s in range(m):
            Ts = T[:, s]
            put(s, [(0, 1.0)])  # theta(0) = knot s
            rhs[:, row] = pts[s]
            row += 1
            put(s, [(0, 1.0), (1, Ts), (2, Ts**2), (3, Ts**3)])  # theta(Ts) = knot s+1
            rhs[:, row] = pts[s + 1]
            row += 1
        put(0, [(1, 1.0)])  # start at rest
        row += 1
        put(m - 1, [(1, 1.0), (2, 2 * T[:, -1]), (3, 3 * T[:, -1] ** 2)])  # goal at rest
        row += 1
        for s in range(m - 1):
            Ts = T[:, s]
            put(s, [(1, 1.0), (2, 2 * Ts), (3, 3 * Ts**2)])  # velocity continuity
            A[:, row, 4 * (s + 1) + 1] = -1.0
            row += 1
            put(s, [(2, 2.0), (3, 6 * Ts)])  # acceleration continuity
            A[:, row, 4 * (s + 1) + 2] = -2.0
            row += 1
        coef = np.linalg.solve(A, rhs)  # (K, M, n)
        return coef.reshape(K, m, 4, self.n_dof)

    def evaluate(self, genes, candidate, t_s, t_piece_s):
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        K, m, n = g.shape[0], self.n_segments, self.n_dof
        # A batch is evaluated twice in a row (coarse grid, then refinement): solve once.
        memo = getattr(self, "_memo", None)
        if memo is not None and memo[0].shape == g.shape and np.array_equal(memo[0], g):
            coef = memo[1]
        else:
            coef = self.coefficients(g).reshape(K * m, 4 * n)
            self._memo = (g.copy(), coef)
        bp = self.breakpoints_s(g)
        seg = np.zeros(t_s.shape, dtype=int)
        for j in range(1, m):  # the segment whose interior holds the piece time
            seg += t_piece_s >= bp[candidate, j]
        flat = candidate * m + seg
        c = coef.take(flat, axis=0).reshape(-1, 4, n)
        seg_start = bp[:, :-1].ravel().take(flat)
        seg_end = bp[:, 1:].ravel().take(flat)
        rest = t_piece_s >= np.where(seg < m - 1, np.inf, seg_end)  # after T0: rest at the goal
        tau = (np.where(rest, seg_end, t_s) - seg_start)[:, None]
        q = c[:, 0] + tau * (c[:, 1] + tau * (c[:, 2] + tau * c[:, 3]))
        qd = c[:, 1] + tau * (2 * c[:, 2] + 3 * tau * c[:, 3])
        qdd = 2 * c[:, 2] + 6 * tau * c[:, 3]
        if rest.any():
            qd[rest] = 0.0
            qdd[rest] = 0.0
        return q, qd, qdd
