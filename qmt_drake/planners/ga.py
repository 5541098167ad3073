"""The binary genetic algorithm of seed 000 (Fig. 2.9, 3.8, 4.7) on any Problem (problem.py), with
elitism, a seeded generator, a stall stop, a per-generation history, progress and resumable
checkpoints.

Thesis settings (Table 2.4, 3.3, 4.3): 12 bits per gene, 50 individuals, crossover ratio 0.5
(probability that a pair exchanges tails at one random cut), mutation ratio 0.05 (per bit), up to
10,000 generations, fitness exp(-c*T0) when every limit holds and 0 otherwise (eq. 2-36; the
problem's `fitness`), parents drawn fitness-proportionally (roulette). Additions: `elite_count`
best individuals pass unchanged (0 gives the plain GA), `stall_generations` stops a run whose best
has not improved, `mutants_per_generation` (seed 003: that many individuals get one random bit
flipped per generation, instead of the per-bit rate).

Chromosomes of any length are keyed by their packed bits (bytes), so any number of genes and bits
works; fitness values of chromosomes already seen are cached, so a converged population costs
little. The best chromosome is confirmed by the problem's own final check (`Problem.confirm`; for
transfer planning the 10 kHz re-check with refined peaks); if it fails there, the next best
feasible chromosome seen is taken, so the GA never returns a plan that breaks a limit.

A checkpoint (written atomically every `checkpoint_every` generations, and on Ctrl-C) carries the
problem's fingerprint, the settings and the seed: it resumes only the same run; any other
checkpoint at that path is refused with one line.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from qmt_drake.config.scenario import GaSettings
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import write_text_atomic


@dataclass
class GaHistory:
    """One row per generation (after evaluating it)."""

    best_cost: list = field(default_factory=list)  # best feasible cost so far (nan: none)
    best_fitness: list = field(default_factory=list)
    mean_fitness: list = field(default_factory=list)
    feasible_fraction: list = field(default_factory=list)
    wall_s: list = field(default_factory=list)  # time since the run started

    def append(self, best_cost, best_fit, fit, wall_s=float("nan")):
        self.best_cost.append(float(best_cost))
        self.best_fitness.append(float(best_fit))
        self.mean_fitness.append(float(np.mean(fit)))
        self.feasible_fraction.append(float(np.mean(fit > 0)))
        self.wall_s.append(float(wall_s))


@dataclass
class GaResult:
    genes: np.ndarray
    cost: float  # the problem's cost of `genes` (motion time [s] for transfer planning)
    feasible: bool
    generations: int
    evaluations: int  # distinct chromosomes evaluated
    wall_s: float
    stop_reason: str
    history: GaHistory
    least_violating_genes: np.ndarray | None = None


class BinaryGa:
    """Decode/encode and the genetic operators for one problem and settings."""

    def __init__(self, problem, settings: GaSettings) -> None:
        self.problem = problem
        self.s = settings
        self.n_genes = len(problem.gene_names)
        self.bits = int(settings.bits_per_gene)
        self.n_bits = self.n_genes * self.bits
        self.levels = 2**self.bits - 1
        # Levels up to 2^62 fit int64 exactly; decode divides in float64 (exact below 2^53).
        self._weights = 2 ** np.arange(self.bits - 1, -1, -1, dtype=np.int64)

    def codes(self, pop: np.ndarray) -> np.ndarray:
        """Integer level of each gene, (P, G)."""
        bits = pop.reshape(pop.shape[0], self.n_genes, self.bits).astype(np.int64)
        if self.s.encoding == "gray":  # binary bit i = XOR of Gray bits 0..i
            bits = np.bitwise_xor.accumulate(bits, axis=2)
        return bits @ self._weights

    def decode(self, pop: np.ndarray) -> np.ndarray:
        lo, hi = self.problem.lower, self.problem.upper
        return lo + (hi - lo) * (self.codes(pop) / self.levels)

    def keys(self, pop: np.ndarray) -> list:
        """One bytes key per chromosome (its bits packed): exact for any length."""
        packed = np.packbits(pop, axis=1)
        return [row.tobytes() for row in packed]

    def chromosome(self, key: bytes) -> np.ndarray:
        """The bits (n_bits,) of a key (inverse of `keys`)."""
        return np.unpackbits(np.frombuffer(key, dtype=np.uint8))[:self.n_bits]

    def genes_of_keys(self, keys) -> np.ndarray:
        return self.decode(np.array([self.chromosome(k) for k in keys], dtype=np.uint8))

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
        m = int(getattr(self.s, "mutants_per_generation", 0) or 0)
        if m > 0:  # seed 003: m individuals, one random bit each
            out = pop.copy()
            who = rng.choice(pop.shape[0], size=min(m, pop.shape[0]), replace=False)
            bit = rng.integers(0, pop.shape[1], who.size)
            out[who, bit] ^= 1
            return out
        flip = rng.random(pop.shape) < self.s.mutation_rate
        return pop ^ flip.astype(np.uint8)


class GaInterrupted(KeyboardInterrupt):
    """Ctrl-C during a GA run; the message says where the run stopped and where its checkpoint is."""


def run_ga(problem, settings: GaSettings | None = None, *, seed: int = 0,
           max_generations: int | None = None, stall_generations: int | None = None,
           progress: Callable[[str], None] | None = None, progress_every_s: float = 2.0,
           checkpoint_path: str | Path | None = None, checkpoint_every: int = 500) -> GaResult:
    """Run the GA on `problem` (the Problem protocol of problem.py). With `checkpoint_path`, state
    is written atomically every `checkpoint_every` generations and on KeyboardInterrupt, and a
    later call with the same path, problem, settings and seed resumes from it."""
    s = settings or problem.scenario.ga
    max_gen = int(max_generations if max_generations is not None else s.max_generations)
    stall = int(stall_generations if stall_generations is not None else s.stall_generations)
    if max_gen < 1:
        raise QmtInputError(f"the GA needs at least one generation, got max_generations={max_gen}")
    if not (isinstance(seed, (int, np.integer)) and seed >= 0):
        raise QmtInputError(f"the GA seed must be a non-negative integer, got {seed!r}")
    ga = BinaryGa(problem, s)
    rng = np.random.default_rng(seed)
    P = s.population
    cache: dict[bytes, tuple[float, float, float]] = {}  # key -> (fitness, cost, violation)
    history = GaHistory()
    pop = rng.integers(0, 2, size=(P, ga.n_bits), dtype=np.uint8)
    best_key, best_cost, best_gen = None, np.inf, 0
    start_gen = 0
    t_start = time.perf_counter()
    wall_before = 0.0
    ckpt = Path(checkpoint_path) if checkpoint_path else None
    run_id = _run_fingerprint(problem.fingerprint(), s, seed)
    state = _load_checkpoint(ckpt, run_id) if ckpt and ckpt.is_file() else None
    if state:
        pop, start_gen, history = state["pop"], state["generation"], state["history"]
        rng.bit_generator.state = state["rng"]
        cache = state["cache"]
        best_key, best_cost, best_gen = state["best_key"], state["best_cost"], state["best_gen"]
        wall_before = state["wall_s"]
        if progress:
            progress(f"resuming {problem.name} seed {seed} at generation {start_gen}")
    last_print = time.perf_counter()
    stop_reason = "max_generations"
    gen = start_gen

    def save():
        _save_checkpoint(ckpt, run_id, pop, gen, rng, history, cache, best_key, best_cost, best_gen,
                         time.perf_counter() - t_start + wall_before)

    try:
        while gen < max_gen:
            keys = ga.keys(pop)
            new = sorted({k for k in keys if k not in cache})
            if new:
                ev = problem.evaluate(ga.genes_of_keys(new))
                fit = problem.fitness(ev)
                for k, f, c, v in zip(new, fit.tolist(), ev.cost.tolist(), ev.violation.tolist()):
                    cache[k] = (f, c, v)
            fitness = np.array([cache[k][0] for k in keys])
            i_best = int(np.argmax(fitness))
            if fitness[i_best] > 0 and cache[keys[i_best]][1] < best_cost - 1e-12:
                best_cost, best_key, best_gen = cache[keys[i_best]][1], keys[i_best], gen
            history.append(best_cost if np.isfinite(best_cost) else np.nan,
                           cache[best_key][0] if best_key is not None else 0.0, fitness,
                           time.perf_counter() - t_start + wall_before)
            gen += 1
            if stall and gen - best_gen >= stall and np.isfinite(best_cost):
                stop_reason = f"best unchanged for {stall} generations"
                if progress:
                    progress(f"{problem.name} seed {seed}: stopped at generation {gen} of at most {max_gen}: "
                             f"{stop_reason}, best cost {best_cost:.4f}")
                break
            # Next generation: elites, then parents -> crossover -> mutation.
            order = np.argsort(-fitness, kind="stable")
            elites = pop[order[:s.elite_count]]
            parents = pop[ga.select(fitness, rng, P)]
            kids = ga.mutate(ga.crossover(parents, rng), rng)
            pop = np.concatenate([elites, kids[:P - s.elite_count]]) if s.elite_count else kids
            now = time.perf_counter()
            if progress and now - last_print >= progress_every_s:
                last_print = now
                stall_note = f" (stops after {stall} without improvement, now {gen - best_gen})" if stall else ""
                progress(f"{problem.name} seed {seed}: generation {gen} of at most {max_gen}{stall_note}, best cost "
                         f"{best_cost:.4f}, feasible {np.mean(fitness > 0):.0%}, "
                         f"{len(cache)} evaluated, {now - t_start + wall_before:.1f} s")
            if ckpt and gen % checkpoint_every == 0:
                save()
    except KeyboardInterrupt:
        if ckpt:
            save()
            raise GaInterrupted(f"at generation {gen}; checkpoint written to {ckpt}: run the same command "
                                "with the same --checkpoint to resume") from None
        raise GaInterrupted(f"at generation {gen}; no checkpoint was kept (give --checkpoint PATH to "
                            "make a long run resumable)") from None

    wall = time.perf_counter() - t_start + wall_before
    chosen = _best_confirmed(problem, ga, cache)
    least = None
    if chosen is None:
        least = _least_violating(problem, ga, cache)
    if ckpt and ckpt.is_file():
        ckpt.unlink()  # the run finished; its result is what the caller writes out
    genes = chosen if chosen is not None else least
    cost = float(problem.evaluate(genes[None], exact=True).cost[0])
    return GaResult(genes=genes, cost=cost, feasible=chosen is not None, generations=gen,
                    evaluations=len(cache), wall_s=wall, stop_reason=stop_reason,
                    history=history, least_violating_genes=least)


def _least_violating(problem, ga, cache, batch: int = 64) -> np.ndarray:
    """Chromosome with the smallest exact violation among all evaluated.

    The cache may hold lower bounds for infeasible candidates (a fast evaluator stops at the
    first violation found), so candidates are re-evaluated exactly in order of their bound
    until no remaining bound can beat the best exact value."""
    order = sorted(cache, key=lambda k: cache[k][2])
    best_key, best = order[0], np.inf
    for i in range(0, len(order), batch):
        keys = order[i:i + batch]
        if cache[keys[0]][2] >= best:
            break
        v = problem.evaluate(ga.genes_of_keys(keys), exact=True).violation
        j = int(np.argmin(v))
        if v[j] < best:
            best, best_key = float(v[j]), keys[j]
    return ga.genes_of_keys([best_key])[0]


def _best_confirmed(problem, ga, cache, tries: int = 50):
    """The cheapest feasible chromosome that passes the problem's final check. Equal costs are
    ordered by their gene levels (not by their bits), so the choice does not depend on the coding."""
    keys = [k for k, (f, _, _) in cache.items() if f > 0]
    if not keys:
        return None
    levels = ga.codes(np.array([ga.chromosome(k) for k in keys], dtype=np.uint8))
    cost = np.array([cache[k][1] for k in keys])
    order = np.lexsort(tuple(levels[:, ::-1].T) + (cost,))  # by cost, then level of gene 1, 2, ...
    for i in order[:tries]:
        genes = ga.genes_of_keys([keys[i]])[0]
        if problem.confirm(genes):
            return genes
    return None


def _run_fingerprint(problem_fingerprint: str, settings, seed) -> str:
    """The problem's data, the GA settings and the seed: what a checkpoint must match to resume."""
    blob = json.dumps({"problem": problem_fingerprint, "settings": asdict(settings), "seed": int(seed)},
                      sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def check_checkpoint(path, problem_fingerprint: str, settings: GaSettings, seed: int) -> None:
    """Raise QmtInputError (one line) unless `path` does not exist or holds a checkpoint of this
    very run (same problem data, GA settings and seed): the CLI calls it before any work."""
    p = Path(path)
    if p.exists():
        _load_checkpoint(p, _run_fingerprint(problem_fingerprint, settings, seed))


def _save_checkpoint(path: Path, run_id, pop, gen, rng, history, cache, best_key, best_cost, best_gen,
                     wall_s) -> None:
    state = dict(format="qmt_drake GA checkpoint 2", run=run_id, generation=gen, pop=pop.tolist(),
                 rng=rng.bit_generator.state, history=history.__dict__,
                 cache=[[k.hex(), f, c, v] for k, (f, c, v) in cache.items()],
                 best_key=None if best_key is None else best_key.hex(),
                 best_cost=best_cost if np.isfinite(best_cost) else None, best_gen=best_gen, wall_s=wall_s)
    write_text_atomic(path, json.dumps(state, allow_nan=True))


def _load_checkpoint(path: Path, run_id: str) -> dict:
    """The saved state, or QmtInputError (one line) for a file that is not a checkpoint of this run."""
    try:
        state = json.loads(path.read_text())
        if not isinstance(state, dict) or state.get("format") != "qmt_drake GA checkpoint 2":
            raise ValueError("not a qmt_drake GA checkpoint")
        if state["run"] != run_id:
            raise QmtInputError(f"checkpoint {path} belongs to another run (its scenario, GA settings or seed "
                                "differ); delete it or give another --checkpoint path")
        hist = GaHistory(**state["history"])
        return dict(pop=np.array(state["pop"], dtype=np.uint8), generation=int(state["generation"]),
                    rng=state["rng"], history=hist,
                    cache={bytes.fromhex(k): (float(f), float(c), float(v)) for k, f, c, v in state["cache"]},
                    best_key=None if state["best_key"] is None else bytes.fromhex(state["best_key"]),
                    best_cost=np.inf if state["best_cost"] is None else float(state["best_cost"]),
                    best_gen=int(state["best_gen"]), wall_s=float(state["wall_s"]))
    except QmtInputError:
        raise
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise QmtInputError(f"checkpoint {path} is unreadable or corrupt ({type(exc).__name__}: "
                            f"{str(exc)[:80]}); delete it to start afresh") from None
