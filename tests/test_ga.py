"""The GA: operators, determinism, resumable checkpoints, re-checked output, infeasible limits."""

import re

import numpy as np
import pytest

from qmt_drake.planners.ga import BinaryGa, run_ga
from qmt_drake.problem import PlanningProblem
from qmt_drake.transfer_scenario import load_scenario


def test_gray_and_binary_decoding_cover_every_level(problems):
    P = problems["thesis-ch4"]
    for enc in ("binary", "gray"):
        s = P.scenario.ga.__class__(**{**P.scenario.ga.__dict__, "encoding": enc})
        ga = BinaryGa(P, s)
        levels = np.arange(4096)
        gray = levels ^ (levels >> 1) if enc == "gray" else levels
        bits = ((gray[:, None] >> np.arange(11, -1, -1)) & 1).astype(np.uint8)
        pop = np.concatenate([bits, bits, bits], axis=1)
        np.testing.assert_array_equal(ga.codes(pop), np.stack([levels] * 3, axis=1))
        g = ga.decode(pop)
        np.testing.assert_allclose(g[[0, -1]], [P.lower, P.upper])


def test_mutation_flips_bits_at_the_set_rate(problems):
    P = problems["thesis-ch4"]
    ga = BinaryGa(P, P.scenario.ga)
    rng = np.random.default_rng(0)
    pop = np.zeros((2000, 36), dtype=np.uint8)
    rate = ga.mutate(pop, rng).mean()
    n = pop.size
    assert abs(rate - 0.05) < 5 * np.sqrt(0.05 * 0.95 / n)


def test_crossover_keeps_each_column_of_a_pair(problems):
    P = problems["thesis-ch4"]
    ga = BinaryGa(P, P.scenario.ga)
    rng = np.random.default_rng(1)
    parents = rng.integers(0, 2, (50, 36), dtype=np.uint8)
    kids = ga.crossover(parents, rng)
    # Single-point crossover swaps tails: every column of a pair keeps its two bits.
    np.testing.assert_array_equal(kids[0::2] + kids[1::2], parents[0::2] + parents[1::2])
    assert (kids != parents).any()


def test_same_seed_same_result_and_output_passes_recheck(problems):
    P = problems["thesis-ch4"]
    a = run_ga(P, seed=5, max_generations=150)
    b = run_ga(P, seed=5, max_generations=150)
    c = run_ga(P, seed=6, max_generations=150)
    np.testing.assert_array_equal(a.genes, b.genes)
    assert a.history.best_cost == b.history.best_cost
    assert a.history.best_cost != c.history.best_cost
    assert a.feasible
    rep = P.report(a.genes, rate_hz=10000)
    assert rep.feasible and rep.peak_moment_ratio <= 1.0
    # Best-so-far never gets worse.
    h = np.array(a.history.best_cost)
    assert np.all(np.diff(h[np.isfinite(h)]) <= 0)


def test_interrupted_run_resumes_to_the_same_result(problems, tmp_path):
    P = problems["thesis-ch3"]
    full = run_ga(P, seed=2, max_generations=120)
    ckpt = tmp_path / "ga.ckpt.json"

    class Stop(Exception):
        pass

    def crash(msg):
        if "generation 70 of" in msg:
            raise Stop

    with pytest.raises(Stop):
        run_ga(P, seed=2, max_generations=120, checkpoint_path=ckpt, checkpoint_every=50,
               progress=crash, progress_every_s=0.0)
    assert ckpt.is_file()
    resumed = run_ga(P, seed=2, max_generations=120, checkpoint_path=ckpt, checkpoint_every=50)
    np.testing.assert_array_equal(resumed.genes, full.genes)
    assert resumed.history.best_cost == full.history.best_cost
    assert not ckpt.exists()


def test_stall_stop_is_said_with_an_honest_count(problems):
    P = problems["thesis-ch3"]
    said = []
    r = run_ga(P, seed=0, max_generations=5000, stall_generations=30, progress=said.append, progress_every_s=0.0)
    assert r.stop_reason.startswith("best unchanged") and r.generations < 5000
    assert f"stopped at generation {r.generations} of at most 5000: best unchanged for 30" in said[-1]
    assert all("/5000" not in m for m in said)


def test_limits_no_gene_meets_give_least_violating_infeasible_plan():
    from qmt_drake.planners import plan_with
    sc = load_scenario("thesis-ch4", overrides={"limits": {"motor_torque_limit_Nm": [1e-5, 1e-5]}})
    plan = plan_with("ga", sc, seed=0, max_generations=40)
    assert not plan.feasible
    assert plan.check.peak_motor_torque_ratio > 1.0
    # It is the least-violating chromosome the run saw: at least as good as every member of
    # the (seeded, reproducible) initial population.
    P = PlanningProblem(sc)
    r = run_ga(P, seed=0, max_generations=40)
    assert not r.feasible
    worst = P.peaks(r.genes[None], exact=True).worst_ratio[0]
    ga = BinaryGa(P, sc.ga)
    initial = np.random.default_rng(0).integers(0, 2, size=(sc.ga.population, 36), dtype=np.uint8)
    assert worst <= P.peaks(ga.decode(initial), exact=True).worst_ratio.min()


