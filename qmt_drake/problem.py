"""PlanningProblem: a scenario's family and limits as one vectorised function of the genes.

`evaluate(genes)` returns the peak ratios of K candidates at once (all samples of all candidates
in one numpy pass); `report(genes)` gives the full LimitReport of one candidate; `trajectory(genes)`
the candidate as a JointTrajectory. Every planner uses this, so they all see the same limits.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.families import make_family
from qmt_drake.limits import BatchPeaks, limit_columns, limit_report
from qmt_drake.sampling import SampleGrid, peak_per_candidate, piecewise_grid, refine_grid
from qmt_drake.scenario import Scenario

COARSE_STRIDE = 20  # coarse samples are every 20th of the planning grid
REFINE_MARGIN = 0.01  # refine around coarse samples within 1% of their candidate's coarse peak
JOINT_REFINE_MARGIN_RAD = 0.05


class PlanningProblem:
    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.arm = scenario.arm
        self.family = make_family(scenario)
        self.gene_names = self.family.gene_names
        self.lower = scenario.family.gene_bounds[:, 0]
        self.upper = scenario.family.gene_bounds[:, 1]
        self.evaluations = 0  # candidates evaluated so far

    def evaluate(self, genes, rate_hz: float | None = None, exact: bool = False) -> BatchPeaks:
        """Peak ratios of candidates `genes` (K, G) on the grid sampled at `rate_hz` (default:
        the scenario's planning rate).

        Fast path (exact=False): sample every COARSE_STRIDE-th point of that grid (an exact
        subset). Candidates already over a limit there are done (their ratios are then lower
        bounds, all a feasibility test needs). For the others the full-rate samples are added
        within one coarse step of every coarse local maximum (within its piece) whose value comes
        within REFINE_MARGIN of its candidate's coarse peak, which finds the full grid's peaks of these piecewise-smooth
        curves (tests/test_problem.py compares with exact=True on random candidates). Joint
        positions are refined only within JOINT_REFINE_MARGIN_RAD of a limit: whether a joint
        leaves its range is decided exactly, its peak excess is not needed."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        rate = rate_hz or self.scenario.sampling.plan_rate_hz
        K, n = g.shape[0], self.arm.n_dof
        self.evaluations += K
        T0 = self.family.motion_time_s(g)
        valid = self.family.valid(g) & np.isfinite(T0)
        peaks = np.full((K, 1 + 3 * n), np.inf)
        todo = np.flatnonzero(valid)
        if todo.size:
            gt = g[todo]
            bp = self.family.breakpoints_s(gt)
            if exact:
                peaks[todo] = self._peaks(gt, piecewise_grid(bp, rate))[0]
            else:
                coarse_grid = piecewise_grid(bp, rate, COARSE_STRIDE)
                coarse, cols = self._peaks(gt, coarse_grid)
                peaks[todo] = coarse
                over = (coarse[:, :1 + n].max(axis=1) > 1.0) | (coarse[:, 1 + n:].max(axis=1) > 1e-12)
                rest = np.flatnonzero(~over)
                if rest.size:
                    c = coarse_grid.candidate
                    cmax = coarse[c]
                    ratios = cols[:, :1 + n]
                    top = (ratios >= cmax[:, :1 + n] * (1 - REFINE_MARGIN)) & _local_max(ratios, coarse_grid)
                    near = np.any(top, axis=1)
                    near |= np.any(cols[:, 1 + n:] >= -JOINT_REFINE_MARGIN_RAD, axis=1)
                    fine_grid = refine_grid(coarse_grid, near & ~over[c])
                    self.last_sample_counts = (coarse_grid.t_s.size, fine_grid.t_s.size)
                    q, qd, qdd = self.family.evaluate(gt, fine_grid.candidate, fine_grid.t_s,
                                                      fine_grid.t_piece_s)
                    fine_cols = limit_columns(self.scenario, q, qd, qdd)
                    # Only the candidates in `rest` have fine samples, contiguous and in order.
                    fine = np.maximum.reduceat(fine_cols, fine_grid.start[rest], axis=0)
                    peaks[todo[rest]] = np.maximum(coarse[rest], fine)
        return BatchPeaks.from_columns(T0, valid, peaks, n)

    def _peaks(self, g, grid):
        q, qd, qdd = self.family.evaluate(g, grid.candidate, grid.t_s, grid.t_piece_s)
        cols = limit_columns(self.scenario, q, qd, qdd)
        return peak_per_candidate(cols, grid), cols

    def sample_candidate(self, genes, rate_hz: float):
        """t, q, qd, qdd of one candidate on the piecewise grid (boundaries twice)."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        grid = piecewise_grid(self.family.breakpoints_s(g), rate_hz)
        q, qd, qdd = self.family.evaluate(g, grid.candidate, grid.t_s, grid.t_piece_s)
        return grid.t_s, q, qd, qdd

    def report(self, genes, rate_hz: float | None = None):
        rate = rate_hz or self.scenario.sampling.check_rate_hz
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        valid = bool(self.family.valid(g)[0])
        T0 = float(self.family.motion_time_s(g)[0])
        t, q, qd, qdd = self.sample_candidate(g, rate)
        return limit_report(self.scenario, t, q, qd, qdd, rate, T0, valid=valid)

    def genes_dict(self, genes) -> dict:
        return {k: float(v) for k, v in zip(self.gene_names, np.ravel(genes))}

    def genes_vector(self, genes: dict) -> np.ndarray:
        missing = [k for k in self.gene_names if k not in genes]
        if missing:
            from qmt_drake.errors import QmtInputError
            raise QmtInputError(f"genes {missing} missing; this family takes {list(self.gene_names)}")
        return np.array([float(genes[k]) for k in self.gene_names])


def _local_max(values: np.ndarray, grid: SampleGrid) -> np.ndarray:
    """Samples >= their neighbours in the same piece of the same candidate, per column."""
    same = np.zeros(values.shape[0], dtype=bool)
    same[1:] = (grid.candidate[1:] == grid.candidate[:-1]) & (grid.piece_a_s[1:] == grid.piece_a_s[:-1])
    ge_prev = np.ones(values.shape, dtype=bool)
    ge_prev[1:] = values[1:] >= values[:-1]
    ge_next = np.ones(values.shape, dtype=bool)
    ge_next[:-1] = values[:-1] >= values[1:]
    left = ~same[:, None] | ge_prev
    right = np.ones(values.shape, dtype=bool)
    right[:-1] = ~same[1:, None] | ge_next[:-1]
    return left & right
