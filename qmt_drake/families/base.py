"""The interface every trajectory family implements, vectorised over candidates."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from qmt_drake.errors import QmtInputError


class TrajectoryFamily(ABC):
    """Maps gene vectors (K, G) to joint trajectories.

    Subclasses define `expected_genes` (thesis names, thesis order), `motion_time_s`,
    `valid` (genes that define a trajectory at all), `breakpoints_s` (phase boundaries, including
    0 and T0, sorted per row) and `evaluate` (q, qd, qdd at flat samples; see sampling.py).
    After T0 the arm rests at the goal.
    """

    expected_genes: tuple[str, ...] = ()

    def __init__(self, scenario) -> None:
        self.scenario = scenario
        self.arm = scenario.arm
        self.gene_names = scenario.family.gene_names
        self.gene_bounds = scenario.family.gene_bounds
        if tuple(self.gene_names) != tuple(self.expected_genes):
            raise QmtInputError(
                f"{scenario.source_path}: family '{scenario.family.kind}' takes genes "
                f"{list(self.expected_genes)} in this order, got {list(self.gene_names)}")
        n_points = len(scenario.task.points_m)
        self.joint_points = np.stack([
            self.arm.inverse_kinematics(p, scenario.task.tool_angle_rad, scenario.task.ik_branch,
                                        what=_point_name(i, n_points))
            for i, p in enumerate(scenario.task.points_m)])

    @property
    def n_dof(self) -> int:
        return self.arm.n_dof

    @abstractmethod
    def motion_time_s(self, genes: np.ndarray) -> np.ndarray: ...

    #: How each gene scales when the motion is slowed by a factor lam (t -> lam*t): times scale
    #: by lam**1, rates by lam**-1. Every limit here is inertial (no gravity in the plane), so
    #: slowing by lam divides every peak ratio by lam**2 exactly.
    time_exponents: tuple[int, ...] | None = None

    def time_scaled(self, genes: np.ndarray, lam) -> np.ndarray:
        """Genes of the same motion played lam times slower (lam may be (K,))."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        exps = np.array(self.time_exponents or (1,) * g.shape[1])
        return g * np.asarray(lam, dtype=float).reshape(-1, 1) ** exps

    def valid(self, genes: np.ndarray) -> np.ndarray:
        return np.ones(np.atleast_2d(genes).shape[0], dtype=bool)

    @abstractmethod
    def breakpoints_s(self, genes: np.ndarray) -> np.ndarray: ...

    @abstractmethod
    def evaluate(self, genes: np.ndarray, candidate: np.ndarray, t_s: np.ndarray,
                 t_piece_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, qd, qdd (S, n) for sample s of candidate `candidate[s]` at time t_s[s], using the
        formula of the piece that contains t_piece_s[s]."""

    def sample(self, genes, t_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q, qd, qdd (len(t), n) of one gene vector at times t (right-continuous pieces)."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        bp = self.breakpoints_s(g)[0]
        # The piece a time belongs to: right-continuous, the last piece closed at T0.
        j = np.clip(np.searchsorted(bp, t, side="right") - 1, 0, len(bp) - 1)
        hi = np.append(bp[1:], bp[-1] + 1.0)
        mid = np.where(t >= bp[-1], bp[-1] + 1.0, 0.5 * (bp[j] + hi[j]))
        # A zero-length piece gives a midpoint on its own boundary; step past it.
        return self.evaluate(g, np.zeros(t.size, dtype=int), t, mid)


def _point_name(i: int, n: int) -> str:
    if i == 0:
        return "start point"
    if i == n - 1:
        return "goal point"
    return f"via point {i}"
