"""Searches over link lengths for each arm type (seed 003, sec. 3.1 and 4.2).

- `run_ga_adapter`: the ONE call into the project's GA (qmt_drake.planners.ga.run_ga on the Problem
  protocol, being generalised on main, issue 9) with the seed's settings: population 200, 30 mutants
  per generation, fitness-proportional selection with elitism, single-point crossover, 4 bits per
  gene (levels 0-15).
- `exhaustive`: every design of the type, as the certificate of the GA's answer. The seed quotes
  ~8.38 million combinations = 16^5 designs (L5 is always 0) x 8 unit tasks. Because L3 and L4 are
  collinear (arm_types), E depends on L3 + L4 only, so the 16^5 designs collapse to
  16 x 16 x 31 x 16 = 126,976 distinct arms, which are all evaluated.
- `run_all_types`: one search per type, all ten types in parallel worker processes.
"""

from __future__ import annotations

import dataclasses
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field

import numpy as np

from qmt_drake.config.scenario import GaSettings
from qmt_drake.design.arm_types import LEVEL_STEP_M, N_LEVELS, TYPES
from qmt_drake.design.problem import DesignProblem, hex_gene
from qmt_drake.design.tasks import Task
from qmt_drake.errors import QmtInputError
from qmt_drake.planners import ga

SEED_GA = dict(population=200, mutants_per_generation=30, bits_per_gene=4, elite_count=1,
               selection="roulette", encoding="binary", crossover_rate=1.0)


@dataclass
class SearchResult:
    type_name: str
    method: str
    genes: np.ndarray            # (5,) lengths in m
    gene_hex: str
    E_per_m: float
    evaluations: int             # designs evaluated
    unit_evaluations: int        # designs x unit tasks
    wall_s: float
    history_best_E: list = field(default_factory=list)   # per generation / per batch
    extra: dict = field(default_factory=dict)


def _ga_settings_class():
    """The project GA (planners/ga.py) and its settings class (config/sections.py)."""
    return ga, GaSettings


def run_ga_adapter(problem: DesignProblem, *, seed: int = 0, max_generations: int = 400,
                   stall_generations: int = 150, progress=None):
    """The single call into the project's GA. Returns its GaResult."""
    ga, Settings = _ga_settings_class()
    names = {f.name for f in dataclasses.fields(Settings)}
    settings = Settings(**{k: v for k, v in SEED_GA.items() if k in names},
                        max_generations=max_generations, stall_generations=stall_generations)
    return ga.run_ga(problem, settings, seed=seed, progress=progress)


def ga_search(problem: DesignProblem, seed: int = 0, **kw) -> SearchResult:
    t0 = time.perf_counter()
    res = run_ga_adapter(problem, seed=seed, **kw)
    E = float(-res.cost)
    hist = [-float(c) for c in res.history.best_cost] if hasattr(res.history, "best_cost") else []
    return SearchResult(problem.type.name, "ga", np.asarray(res.genes), hex_gene(res.genes), E,
                        int(res.evaluations), int(res.evaluations) * len(problem.task.units),
                        time.perf_counter() - t0, hist, {"generations": int(res.generations),
                                                         "stop_reason": str(res.stop_reason)})


def reduced_grid() -> np.ndarray:
    """All distinct arms as genes in m (126976, 5): L1, L2 in 0..15, S = L3 + L4 in 0..30 levels
    (L3 = min(S, 15), L4 = S - L3), L6 in 0..15."""
    a = np.arange(N_LEVELS)
    s = np.arange(2 * N_LEVELS - 1)
    L1, L2, S, L6 = np.meshgrid(a, a, s, a, indexing="ij")
    L3 = np.minimum(S, N_LEVELS - 1)
    lv = np.stack([L1, L2, L3, S - L3, L6], axis=-1).reshape(-1, 5)
    return lv * LEVEL_STEP_M


