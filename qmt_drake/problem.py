"""The problem protocol every gene-based planner works on, and the transfer-planning problem.

A `Problem` is bounds plus a batched `evaluate(genes) -> Evaluation(cost, violation)` and a
`fitness` that turns an evaluation into a non-negative score (larger is better, 0 when
infeasible). The GA (planners/ga.py) and the family optimum take any Problem, so a new objective
or a new design problem (seed 003's link lengths) needs no change to them.

`PlanningProblem` is the transfer task of a scenario: its trajectory family's genes, its limit set
and an objective (minimum motion time by default). `peaks(genes)` returns the peak limit ratios of
K candidates at once (all samples of all candidates in one numpy pass); `report(genes)` gives the
full LimitReport of one candidate. Every planner uses these, so they all see the same limits.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from qmt_drake.config.registry import OBJECTIVES, TRANSFER, ObjectivePlugin, for_scenario_kind
from qmt_drake.errors import QmtInputError
from qmt_drake.families import make_family
from qmt_drake.limits import BatchPeaks
from qmt_drake.sampling import SampleGrid, peak_per_candidate, piecewise_grid, refine_grid
from qmt_drake.trajectory import FamilyTrajectory
from qmt_drake.transfer_scenario import TransferScenario

COARSE_STRIDE = 20  # coarse samples are every 20th of the planning grid
REFINE_MARGIN = 0.01  # refine around coarse samples within 1% of their candidate's coarse peak
JOINT_REFINE_MARGIN_RAD = 0.05


@dataclass(frozen=True)
class Evaluation:
    """Batched result of a Problem: `cost` (K,) to minimise (inf where the genes define nothing)
    and `violation` (K,) >= 0, 0 when every limit holds."""

    cost: np.ndarray
    violation: np.ndarray

    @property
    def feasible(self) -> np.ndarray:
        return (self.violation <= 0.0) & np.isfinite(self.cost)


@runtime_checkable
class Problem(Protocol):
    """What the GA and other gene-based planners need (see module docstring)."""

    name: str
    gene_names: tuple
    lower: np.ndarray
    upper: np.ndarray

    def evaluate(self, genes: np.ndarray, exact: bool = False) -> Evaluation:
        """(K, G) genes -> Evaluation. exact=False may return a lower bound of the violation of an
        infeasible candidate (enough to reject it); exact=True must return the true value."""

    def fitness(self, ev: Evaluation) -> np.ndarray:
        """(K,) >= 0, larger is better, 0 for infeasible candidates."""

    def confirm(self, genes: np.ndarray) -> bool:
        """An independent final check of one candidate (e.g. a finer re-check)."""

    def fingerprint(self) -> str:
        """Identifies the problem's data, so a checkpoint is resumed only by the same problem."""


@dataclass(frozen=True)
class MinimumTime:
    """Objective of seed 000: cost = motion time T0 [s]; GA fitness exp(-c T0) when every limit
    holds, else 0 (eq. 2-36)."""

    fitness_c_per_s: float

    def fitness(self, ev: Evaluation) -> np.ndarray:
        return np.where(ev.feasible, np.exp(-self.fitness_c_per_s * np.where(ev.feasible, ev.cost, 0.0)), 0.0)


# the transfer scenarios' objective: make(scenario) -> MinimumTime with the scenario's GA fitness constant
OBJECTIVES.register(ObjectivePlugin("min_time", lambda scenario: MinimumTime(scenario.ga.fitness_c_per_s),
                                    summary="T0, the motion time; GA fitness exp(-c T0) when every limit holds"))


