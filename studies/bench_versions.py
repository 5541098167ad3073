"""The planning core of this checkout against another checkout of qmt_drake, side by side in one run.

    .venv/bin/python -m studies.bench_versions --ref /path/to/other/checkout [--rounds 2] [--out out]

Each measure runs in a fresh subprocess per version, the versions interleaved round by round, so a
busy machine slows both alike: fitness evaluations per second (ch.4, 1 kHz, batches of 50 random
candidates), GA wall time to within 0.5% of the ch.4 family optimum (5 seeds), one full
10,000-generation GA run, seed 001's SNOPT solve time per optimum (ohsaka-fig3, median of its 8
starts) and the magnet co-simulation's cost per plant step and its ratio to the Drake-primitives
floor (each version's studies/bench_cosim_floor.py, 25 repeats of the 1208-step move; the ratio is the
median's, cosim_us_per_step_best the fastest of the 25 runs, read from the same run: on this shared VM
a 5-repeat median moved by 10 % between identical runs, the best of 25 by under 2 %). Prints a table with the ratio this/ref and writes OUT/bench_versions.json
(atomically). The probe copes with the older API names (problem.evaluate/peaks, result
motion_time_s/cost)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

PROBE = r"""
import json, sys, time
import numpy as np
try:
    from qmt_drake.transfer_scenario import load_scenario
except ImportError:
    from qmt_drake.scenario import load_scenario
from qmt_drake.planners.ga import run_ga
from qmt_drake.problem import PlanningProblem
what = sys.argv[1]
P = PlanningProblem(load_scenario("thesis-ch4"))
peaks = getattr(P, "peaks", None) or P.evaluate
if what == "evaluations_per_s":
    g = P.lower + (P.upper - P.lower) * np.random.default_rng(0).random((1050, 3))
    peaks(g[:50], rate_hz=1000.0)
    t = time.perf_counter()
    for i in range(1, 21):
        peaks(g[i * 50:(i + 1) * 50], rate_hz=1000.0)
    out = 1000 / (time.perf_counter() - t)
elif what == "ga_s_to_0.5pct_median":
    walls = []
    for seed in range(5):
        r = run_ga(P, seed=seed, max_generations=3000)
        h = np.array(getattr(r.history, "best_cost", None) or r.history.best_motion_time_s)
        hit = np.flatnonzero(h <= 1.6885 * 1.005)
        walls.append(float(r.history.wall_s[hit[0]]) if hit.size else float("nan"))
    out = float(np.median(walls))
else:
    out = run_ga(P, seed=0, stall_generations=0).wall_s
print(json.dumps(out))
"""
MEASURES = ("evaluations_per_s", "ga_s_to_0.5pct_median", "full_10000_generation_run_s",
            "snopt_s_per_optimum_median", "cosim_cost_ratio_to_floor", "cosim_us_per_step_best")


def _run(tree: Path, args: list) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(tree), MPLBACKEND="Agg")
    return subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True, cwd=str(tree), check=True)


def _probe(tree: Path, measure: str, scratch: Path) -> float:
    if measure == "snopt_s_per_optimum_median":
        # seed 001: the 8 SNOPT optima of ohsaka-fig3 (both versions accept this command; the older
        # one rerouted it to its own plan-energy); each optimum's own solve time
        f = scratch / "snopt.json"
        _run(tree, ["-m", "qmt_drake.apps.cli", "plan", "ohsaka-fig3", "--method", "snopt", "--json", str(f)])
        return float(np.median([o["wall_s"] for o in json.loads(f.read_text())["optima"]]))
    if measure.startswith("cosim_"):
        # the magnet co-simulation against its Drake-primitives floor (studies/bench_cosim_floor.py of
        # each version: the same plant, plan and step), 25 alternating repeats
        if measure == "cosim_cost_ratio_to_floor":
            _run(tree, ["-m", "studies.bench_cosim_floor", "--repeats", "25", "--sweep-cases", "0",
                        "--out", str(scratch)])
        cost = json.loads((scratch / "bench_cosim_floor.json").read_text())["cost"]
        if measure == "cosim_cost_ratio_to_floor":
            return float(cost["ratio_wall_median"])
        steps = cost["sim_time_s"] / cost["time_step_s"]
        return float(min(cost["runs"]["ours"]["wall"]) / steps * 1e6)
    out = _run(tree, ["-c", PROBE, measure])
    return float(json.loads(out.stdout.strip().splitlines()[-1]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True, help="another qmt_drake checkout (its qmt_drake/ folder is imported)")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", default="out")
    ap.add_argument("--measures", nargs="+", choices=MEASURES, default=list(MEASURES), metavar="MEASURE",
                    help=f"which measures (default all: {' '.join(MEASURES)})")
    a = ap.parse_args(argv)
    this, ref = Path(__file__).resolve().parents[1], Path(a.ref).resolve()
    if not (ref / "qmt_drake" / "__init__.py").is_file():
        print(f"bench_versions: error: --ref {ref} is not a qmt_drake checkout (no qmt_drake/__init__.py)",
              file=sys.stderr)
        return 2
    measures = [m for m in MEASURES if m in a.measures]  # in MEASURES' order: the ratio reads the run before it
    if "cosim_us_per_step_best" in measures and "cosim_cost_ratio_to_floor" not in measures:
        measures.insert(measures.index("cosim_us_per_step_best"), "cosim_cost_ratio_to_floor")
    results = {m: {"this": [], "ref": []} for m in measures}
    scratch = {"ref": Path(tempfile.mkdtemp(prefix="bench_ref_")), "this": Path(tempfile.mkdtemp(prefix="bench_this_"))}
    for r in range(a.rounds):
        for m in measures:
            for name, tree in (("ref", ref), ("this", this)):
                v = _probe(tree, m, scratch[name])
                results[m][name].append(v)
                print(f"round {r + 1} {m} {name}: {v:.4g}", file=sys.stderr, flush=True)
    print("| measure | this (median) | ref (median) | this / ref |\n|---|---|---|---|")
    for m in measures:
        t, f = np.median(results[m]["this"]), np.median(results[m]["ref"])
        print(f"| {m} | {t:.4g} | {f:.4g} | {t / f:.3f} |")
    from qmt_drake.outputs import write_text_atomic
    write_text_atomic(Path(a.out) / "bench_versions.json",
                      json.dumps({"ref": str(ref), "this": str(this), "rounds": a.rounds, "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
