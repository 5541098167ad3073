"""The family optimum: the shortest motion a trajectory family allows under the limits, found
deterministically, to measure how far the GA is from the best of its own family.

When every limit is inertial (LimitSet.time_scaling_is_exact: no gravity in the plane, no
velocity limit), playing a motion lam times slower divides every peak ratio by lam^2 exactly, and a
gene vector x maps to the tight motion y(x) = time_scaled(x, sqrt(worst_ratio(x))), whose duration is
T0(x) * sqrt(worst_ratio(x)); the family optimum is the smallest such duration among the y that
stay inside the gene bounds. That objective is piecewise smooth (a max over samples), so it is
minimised with bounded Nelder-Mead (the one family-optimum search, planners/family_optimum_core.py;
this is its planar adapter) from a seeded Latin hypercube of starts, with a penalty for y leaving
the bounds; the best y is clipped to the bounds and, if still over a limit,
slowed by the exact factor. With gravity (or any other non-inertial limit) the tight scale is found
by a batched bisection on lam instead (`tight_scale`). The winner is re-checked at the check rate
like every plan.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.stats import qmc

from qmt_drake.plan import Plan, family_plan
from qmt_drake.planners import family_optimum_core
from qmt_drake.problem import Evaluation, PlanningProblem
from qmt_drake.timescale import Grow, bisect_batch, search_scale

BOUND_PENALTY_S = 100.0  # seconds of objective per unit of normalised bound violation


def tight_motion(problem: PlanningProblem, genes: np.ndarray):
    """(y, T0(y), bound violation) for rows of genes, y on the limit boundary (nan if none)."""
    g = np.atleast_2d(genes)
    lam = tight_scale(problem, g)
    y = problem.family.time_scaled(g, lam)
    span = problem.upper - problem.lower
    viol = (np.maximum(problem.lower - y, 0) + np.maximum(y - problem.upper, 0)) / span
    return y, problem.family.motion_time_s(y), viol.sum(axis=1)


def tight_scale(problem: PlanningProblem, genes: np.ndarray, *, lam_max: float = 1e3,
                iterations: int = 40) -> np.ndarray:
    """(K,) smallest lam with the motion played lam times slower on every limit (nan: none).

    Exact (lam = sqrt(worst ratio)) when the limit set allows the time-scaling shortcut; otherwise
    a batched bisection in log(lam) over [1/lam_max, lam_hi] (40 halvings of every row:
    timescale.bisect_batch), where lam_hi is
    lam_max or, if smaller, the slowing that makes the motion as long as the family's slowest
    motion (all genes at their upper bounds; slower ones lie outside the family, and sampling
    them would cost memory in proportion to their length)."""
    g = np.atleast_2d(genes)
    peaks = problem.peaks(g)
    ok = peaks.valid & peaks.joint_range_ok & np.isfinite(peaks.worst_ratio)
    if problem.limit_set.time_scaling_is_exact:
        return np.sqrt(np.where(ok, peaks.worst_ratio, np.nan))
    slowest_s = problem.family.motion_time_s(problem.upper[None])[0]
    lam_hi = np.clip(slowest_s / problem.family.motion_time_s(g), 1.0, lam_max)
    lo = np.full(len(g), -np.log(lam_max))
    hi = np.log(lam_hi)
    feasible_hi = problem.peaks(problem.family.time_scaled(g, np.exp(hi))).feasible

    def excess(v, i):  # the verdict at lam = exp(v): -1 on every limit, 1 over one
        return np.where(problem.peaks(problem.family.time_scaled(g[i], np.exp(v))).feasible, -1.0, 1.0)
    hi = bisect_batch(excess, lo, hi, rel_tol=None, max_steps=iterations, midpoint="arithmetic", safe="above")
    return np.where(ok & feasible_hi, np.exp(hi), np.nan)


class TightTimingProblem:
    """A PlanningProblem whose every candidate is played at its tight time scale (`tight_motion`):
    the GA with `ga.tight_timing` searches motion shapes and each is timed exactly to its limits.
    Problem protocol (problem.py); `realize(genes)` gives the family genes of the tight motion."""

    def __init__(self, base: PlanningProblem) -> None:
        self.base = base
        self.scenario, self.family, self.limit_set = base.scenario, base.family, base.limit_set
        self.name, self.gene_names = base.name, base.gene_names
        self.lower, self.upper = base.lower, base.upper

    def evaluate(self, genes, exact: bool = False):
        y, T0, viol = tight_motion(self.base, genes)
        ok = np.isfinite(T0)
        return Evaluation(np.where(ok & (viol <= 0), T0, np.inf), np.where(ok, viol, np.inf))

    def fitness(self, ev):
        return self.base.fitness(ev)

    def realize(self, genes) -> np.ndarray:
        """(G,) family genes of the tight motion of `genes` (inside the bounds: `evaluate` gives a
        tight motion that leaves them a violation), slowed further if the refined re-check needs it."""
        y = tight_motion(self.base, np.atleast_2d(genes))[0][0]
        if not self.base.confirm(y):
            y = _slow_until_confirmed(self.base, y)
        return y

    def confirm(self, genes) -> bool:
        y = tight_motion(self.base, np.atleast_2d(genes))[0][0]
        return bool(np.all(np.isfinite(y))) and self.base.confirm(_slow_until_confirmed(self.base, y))

    def fingerprint(self) -> str:
        return self.base.fingerprint() + ":tight_timing"


def plan_family_optimum(problem: PlanningProblem, *, starts: int = 24, polished: int = 6,
                        seed: int = 0, progress=None) -> Plan:
    """Best gene vector of the family (see module docstring); returns a re-checked Plan."""
    t_start = time.perf_counter()
    lo, hi = problem.lower, problem.upper
    span = hi - lo
    n_eval0 = problem.evaluations
    x0 = lo + span * qmc.LatinHypercube(d=lo.size, seed=seed).random(starts)
    _, T0s, viol = tight_motion(problem, x0)
    score = np.where(np.isfinite(T0s), T0s + BOUND_PENALTY_S * viol, np.inf)
    order = np.argsort(score)[:polished]

    def objective(z):
        y, T0, v = tight_motion(problem, (lo + span * z)[None])
        return float(T0[0] + BOUND_PENALTY_S * v[0]) if np.isfinite(T0[0]) else 1e6

    def settle(res):  # the tight motion of the polished start, inside the gene bounds (or dropped)
        y = _settle_inside_bounds(problem, tight_motion(problem, (lo + span * res.x)[None])[0][0])
        return None if y is None else (float(problem.family.motion_time_s(y[None])[0]), y)

    def report(k, T0):
        if progress:
            progress(f"{problem.scenario.name} optimum: start {k + 1}/{len(order)} -> T0 {T0:.5f} s")

    starts_z = [(x0[i] - lo) / span if np.isfinite(score[i]) else None for i in order]
    best = family_optimum_core.minimise(objective, starts_z, bounds=[(0.0, 1.0)] * lo.size, settle=settle,
                                        progress=report, options={"xatol": 1e-7, "fatol": 1e-8, "maxiter": 2000})
    genes = best[1] if best is not None else x0[order[0]]
    plan = family_plan(problem, genes, "optimum")
    if best is not None and not plan.feasible and plan.check.joint_range_ok:
        # The refined check found a peak a hair above 1 between the planning samples: slow down
        # by the exact factor (or the searched one when gravity acts).
        if problem.limit_set.time_scaling_is_exact:
            lam = np.sqrt(plan.check.worst_ratio)
            genes = problem.family.time_scaled(genes, lam * (1 + 1e-9))[0]
        else:
            genes = _slow_until_confirmed(problem, genes)
        plan = family_plan(problem, genes, "optimum")
    plan.planner_wall_s = time.perf_counter() - t_start
    plan.evaluations = problem.evaluations - n_eval0
    plan.extra = {"starts": int(starts), "polished": int(len(order)), "seed": seed,
                  "solver": "scipy Nelder-Mead on the time-scaled (tight) duration, "
                            "multi-start from a Latin hypercube"}
    return plan


def _slow_until_confirmed(problem, genes, step: float = 1e-6, tries: int = 60):
    """Play the motion 1e-6, 2e-6, 4e-6 ... slower until the refined re-check passes (no exact
    factor exists when gravity acts): timescale.search_scale on that table of factors, not bisected."""
    def slowed(lam):
        return problem.family.time_scaled(genes, lam)[0]
    if tries < 1:
        return genes
    found = search_scale(lambda lam: problem.confirm(slowed(lam)), steps=0,
                         grow=Grow(start=1.0, table=tuple(1.0 + step * 2**k for k in range(tries))))
    return genes if found.holding is None else slowed(found.holding)


def _settle_inside_bounds(problem, y):
    """Clip a tight motion into the gene bounds and slow it again if that broke a limit."""
    if not np.all(np.isfinite(y)):
        return None
    y = np.clip(y, problem.lower, problem.upper)
    for _ in range(3):
        p = problem.peaks(y[None])
        if p.feasible[0]:
            return y
        if not (p.valid[0] and p.joint_range_ok[0]):
            return None
        lam = tight_scale(problem, y[None])[0]
        if not np.isfinite(lam):
            return None
        y = np.clip(problem.family.time_scaled(y, lam * (1 + 1e-12))[0], problem.lower, problem.upper)
    return y if problem.peaks(y[None]).feasible[0] else None