class _Sphere:
    """A cheap Problem for the GA's mechanics: minimise |genes - target|^2 (always feasible)."""

    def __init__(self, n_genes, lower=-1.0, upper=2.0):
        self.name = f"sphere{n_genes}"
        self.gene_names = tuple(f"g{i}" for i in range(n_genes))
        self.lower = np.full(n_genes, lower)
        self.upper = np.full(n_genes, upper)
        self.target = np.linspace(0.1, 0.9, n_genes)

    def evaluate(self, genes, exact=False):
        from qmt_drake.problem import Evaluation
        g = np.atleast_2d(genes)
        return Evaluation(np.sum((g - self.target) ** 2, axis=1), np.zeros(len(g)))

    def fitness(self, ev):
        return np.exp(-ev.cost)

    def confirm(self, genes):
        return True

    def fingerprint(self):
        return self.name


@pytest.mark.parametrize("n_genes, bits", [(3, 12), (3, 22), (6, 12), (6, 17), (10, 12), (10, 22)])
@pytest.mark.parametrize("encoding", ["binary", "gray"])
def test_keys_and_decoding_round_trip_for_long_chromosomes(n_genes, bits, encoding):
    """genes x bits well beyond 63: every chromosome keeps its own key and decodes back."""
    from qmt_drake.config.scenario import GaSettings
    P = _Sphere(n_genes)
    ga = BinaryGa(P, GaSettings(bits_per_gene=bits, encoding=encoding))
    rng = np.random.default_rng(n_genes * bits)
    pop = rng.integers(0, 2, (64, n_genes * bits), dtype=np.uint8)
    pop[1] = pop[0]
    pop[1, -1] ^= 1  # differs from chromosome 0 in the last bit only
    keys = ga.keys(pop)
    assert len(set(keys)) == len({row.tobytes() for row in pop})
    assert keys[0] != keys[1]
    np.testing.assert_array_equal(np.array([ga.chromosome(k) for k in keys]), pop)
    np.testing.assert_allclose(ga.genes_of_keys(keys), ga.decode(pop), rtol=0, atol=0)
    codes = ga.codes(pop)
    assert codes.min() >= 0 and codes.max() <= 2**bits - 1
    # Decoding is monotone in the level and hits both bounds exactly.
    ends = np.zeros((2, n_genes * bits), np.uint8)
    ends[1] = 1 if encoding == "binary" else np.tile(np.r_[1, np.zeros(bits - 1, np.uint8)], n_genes)
    np.testing.assert_array_equal(ga.decode(ends), [P.lower, P.upper])


def test_ga_on_a_generic_problem_returns_what_it_evaluated():
    """The reported best is the decoded genes of the best chromosome it evaluated (10 genes x 20 bits)."""
    from qmt_drake.config.scenario import GaSettings
    P = _Sphere(10)
    s = GaSettings(population=40, bits_per_gene=20, max_generations=300, elite_count=1, selection="tournament",
                   encoding="gray")
    r = run_ga(P, s, seed=1)
    assert r.cost == pytest.approx(P.evaluate(r.genes[None]).cost[0], rel=0, abs=0)
    assert r.cost == pytest.approx(np.nanmin(r.history.best_cost), rel=1e-12)
    assert r.cost < 0.05


def test_mutants_per_generation_flip_one_bit_in_that_many_individuals():
    from qmt_drake.config.scenario import GaSettings
    ga = BinaryGa(_Sphere(6), GaSettings(population=200, bits_per_gene=4, mutants_per_generation=30))
    pop = np.zeros((200, 24), np.uint8)
    out = ga.mutate(pop, np.random.default_rng(0))
    assert (out.sum(axis=1) == 1).sum() == 30 and out.sum() == 30


def test_checkpoint_of_another_run_or_corrupt_is_refused(problems, tmp_path):
    from qmt_drake.errors import QmtInputError
    P = problems["thesis-ch4"]
    ckpt = tmp_path / "ga.json"
    with pytest.raises(KeyboardInterrupt, match=f"checkpoint written to {re.escape(str(ckpt))}"):
        def stop(msg):
            raise KeyboardInterrupt
        run_ga(P, seed=0, max_generations=50, checkpoint_path=ckpt, progress=stop, progress_every_s=0.0)
    assert ckpt.is_file()  # Ctrl-C leaves a checkpoint and says where
    with pytest.raises(QmtInputError, match="belongs to another run"):
        run_ga(P, seed=1, max_generations=50, checkpoint_path=ckpt)
    edited = load_scenario("thesis-ch4", overrides={"limits": {"moment_limit_Nm": 0.6e-3}})
    with pytest.raises(QmtInputError, match="belongs to another run"):
        run_ga(PlanningProblem(edited), seed=0, max_generations=50, checkpoint_path=ckpt)
    ckpt.write_text("{not json")
    with pytest.raises(QmtInputError, match="corrupt"):
        run_ga(P, seed=0, max_generations=50, checkpoint_path=ckpt)


@pytest.mark.parametrize("kw, needle", [({"max_generations": 0}, "at least one generation"),
                                        ({"seed": -1}, "non-negative integer")])
def test_bad_ga_arguments_are_one_line_errors(problems, kw, needle):
    from qmt_drake.errors import QmtInputError
    with pytest.raises(QmtInputError, match=needle):
        run_ga(problems["thesis-ch4"], **{"seed": 0, **kw})


def test_tight_timing_ga_returns_motions_on_their_limits():
    """ga.tight_timing: each chromosome is played at the scale that puts it on its limits, so the
    returned plan is feasible on the refined check and touches its worst limit."""
    from qmt_drake.planners import plan_with
    sc = load_scenario("thesis-ch4", overrides={"ga": {"tight_timing": True}})
    plan = plan_with("ga", sc, seed=0, max_generations=60)
    assert plan.feasible
    assert 0.999 < plan.check.worst_ratio <= 1.0
    plain = plan_with("ga", load_scenario("thesis-ch4"), seed=0, max_generations=60)
    assert plan.motion_time_s < plain.motion_time_s