def exhaustive(problem: DesignProblem, *, genes: np.ndarray | None = None, batch: int = 2000,
               progress=None) -> SearchResult:
    """Evaluate every design of `genes` (default: the whole reduced grid)."""
    G = reduced_grid() if genes is None else np.atleast_2d(genes)
    t0 = time.perf_counter()
    E = np.empty(G.shape[0])
    u0 = problem.unit_evaluations
    hist = []
    for s in range(0, G.shape[0], batch):
        E[s:s + batch] = problem.fitness_E(G[s:s + batch])
        hist.append(float(E[:s + batch].max()))
        if progress:
            progress(f"{problem.type.name}: {min(s + batch, G.shape[0])}/{G.shape[0]} designs, best "
                     f"E {hist[-1]:.4f} 1/m, {time.perf_counter() - t0:.0f} s")
    i = int(np.argmax(E))
    top = np.argsort(-E)[:10]
    return SearchResult(problem.type.name, "exhaustive", G[i], hex_gene(G[i]), float(E[i]), G.shape[0],
                        problem.unit_evaluations - u0, time.perf_counter() - t0, hist,
                        {"top10": [(hex_gene(G[j]), float(E[j])) for j in top],
                         "ties_within_1e-12": int(np.sum(E >= E[i] - 1e-12))})


GA_GENERATIONS = (400, 100)  # (max, stall): the seed saw convergence by ~60, some types ~360


METHODS = ("auto", "ga", "exhaustive")


def search_type(task: Task, type_name: str, method: str = "ga", seed: int = 0,
                ga_generations: tuple = GA_GENERATIONS,
                relations: dict | None = None, branch: str = "task", restarts: int = 1) -> SearchResult:
    """One type's search: 'ga' (the project's GA; 'auto' is the same) or 'exhaustive'. branch:
    DesignProblem's branch choice ("task": one IK branch label for the whole task, the seed's;
    "point"). restarts: GA runs with seeds seed, seed + 1, ...; the best is returned (the seed
    ran one GA per type; one run can stall below the type's optimum, see README)."""
    pr = DesignProblem(task, type_name, relations, branch)
    if method in ("auto", "ga"):
        runs = [ga_search(pr, seed=seed + i, max_generations=ga_generations[0],
                          stall_generations=ga_generations[1]) for i in range(max(1, restarts))]
        best = max(runs, key=lambda r: r.E_per_m)
        if len(runs) > 1:   # the best run's history; every run's E and the total effort
            best.extra["restarts"] = [{"seed": seed + i, "gene": r.gene_hex, "E_per_m": r.E_per_m,
                                       "generations": r.extra.get("generations")}
                                      for i, r in enumerate(runs)]
            best.evaluations = sum(r.evaluations for r in runs)
            best.unit_evaluations = sum(r.unit_evaluations for r in runs)
            best.wall_s = sum(r.wall_s for r in runs)
        return best
    if method == "exhaustive":
        return exhaustive(pr)
    raise QmtInputError(f"search method {method!r}: use one of {', '.join(METHODS)}")


def _search_star(args):
    return search_type(*args)


def run_all_types(task: Task, *, method: str = "ga", workers: int = 2, seed: int = 0,
                  types=TYPES,
                  ga_generations: tuple = GA_GENERATIONS,
                  relations: dict | None = None,
                  branch: str = "task", restarts: int = 1, progress=None) -> tuple[list[SearchResult], float]:
    """Search every type (in `workers` processes; 1 = in this process). Returns the results in
    TYPES order and the wall time in s; `progress(line)` hears of each type as it finishes."""
    t0 = time.perf_counter()
    if method not in METHODS:
        raise QmtInputError(f"search method {method!r}: use one of {', '.join(METHODS)}")
    jobs = [(task, t, method, seed, ga_generations, relations, branch, restarts) for t in types]

    def done(r, k):
        if progress:
            progress(f"design {task.name}: {r.type_name} done ({k}/{len(jobs)} types), E {r.E_per_m:.4f} 1/m, "
                     f"{time.perf_counter() - t0:.0f} s")
        return r

    if workers <= 1:
        res = [done(_search_star(j), k + 1) for k, j in enumerate(jobs)]
    else:
        with ProcessPoolExecutor(max_workers=workers) as ex:
            futures = [ex.submit(_search_star, j) for j in jobs]
            for k, f in enumerate(as_completed(futures)):
                done(f.result(), k + 1)
            res = [f.result() for f in futures]
    return res, time.perf_counter() - t0