class PlanningProblem:
    """A scenario's transfer task as a Problem (minimum time under its limit set, or the registered
    transfer objective `objective` names)."""

    def __init__(self, scenario: TransferScenario, objective: MinimumTime | str | None = None) -> None:
        self.scenario = scenario
        self.name = scenario.name
        if objective is None or isinstance(objective, str):
            entry = OBJECTIVES.get(objective or scenario.objective, "PlanningProblem objective",
                                   accept=for_scenario_kind(TRANSFER))
            objective = entry.make(scenario)
        self.objective = objective
        self.arm = scenario.arm
        self.limit_set = scenario.limit_set
        self.family = make_family(scenario)
        self.gene_names = self.family.gene_names
        self.lower = scenario.family.gene_bounds[:, 0]
        self.upper = scenario.family.gene_bounds[:, 1]
        self.evaluations = 0  # candidates evaluated so far

    def evaluate(self, genes, exact: bool = False) -> Evaluation:
        """The Problem protocol: cost = motion time, violation = how far the worst limit ratio
        exceeds 1 plus how far a joint leaves its range [rad] (inf: the genes define no motion)."""
        p = self.peaks(genes, exact=exact)
        excess = np.maximum(p.worst_ratio - 1.0, 0.0) + (~p.joint_range_ok) * np.maximum(p.joint_excess_rad, 1e-12)
        violation = np.where(p.valid, excess, np.inf)
        return Evaluation(np.where(p.valid, p.motion_time_s, np.inf), violation)

    def fitness(self, ev: Evaluation) -> np.ndarray:
        return self.objective.fitness(ev)

    def confirm(self, genes) -> bool:
        return bool(self.report(genes).feasible)

    def fingerprint(self) -> str:
        return self.scenario.fingerprint()

    def peaks(self, genes, rate_hz: float | None = None, exact: bool = False) -> BatchPeaks:
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
        K = g.shape[0]
        ls = self.limit_set
        n_cols, ratio = ls.n_columns, ls.ratio_mask
        self.evaluations += K
        T0 = self.family.motion_time_s(g)
        valid = self.family.valid(g) & np.isfinite(T0)
        peaks = np.full((K, n_cols), np.inf)
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
                over = (coarse[:, ratio].max(axis=1, initial=0.0) > 1.0) | (
                    coarse[:, ~ratio].max(axis=1, initial=-np.inf) > 1e-12)
                rest = np.flatnonzero(~over)
                if rest.size:
                    c = coarse_grid.candidate
                    cmax = coarse[c]
                    ratios = cols[:, ratio]
                    top = (ratios >= cmax[:, ratio] * (1 - REFINE_MARGIN)) & _local_max(ratios, coarse_grid)
                    near = np.any(top, axis=1)
                    near |= np.any(cols[:, ~ratio] >= -JOINT_REFINE_MARGIN_RAD, axis=1)
                    fine_grid = refine_grid(coarse_grid, near & ~over[c])
                    self.last_sample_counts = (coarse_grid.t_s.size, fine_grid.t_s.size)
                    q, qd, qdd = self.family.evaluate(gt, fine_grid.candidate, fine_grid.t_s,
                                                      fine_grid.t_piece_s)
                    fine_cols = ls.columns(q, qd, qdd)
                    # Only the candidates in `rest` have fine samples, contiguous and in order.
                    fine = np.maximum.reduceat(fine_cols, fine_grid.start[rest], axis=0)
                    peaks[todo[rest]] = np.maximum(coarse[rest], fine)
        return ls.batch_peaks(T0, valid, peaks)

    def _peaks(self, g, grid):
        q, qd, qdd = self.family.evaluate(g, grid.candidate, grid.t_s, grid.t_piece_s)
        cols = self.limit_set.columns(q, qd, qdd)
        return peak_per_candidate(cols, grid), cols

    def sample_candidate(self, genes, rate_hz: float):
        """t, q, qd, qdd of one candidate on the piecewise grid (boundaries twice)."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        grid = piecewise_grid(self.family.breakpoints_s(g), rate_hz)
        q, qd, qdd = self.family.evaluate(g, grid.candidate, grid.t_s, grid.t_piece_s)
        return grid.t_s, q, qd, qdd

    def report(self, genes, rate_hz: float | None = None):
        """The re-check of one candidate (LimitSet.report: check rate, local maxima refined)."""
        g = np.atleast_2d(np.asarray(genes, dtype=float))
        valid = bool(self.family.valid(g)[0])
        return self.limit_set.report(FamilyTrajectory(self.family, g[0]),
                                     rate_hz or self.scenario.sampling.check_rate_hz, valid=valid)

    def genes_dict(self, genes) -> dict:
        return {k: float(v) for k, v in zip(self.gene_names, np.ravel(genes))}

    def genes_vector(self, genes: dict) -> np.ndarray:
        missing = [k for k in self.gene_names if k not in genes]
        if missing:
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
