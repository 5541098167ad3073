"""The binary genetic algorithm of seed 000 (Fig. 2.9, 3.8, 4.7), with elitism, a seeded generator,
a stall stop, a per-generation history, progress and resumable checkpoints.

Thesis settings (Table 2.4, 3.3, 4.3): 12 bits per gene, 50 individuals, crossover ratio 0.5
(probability that a pair exchanges tails at one random cut), mutation ratio 0.05 (per bit), up to
10,000 generations, fitness exp(-c*T0) when every limit holds and 0 otherwise (eq. 2-36), parents
drawn fitness-proportionally (roulette). Additions: `elite_count` best individuals pass unchanged
(0 gives the plain GA), `stall_generations` stops a run whose best has not improved.

Fitness values of chromosomes already seen are cached, so a converged population costs little.
The best plan is re-checked at the scenario's check rate (10 kHz); if it fails there, the next
best feasible chromosome seen is taken, so the GA never returns a plan that breaks a limit.
"""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from qmt_drake.problem import PlanningProblem
from qmt_drake.scenario import GaSettings


@dataclass
class GaHistory:
    """One row per generation (after evaluating it)."""

    best_motion_time_s: list = field(default_factory=list)  # best feasible so far (nan: none)
    best_fitness: list = field(default_factory=list)
    mean_fitness: list = field(default_factory=list)
    feasible_fraction: list = field(default_factory=list)
    wall_s: list = field(default_factory=list)  # time since the run started

    def append(self, best_T0, best_fit, fit, wall_s=float("nan")):
        self.best_motion_time_s.append(float(best_T0))
        self.best_fitness.append(float(best_fit))
        self.mean_fitness.append(float(np.mean(fit)))
        self.feasible_fraction.append(float(np.mean(fit > 0)))
        self.wall_s.append(float(wall_s))


@dataclass
class GaResult:
    genes: np.ndarray
    motion_time_s: float
    feasible: bool
    generations: int
    evaluations: int  # distinct chromosomes evaluated
    wall_s: float
    stop_reason: str
    history: GaHistory
    least_violating_genes: np.ndarray | None = None


