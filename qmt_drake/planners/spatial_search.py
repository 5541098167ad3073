"""The family optimum and the GA on a spatial scenario, over any spatial family (planners/spatial_families).

- `plan_family_optimum(sc, family=...)`: the family's fastest member within the limits.
  * via_cubic: Nelder-Mead over the segment-time shares, each share vector at its tight time scale
    (`tight_time`; planners/spatial_tight.py), from `restarts` starts (shares ~ sqrt of the joint
    distance, equal shares).
  * line_cubic_velocity, trapezoid_ptp: the segments are rest to rest, so the optimum is each
    segment's own: per segment, its tight time (2 + r) k(r) over the cruise/accel ratio r = T2 / T1,
    on a grid of OPT_GRID ratios and then by bounded Brent around the best.
- `plan_ga_spatial(sc, family=...)`: the binary GA (planners/ga.run_ga) on the family's genes; with
  tight timing (default) every candidate is played at its tight time scale (SpatialFamilyProblem: the
  genes give the shape, the cost is the tight duration), else a candidate is feasible or not as its
  genes give it (the thesis's GA: it must find the feasibility boundary itself).

Both return a SpatialPlan held at the re-check rate (spatial_plan_io.finish_plan). The optimum's searches
are the one family-optimum search's (planners/family_optimum_core.py; this is its spatial adapter).
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from qmt_drake.config.scenario import GaSettings
from qmt_drake.errors import QmtInputError, QmtNoPlanError
from qmt_drake.limits.spatial_columns import joint_range_by_name
from qmt_drake.planners import family_optimum_core
from qmt_drake.planners.ga import check_checkpoint, run_ga
from qmt_drake.planners.spatial_families import spatial_family
from qmt_drake.planners.spatial_plan_io import SpatialPlan, finish_plan, make_spatial_plan
from qmt_drake.planners.spatial_tight import TIGHT_SAMPLES, tight_scales
from qmt_drake.planners.spatial_trajectory import TimeScaled, check, scale_to_hold
from qmt_drake.problem import Evaluation, MinimumTime

TIGHT_BATCH = 50  # candidates per tight_scales call
OPT_GRID = 41  # cruise/accel ratios tried per rest-to-rest segment before Brent
OPT_RATIO_MAX = 20.0
RANGE_PENALTY_S_PER_RAD = 100.0  # the via optimum's objective: seconds per radian outside a joint range
# the ranges the via optimum keeps, shrunk by this (rad): a penalty's optimum lies a hair outside its
# boundary (where the time it gains outweighs the penalty), so the boundary is drawn this much inside
RANGE_MARGIN_RAD = 1e-6
GA_RUN_LENGTH = (150, 60)  # the settings' (generations, stall) in a checkpoint's identity; the call's own are used


LEAST_VIOLATING_SCALE = 20.0  # scale_to_hold's k_max: slower than this, speed no longer matters


def _tight_or_refuse(sc, traj, samples: int) -> float:
    k = float(tight_scales(sc, [traj], samples)[0])
    if not np.isfinite(k):
        try:
            scale_to_hold(sc, traj, sc.check_rate_hz, k_max=12.0)  # raises naming the limit broken at rest
        except QmtNoPlanError:
            raise
        except QmtInputError as exc:
            raise QmtNoPlanError(f"no time scale makes the family's motion hold its limits: {exc}") from None
        raise QmtNoPlanError("no time scale makes the family's motion hold its limits; relax a limit")
    return k


def binding_clause(sc, traj) -> str:
    """'<limit column> at <ratio> of its limit at t = <s> s (<k>x slower: gravity alone there)': the
    binding limit of a trajectory no timing holds, from the re-check played LEAST_VIOLATING_SCALE
    times slower (where speed no longer matters, so what breaks there is the load at rest)."""
    c = check(sc, TimeScaled(traj, LEAST_VIOLATING_SCALE), sc.recheck_rate_hz)
    return (f"{c['binding']} at {c['max']:.4g} of its limit at t = {c['binding_time_s']:.4g} s even "
            f"{LEAST_VIOLATING_SCALE:g}x slower (speed no longer matters there: the load at rest breaks it)")


def finish_or_least_violating(sc, method: str, traj, pose_times, t0: float, info: dict) -> SpatialPlan:
    """spatial_plan_io.finish_plan (the trajectory held at the re-check rate), or, where no time scale
    up to LEAST_VIOLATING_SCALE holds it, the least-violating plan: the trajectory that many times
    slower (speed no longer matters there), re-checked and so not feasible, with
    info['least_violating'] naming the binding limit (the CLI writes it and exits 3)."""
    try:
        return finish_plan(sc, method, traj, pose_times, t0, info)
    except QmtInputError:
        pass
    k = LEAST_VIOLATING_SCALE
    why = binding_clause(sc, traj)
    return make_spatial_plan(sc, method, TimeScaled(traj, k), np.asarray(pose_times, float) * k,
                             planning_s=time.perf_counter() - t0, raw_duration_s=traj.duration_s, hold_scale=k,
                             info={**info, "least_violating": why})


def tight_time(sc, shares, samples: int = TIGHT_SAMPLES) -> tuple[float, np.ndarray]:
    """(T0, segment times) of the via cubic with these relative segment times at its tight time scale
    (planners/spatial_tight.py: in closed form on `samples` points, as the GA's candidates);
    QmtInputError naming the limit when no time scale makes it hold."""
    fam = spatial_family(sc, "via_cubic")
    w = np.abs(np.asarray(shares, float)) + 1e-6
    T = w / w.sum()
    k = _tight_or_refuse(sc, fam.trajectory(T), samples)
    return k, T * k


def range_excess_rad(pp, lower_rad, upper_rad) -> float:
    """How far (rad) a cubic PiecewisePolynomial q(t) leaves the joint ranges anywhere (0 inside): its
    values at the breaks and at every stationary point of every piece (the roots of its derivative, a
    quadratic fitted exactly through three of its values), so between samples too."""
    b = np.asarray(pp.get_segment_times(), float)
    t0, t1 = b[:-1], b[1:]
    d = pp.MakeDerivative(1)
    d0, dm, d1 = (d.vector_values(t).T for t in (t0, 0.5 * (t0 + t1), t1))  # (P, n) each; C1, so ends agree
    a2, a1, a0 = 2.0 * d1 + 2.0 * d0 - 4.0 * dm, 4.0 * dm - 3.0 * d0 - d1, d0  # d(u) = a2 u^2 + a1 u + a0
    with np.errstate(invalid="ignore", divide="ignore"):
        disc = np.sqrt(np.where(a1 * a1 - 4.0 * a2 * a0 >= 0.0, a1 * a1 - 4.0 * a2 * a0, np.nan))
        quad = np.abs(a2) > 1e-12 * (np.abs(a1) + np.abs(a0) + 1e-300)
        roots = [np.where(quad, (-a1 + disc) / (2.0 * a2), -a0 / a1), np.where(quad, (-a1 - disc) / (2.0 * a2), np.nan)]
    h = (t1 - t0)[:, None]
    excess = 0.0
    for u in roots:  # per piece and joint: evaluate joint j at t0 + u h where 0 < u < 1
        ok = np.isfinite(u) & (u > 0.0) & (u < 1.0)
        for i, j in zip(*np.nonzero(ok)):
            v = pp.value(t0[i] + u[i, j] * h[i, 0])[j, 0]
            excess = max(excess, v - upper_rad[j], lower_rad[j] - v)
    q = pp.vector_values(b).T
    return float(max(excess, np.max(q - upper_rad), np.max(lower_rad - q), 0.0))


def _via_optimum(sc, restarts: int):
    """Nelder-Mead over the shares of the tight duration plus RANGE_PENALTY_S_PER_RAD times how far the
    cubic leaves a joint range shrunk by RANGE_MARGIN_RAD (range_excess_rad: the timing does not move the
    path, the shares do), so a cubic inside the ranges is found where one exists; inside them the
    objective is the tight duration alone."""
    m = len(sc.q_poses_rad) - 1
    d = np.linalg.norm(np.diff(sc.q_poses_rad, axis=0), ord=np.inf, axis=1)
    starts = [np.sqrt(d), np.ones(m)][:restarts]
    lower, upper = joint_range_by_name(sc.plant, sc.joint_names)
    lower, upper = lower + RANGE_MARGIN_RAD, upper - RANGE_MARGIN_RAD
    fam = spatial_family(sc, "via_cubic")

    def objective(x):
        w = np.abs(np.asarray(x, float)) + 1e-6  # the shares as tight_time takes them
        excess = range_excess_rad(fam.trajectory(w / w.sum()).pp, lower, upper)
        return tight_time(sc, x)[0] + RANGE_PENALTY_S_PER_RAD * excess if excess > 0.0 else tight_time(sc, x)[0]

    _, best = family_optimum_core.minimise(objective, [x0 / x0.sum() for x0 in starts],
                                           options={"xatol": 1e-5, "fatol": 1e-7, "maxiter": 600})
    return tight_time(sc, best.x)[1], int(best.nfev)


def _segment_optimum(sc, fam, i: int) -> tuple[np.ndarray, int]:
    """(T1, T2) of segment i's fastest member at its tight scale, and the evaluations it took."""
    def times(ratios):  # tight durations of shapes (1, r)
        trajs = [fam.segment_trajectory(i, 1.0, r) for r in ratios]
        return np.array([(2.0 + r) * k for r, k in zip(ratios, tight_scales(sc, trajs))])

    grid = np.r_[0.0, np.geomspace(0.01, OPT_RATIO_MAX, OPT_GRID - 1)]
    T = times(grid)
    if not np.isfinite(T).any():
        _tight_or_refuse(sc, fam.segment_trajectory(i, 1.0, 0.0), TIGHT_SAMPLES)
    ratio, best, evaluations = family_optimum_core.grid_then_brent(times, grid, T, xatol=1e-6)
    k = best / (2.0 + ratio)
    return np.array([k, k * ratio]), evaluations


def plan_family_optimum(sc, *, restarts: int = 1, family: str = "via_cubic") -> SpatialPlan:
    """The family's fastest member within the limits (module docstring)."""
    t0 = time.perf_counter()
    fam = spatial_family(sc, family)
    if family == "via_cubic":
        genes, evaluations = _via_optimum(sc, restarts)
    else:
        parts = [_segment_optimum(sc, fam, i) for i in range(fam.n_segments)]
        genes, evaluations = np.concatenate([p[0] for p in parts]), sum(p[1] for p in parts)
    return finish_or_least_violating(sc, "family_optimum", fam.trajectory(genes), fam.pose_times(genes), t0,
                       {"family": family, **fam.facts, "genes": dict(zip(fam.gene_names, genes)),
                        **_segment_times(fam, genes), "evaluations": evaluations})


def _segment_times(fam, genes) -> dict:
    """info['segment_times_s']: the time between neighbouring task poses (s)."""
    return {"segment_times_s": fam.segment_times(genes)}


class SpatialFamilyProblem:
    """A spatial family as a GA Problem (problem.py protocol), a candidate feasible or not as its genes give it."""

    def __init__(self, sc, family: str = "via_cubic", *, fitness_c_per_s: float = 1.0) -> None:
        self.sc = sc
        self.family = spatial_family(sc, family)
        self.name = f"{sc.name} {family.replace('_', '-')}"
        self.gene_names = self.family.gene_names
        self.lower, self.upper = self.family.lower, self.family.upper
        self.objective = MinimumTime(fitness_c_per_s)

    def evaluate(self, genes, exact: bool = False) -> Evaluation:
        G = np.atleast_2d(np.asarray(genes, float))
        viol = np.array([max(check(self.sc, self.family.trajectory(g), self.sc.check_rate_hz)["max"] - 1.0, 0.0)
                         for g in G])
        return Evaluation(cost=self.family.duration_s(G), violation=viol)

    def fitness(self, ev: Evaluation) -> np.ndarray:
        return self.objective.fitness(ev)

    def realize(self, genes) -> np.ndarray:
        return np.asarray(genes, float)

    def confirm(self, genes) -> bool:
        return check(self.sc, self.family.trajectory(genes), self.sc.recheck_rate_hz)["max"] <= 1.0

    def fingerprint(self) -> str:
        data = np.r_[self.sc.q_poses_rad.ravel(), self.lower, self.upper]
        kind = "" if self.family.kind == "via_cubic" else self.family.kind  # via-cubic prints as before
        return hashlib.sha256(data.tobytes() + self.sc.name.encode() + kind.encode()).hexdigest()[:16]


class SpatialTightFamilyProblem(SpatialFamilyProblem):
    """The family with every candidate played at its tight time scale (planners/spatial_tight.py, as the
    planar GA's ga.tight_timing): the genes give the shape, the cost is the tight duration k * T(genes),
    so the GA searches shapes and never the feasibility boundary."""

    def __init__(self, sc, family: str = "via_cubic", *, samples: int = TIGHT_SAMPLES, **kwargs) -> None:
        super().__init__(sc, family, **kwargs)
        self.samples = samples
        self.name += " (tight timing)"

    def scales(self, G) -> np.ndarray:
        # in batches: each trajectory's scale is its own (the same to the bit in any batch), and one batch of
        # a whole population held ~4 MB a candidate (16 GiB at 4000); batches of 50 are also faster (cache)
        G = np.atleast_2d(G)
        trajs = [self.family.trajectory(g) for g in G]
        return np.concatenate([tight_scales(self.sc, trajs[i:i + TIGHT_BATCH], self.samples)
                               for i in range(0, len(G), TIGHT_BATCH)] or [np.zeros(0)])

    def evaluate(self, genes, exact: bool = False) -> Evaluation:
        G = np.atleast_2d(np.asarray(genes, float))
        k = self.scales(G)
        ok = np.isfinite(k)
        return Evaluation(cost=np.where(ok, k * self.family.duration_s(G), np.inf), violation=np.where(ok, 0.0, np.inf))

    def realize(self, genes) -> np.ndarray:
        """The genes (s) of the tight motion of `genes` (every time gene times the scale)."""
        g = np.asarray(genes, float)
        return g * self.scales(g)[0]

    def confirm(self, genes) -> bool:  # the plan is held at the re-check rate by finish_plan's scale_to_hold
        return bool(np.isfinite(self.scales(genes)[0]))

    def fingerprint(self) -> str:
        return super().fingerprint() + f":tight{self.samples}"


def SpatialViaProblem(sc, **kwargs) -> SpatialFamilyProblem:  # noqa: N802 - the via-cubic problem's old name
    return SpatialFamilyProblem(sc, "via_cubic", **kwargs)


def SpatialTightViaProblem(sc, **kwargs) -> SpatialTightFamilyProblem:  # noqa: N802 - its old name
    return SpatialTightFamilyProblem(sc, "via_cubic", **kwargs)


def _ga_run(sc, generations: int, population: int, stall: int, tight_timing: bool, family: str):
    """(problem, settings) of a spatial GA run: what plan_ga_spatial runs and a checkpoint must match.
    How long it may run (generations, stall) is not part of the run, as on the planar arms (run_ga takes
    them apart): a run stopped by Ctrl-C resumes with more generations."""
    problem = (SpatialTightFamilyProblem if tight_timing else SpatialFamilyProblem)(sc, family)
    settings = GaSettings(population=population, max_generations=GA_RUN_LENGTH[0], stall_generations=GA_RUN_LENGTH[1],
                          fitness_c_per_s=1.0, selection="tournament", encoding="gray", tight_timing=tight_timing)
    return problem, settings


def check_ga_checkpoint(sc, path, *, seed: int = 0, generations: int = 150, population: int = 40, stall: int = 60,
                        tight_timing: bool = True, family: str = "via_cubic", **_other) -> None:
    """One line (ga.check_checkpoint) unless `path` is absent or a checkpoint of this very spatial GA
    run (same scenario data, family, GA settings and seed); before any work."""
    problem, settings = _ga_run(sc, generations, population, stall, tight_timing, family)
    check_checkpoint(path, problem.fingerprint(), settings, seed)


def plan_ga_spatial(sc, *, seed: int = 0, generations: int = 150, population: int = 40, stall: int = 60,
                    tight_timing: bool = True, family: str = "via_cubic", progress=None,
                    checkpoint_path: str | None = None, checkpoint_every: int = 500,
                    progress_every_s: float = 2.0) -> SpatialPlan:
    """The binary GA (planners/ga.run_ga) on the family's genes (module docstring). checkpoint_path:
    the run's state written there every `checkpoint_every` generations and on Ctrl-C, and resumed from
    by the same call (ga.run_ga: the same plan as an uninterrupted run). When no candidate held the
    limits, the least-violating plan: the GA's best genes played LEAST_VIOLATING_SCALE times slower
    (tight timing: no time scale held them) or as they are, not feasible, info['least_violating']
    naming the binding limit."""
    t0 = time.perf_counter()
    problem, settings = _ga_run(sc, generations, population, stall, tight_timing, family)
    res = run_ga(problem, settings, seed=seed, max_generations=generations, stall_generations=stall, progress=progress,
                 progress_every_s=progress_every_s, checkpoint_path=checkpoint_path, checkpoint_every=checkpoint_every)
    fam = problem.family
    if not res.feasible:  # the least-violating plan, as the planar GA's (plan.feasible False, exit 3)
        genes = np.asarray(res.genes, float)
        traj = fam.trajectory(genes)
        why = (f"the GA found no {family} motion within the limits in {res.generations} generations: "
               f"{binding_clause(sc, traj)}; relax that limit or move the task poses")
        info = {"family": family, **fam.facts, "genes": dict(zip(fam.gene_names, genes)), **_segment_times(fam, genes),
                "generations": res.generations, "evaluations": res.evaluations, "seed": seed,
                "tight_timing": tight_timing}
        if progress:
            progress(f"qmt-drake: {why}")
        if tight_timing:
            return finish_or_least_violating(sc, "ga", traj, fam.pose_times(genes), t0, info)
        return make_spatial_plan(sc, "ga", traj, fam.pose_times(genes), planning_s=time.perf_counter() - t0,
                                 raw_duration_s=traj.duration_s, hold_scale=1.0, info={**info, "least_violating": why})
    genes = problem.realize(res.genes)
    return finish_plan(sc, "ga", fam.trajectory(genes), fam.pose_times(genes), t0,
                       {"family": family, **fam.facts, "genes": dict(zip(fam.gene_names, genes)),
                        **_segment_times(fam, genes), "generations": res.generations,
                        "evaluations": res.evaluations, "seed": seed, "tight_timing": tight_timing})
