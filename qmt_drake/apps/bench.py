"""`qmt-drake bench`: speed of the planning core, printed and written as JSON.

Measures, for one scenario (default thesis-ch4):
- fitness evaluations per second at 1 kHz sampling (batches of one GA population of random
  candidates), for the fast evaluator (coarse grid + refinement) and for the full grid;
- the batched evaluator's speed-up over per-sample Drake calls (CalcInverseDynamics plus the hand's
  J*qdd + Jdot*qd) on the same samples;
- the wall time of GA runs (thesis settings, several seeds) until the best plan is within 0.5% of
  the family optimum, and of one full 10,000-generation run.
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

import numpy as np

from qmt_drake.outputs import write_text_atomic
from qmt_drake.planners import registry
from qmt_drake.planners.ga import run_ga
from qmt_drake.problem import PlanningProblem
from qmt_drake.transfer_scenario import load_scenario


def _evaluations_per_s(problem, exact: bool, batches: int = 20, batch: int = 50) -> float:
    rng = np.random.default_rng(0)
    g = problem.lower + (problem.upper - problem.lower) * rng.random((batches * batch,
                                                                      problem.lower.size))
    t = time.perf_counter()
    for i in range(batches):
        problem.peaks(g[i * batch:(i + 1) * batch], rate_hz=1000.0, exact=exact)
    return batches * batch / (time.perf_counter() - t)


def _drake_speedup(problem, n_samples: int = 2000) -> dict:
    sc = problem.scenario
    g = problem.genes_vector(sc.reported["genes"]) if sc.reported.get("genes") else \
        0.5 * (problem.lower + problem.upper)
    t = np.linspace(0, problem.family.motion_time_s(g[None])[0], n_samples)
    q, qd, qdd = problem.family.sample(g, t)
    arm = problem.arm
    t0 = time.perf_counter()
    for k in range(n_samples):
        arm.drake_inverse_dynamics(q[k], qd[k], qdd[k])
        arm.drake_tip_acceleration(q[k], qd[k], qdd[k])
    drake_s = time.perf_counter() - t0
    reps = 20
    t0 = time.perf_counter()
    for _ in range(reps):
        arm.tip_acceleration_and_joint_torque(q, qd, qdd)
    batched_s = (time.perf_counter() - t0) / reps
    return {"samples": n_samples, "drake_per_sample_total_s": drake_s,
            "batched_total_s": batched_s, "speedup": drake_s / batched_s}


def run_bench(scenario: str = "thesis-ch4", out_dir: Path = Path("out"), progress=print,
              seeds: int = 5, full_run: bool = True) -> dict:
    sc = load_scenario(scenario)
    problem = PlanningProblem(sc)
    progress(f"bench {scenario}: evaluator speed")
    fast = _evaluations_per_s(problem, exact=False)
    full = _evaluations_per_s(problem, exact=True, batches=4)
    speed = _drake_speedup(problem)
    progress(f"bench {scenario}: family optimum")
    opt = registry.plan(sc, "optimum")  # the one planner registry; the GA runs below time the GA engine itself
    target = opt.motion_time_s * 1.005
    runs = []
    for seed in range(seeds):
        r = run_ga(PlanningProblem(sc), seed=seed, max_generations=3000)
        h = np.array(r.history.best_cost)
        hit = np.flatnonzero(h <= target)
        runs.append({"seed": seed, "generations_to_0.5pct": int(hit[0]) + 1 if hit.size else None,
                     "wall_s_to_0.5pct": float(r.history.wall_s[hit[0]]) if hit.size else None,
                     "best_motion_time_s_after_3000": r.cost})
        progress(f"bench {scenario}: GA seed {seed}: {runs[-1]}")
    data = {
        "scenario": scenario,
        "machine": {"cpu_count": __import__("os").cpu_count(), "python": platform.python_version()},
        "fitness_evaluations_per_s_1kHz_fast": fast,
        "fitness_evaluations_per_s_1kHz_full_grid": full,
        "batched_vs_drake_per_sample": speed,
        "family_optimum_motion_time_s": opt.motion_time_s,
        "family_optimum_wall_s": opt.planner_wall_s,
        "ga_runs_to_within_0.5pct": runs,
    }
    hits = [r["wall_s_to_0.5pct"] for r in runs if r["wall_s_to_0.5pct"] is not None]
    data["ga_wall_s_to_within_0.5pct_median"] = float(np.median(hits)) if hits else None
    if full_run:
        progress(f"bench {scenario}: one full {sc.ga.max_generations}-generation GA run")
        r = run_ga(PlanningProblem(sc), seed=0, progress=progress, progress_every_s=20,
                   stall_generations=0)  # all generations, no early stop
        data["ga_full_run"] = {"generations": r.generations, "wall_s": r.wall_s,
                               "motion_time_s": r.cost, "evaluations": r.evaluations}
    out = Path(out_dir) / "bench.json"
    write_text_atomic(out, json.dumps(data, indent=1) + "\n")
    write_text_atomic(Path(out_dir) / "bench.md", bench_markdown(data))
    progress(f"wrote {out}")
    return data


def bench_markdown(data: dict) -> str:
    """The planner-speed figures of one `run_bench` as a Markdown table (for the report)."""
    speed = data["batched_vs_drake_per_sample"]
    rows = [
        ("fitness evaluations per s, 1 kHz check, fast path", f"{data['fitness_evaluations_per_s_1kHz_fast']:.0f}"),
        ("fitness evaluations per s, 1 kHz check, full grid", f"{data['fitness_evaluations_per_s_1kHz_full_grid']:.0f}"),
        ("family optimum: motion time [s] / wall time [s]",
         f"{data['family_optimum_motion_time_s']:.4f} / {data['family_optimum_wall_s']:.2f}"),
        ("GA wall time to within 0.5 % of the optimum, median [s]",
         "not reached" if data["ga_wall_s_to_within_0.5pct_median"] is None
         else f"{data['ga_wall_s_to_within_0.5pct_median']:.2f}"),
    ]
    rows += [(f"batched vs Drake per sample: {k}", f"{v:.4g}" if isinstance(v, float) else str(v))
             for k, v in speed.items()]
    if "ga_full_run" in data:
        f = data["ga_full_run"]
        rows.append(("one full GA run: generations / wall [s] / motion time [s]",
                     f"{f['generations']} / {f['wall_s']:.1f} / {f['motion_time_s']:.4f}"))
    lines = [f"Scenario `{data['scenario']}`, {data['machine']['cpu_count']} CPUs, Python {data['machine']['python']}.",
             "", "| quantity | value |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in rows]
    return "\n".join(lines) + "\n"