class BinaryGa:
    """Decode/encode and the genetic operators for one problem and settings."""

    def __init__(self, problem: PlanningProblem, settings: GaSettings) -> None:
        self.problem = problem
        self.s = settings
        self.n_genes = len(problem.gene_names)
        self.bits = settings.bits_per_gene
        self.levels = 2**self.bits - 1
        self._weights = (1 << np.arange(self.bits - 1, -1, -1)).astype(np.int64)

    def codes(self, pop: np.ndarray) -> np.ndarray:
        """Integer level of each gene, (P, G)."""
        bits = pop.reshape(pop.shape[0], self.n_genes, self.bits)
        if self.s.encoding == "gray":  # binary bit i = XOR of Gray bits 0..i
            bits = np.bitwise_xor.accumulate(bits, axis=2)
        return bits @ self._weights

    def decode(self, pop: np.ndarray) -> np.ndarray:
        lo, hi = self.problem.lower, self.problem.upper
        return lo + (hi - lo) * self.codes(pop) / self.levels

    def keys(self, pop: np.ndarray) -> np.ndarray:
        """One integer per chromosome (the levels packed), for the fitness cache."""
        c = self.codes(pop)
        key = np.zeros(pop.shape[0], dtype=np.int64)
        for g in range(self.n_genes):
            key = (key << self.bits) | c[:, g]
        return key

    def select(self, fitness: np.ndarray, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.s.selection == "tournament":
            a, b = rng.integers(0, fitness.size, (2, n))
            return np.where(fitness[a] >= fitness[b], a, b)
        total = fitness.sum()
        if total <= 0:
            return rng.integers(0, fitness.size, n)
        return rng.choice(fitness.size, size=n, p=fitness / total)

    def crossover(self, parents: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        kids = parents.copy()
        n_pairs = kids.shape[0] // 2
        a, b = kids[0:2 * n_pairs:2], kids[1:2 * n_pairs:2]
        do = rng.random(n_pairs) < self.s.crossover_rate
        cut = rng.integers(1, kids.shape[1], n_pairs)
        mask = (np.arange(kids.shape[1])[None, :] >= cut[:, None]) & do[:, None]
        a_new = np.where(mask, b, a)
        b_new = np.where(mask, a, b)
        kids[0:2 * n_pairs:2], kids[1:2 * n_pairs:2] = a_new, b_new
        return kids

    def mutate(self, pop: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        flip = rng.random(pop.shape) < self.s.mutation_rate
        return pop ^ flip.astype(np.uint8)


def run_ga(problem: PlanningProblem, settings: GaSettings | None = None, *, seed: int = 0,
           max_generations: int | None = None, stall_generations: int | None = None,
           progress: Callable[[str], None] | None = None, progress_every_s: float = 2.0,
           checkpoint_path: str | Path | None = None, checkpoint_every: int = 500) -> GaResult:
    """Run the GA on `problem`. With `checkpoint_path`, state is written atomically every
    `checkpoint_every` generations and a later call with the same path resumes from it."""
    s = settings or problem.scenario.ga
    max_gen = int(max_generations if max_generations is not None else s.max_generations)
    stall = int(stall_generations if stall_generations is not None else s.stall_generations)
    ga = BinaryGa(problem, s)
    rng = np.random.default_rng(seed)
    P, nbits = s.population, ga.n_genes * ga.bits
    c = s.fitness_c_per_s
    cache: dict[int, tuple[float, float]] = {}  # key -> (fitness, worst ratio)
    history = GaHistory()
    pop = rng.integers(0, 2, size=(P, nbits), dtype=np.uint8)
    best_key, best_T0, best_gen = None, np.inf, 0
    start_gen = 0
    t_start = time.perf_counter()
    wall_before = 0.0
    ckpt = Path(checkpoint_path) if checkpoint_path else None
    state = _load_checkpoint(ckpt, problem, seed) if ckpt and ckpt.is_file() else None
    if state:
        pop, start_gen, history = state["pop"], state["generation"], state["history"]
        rng.bit_generator.state = state["rng"]
        cache = state["cache"]
        best_key, best_T0, best_gen = state["best_key"], state["best_T0"], state["best_gen"]
        wall_before = state["wall_s"]
        if progress:
            progress(f"resuming {problem.scenario.name} seed {seed} at generation {start_gen}")
    last_print = time.perf_counter()
    stop_reason = "max_generations"
    gen = start_gen
    while gen < max_gen:
        keys = ga.keys(pop)
        new = np.array([k not in cache for k in keys.tolist()])
        if new.any():
            new_keys, first = np.unique(keys[new], return_index=True)
            genes = ga.decode(pop[new][first])
            peaks = problem.evaluate(genes)
            fit = np.where(peaks.feasible, np.exp(-c * peaks.motion_time_s), 0.0)
            for k, f, w in zip(new_keys.tolist(), fit.tolist(), peaks.worst_ratio.tolist()):
                cache[k] = (f, w)
        fitness = np.array([cache[k][0] for k in keys.tolist()])
        i_best = int(np.argmax(fitness))
        if fitness[i_best] > 0:
            T0 = -np.log(fitness[i_best]) / c
            if T0 < best_T0 - 1e-12:
                best_T0, best_key, best_gen = T0, int(keys[i_best]), gen
        history.append(best_T0 if np.isfinite(best_T0) else np.nan,
                       np.exp(-c * best_T0) if np.isfinite(best_T0) else 0.0, fitness,
                       time.perf_counter() - t_start + wall_before)
        gen += 1
        if stall and gen - best_gen >= stall and np.isfinite(best_T0):
            stop_reason = f"best unchanged for {stall} generations"
            break
        # Next generation: elites, then roulette parents -> crossover -> mutation.
        order = np.argsort(-fitness, kind="stable")
        elites = pop[order[:s.elite_count]]
        parents = pop[ga.select(fitness, rng, P)]
        kids = ga.mutate(ga.crossover(parents, rng), rng)
        pop = np.concatenate([elites, kids[:P - s.elite_count]]) if s.elite_count else kids
        now = time.perf_counter()
        if progress and now - last_print >= progress_every_s:
            last_print = now
            progress(f"{problem.scenario.name} seed {seed}: generation {gen}/{max_gen}, best T0 "
                     f"{best_T0:.4f} s, feasible {np.mean(fitness > 0):.0%}, "
                     f"{len(cache)} evaluated, {now - t_start + wall_before:.1f} s")
        if ckpt and gen % checkpoint_every == 0:
            _save_checkpoint(ckpt, problem, seed, pop, gen, rng, history, cache, best_key,
                             best_T0, best_gen, time.perf_counter() - t_start + wall_before)

    wall = time.perf_counter() - t_start + wall_before
    chosen = _best_passing_recheck(problem, ga, cache, c)
    least = None
    if chosen is None:
        least = _least_violating(problem, ga, cache)
    if ckpt and ckpt.is_file():
        ckpt.unlink()  # the run finished; its result is what the caller writes out
    genes = chosen if chosen is not None else least
    T0 = float(problem.family.motion_time_s(genes[None])[0])
    return GaResult(genes=genes, motion_time_s=T0, feasible=chosen is not None, generations=gen,
                    evaluations=len(cache), wall_s=wall, stop_reason=stop_reason,
                    history=history, least_violating_genes=least)


def _key_to_genes(ga: BinaryGa, key: int) -> np.ndarray:
    codes = [(key >> (ga.bits * (ga.n_genes - 1 - g))) & ga.levels for g in range(ga.n_genes)]
    lo, hi = ga.problem.lower, ga.problem.upper
    return lo + (hi - lo) * np.array(codes) / ga.levels


def _least_violating(problem, ga, cache, batch: int = 64) -> np.ndarray:
    """Chromosome with the smallest worst ratio on the full grid among all evaluated.

    The cache holds lower bounds for infeasible candidates (the fast evaluator stops at the
    first coarse violation), so candidates are re-evaluated exactly in order of their bound
    until no remaining bound can beat the best exact value."""
    order = sorted(cache, key=lambda k: cache[k][1])
    best_key, best = order[0], np.inf
    for i in range(0, len(order), batch):
        keys = order[i:i + batch]
        if cache[keys[0]][1] >= best:
            break
        genes = np.array([_key_to_genes(ga, k) for k in keys])
        worst = problem.evaluate(genes, exact=True).worst_ratio
        j = int(np.argmin(worst))
        if worst[j] < best:
            best, best_key = float(worst[j]), keys[j]
    return _key_to_genes(ga, best_key)


def _best_passing_recheck(problem, ga, cache, c, tries: int = 50):
    feasible = sorted((-np.log(f) / c, k) for k, (f, _) in cache.items() if f > 0)
    for _, k in feasible[:tries]:
        genes = _key_to_genes(ga, k)
        if problem.report(genes).feasible:
            return genes
    return None


def _save_checkpoint(path: Path, problem, seed, pop, gen, rng, history, cache, best_key, best_T0,
                     best_gen, wall_s) -> None:
    state = dict(scenario=problem.scenario.name, seed=seed, generation=gen, pop=pop.tolist(),
                 rng=rng.bit_generator.state, history=history.__dict__,
                 cache=[[k, f, w] for k, (f, w) in cache.items()], best_key=best_key,
                 best_T0=best_T0 if np.isfinite(best_T0) else None, best_gen=best_gen,
                 wall_s=wall_s)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(state))
    os.replace(tmp, path)


def _load_checkpoint(path: Path, problem, seed) -> dict | None:
    state = json.loads(path.read_text())
    if state["scenario"] != problem.scenario.name or state["seed"] != seed:
        print(f"warning: checkpoint {path} is for {state['scenario']} seed {state['seed']}; "
              "starting afresh", file=sys.stderr)
        path.unlink()
        return None
    hist = GaHistory(**state["history"])
    return dict(pop=np.array(state["pop"], dtype=np.uint8), generation=state["generation"],
                rng=state["rng"], history=hist,
                cache={int(k): (float(f), float(w)) for k, f, w in state["cache"]},
                best_key=state["best_key"],
                best_T0=np.inf if state["best_T0"] is None else state["best_T0"],
                best_gen=state["best_gen"], wall_s=state["wall_s"])
