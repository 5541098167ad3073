"""Reproduce one chapter of seed 000: the reported genes, our GA over 10 seeds, the family
optimum, the figures and a table, all written to `out/<scenario>/`.

GA runs go to a process pool (one process per core) and each run's plan is written as it
finishes (`ga_seed<k>.json`), so an interrupted study resumes where it stopped. The JSON files
load again with `qmt_drake.load_plan`.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from qmt_drake.apps import plots
from qmt_drake.hands import run_simulate
from qmt_drake.outputs import write_text_atomic
from qmt_drake.plan_files import load_plan
from qmt_drake.planners import plan_with
from qmt_drake.transfer_scenario import load_scenario


def _ga_worker(scenario: str, seed: int, path: str, overrides: dict | None) -> str:
    sc = load_scenario(scenario, overrides=overrides)
    plan = plan_with("ga", sc, seed=seed)
    plan.write_json(path)
    return path


def run_ga_seeds(scenario: str, out: Path, seeds: int, workers: int, progress,
                 overrides: dict | None = None) -> list:
    paths = [out / f"ga_seed{s}.json" for s in range(seeds)]
    todo = [(s, p) for s, p in enumerate(paths) if not p.is_file()]
    if len(todo) < seeds:
        progress(f"{scenario}: {seeds - len(todo)} GA runs already in {out}, resuming")
    if todo:
        ctx = multiprocessing.get_context("spawn")  # Drake objects do not survive fork safely
        with ProcessPoolExecutor(max_workers=max(1, workers), mp_context=ctx) as pool:
            futs = {pool.submit(_ga_worker, scenario, s, str(p), overrides): s for s, p in todo}
            for f in as_completed(futs):
                f.result()
                progress(f"{scenario}: GA seed {futs[f]} done")
    sc = load_scenario(scenario, overrides=overrides)
    return [load_plan(p, scenario=sc) for p in paths]


def run_chapter(scenario: str, out_dir: Path = Path("out"), *, seeds: int = 10, workers: int = 2,
                progress=print, record: bool = True) -> dict:
    t_start = time.perf_counter()
    sc = load_scenario(scenario)
    out = Path(out_dir) / scenario
    out.mkdir(parents=True, exist_ok=True)
    progress(f"{scenario}: thesis genes and family optimum")
    thesis = plan_with("thesis", sc)
    thesis.write_json(out / "thesis.json")
    opt_path = out / "optimum.json"
    optimum = load_plan(opt_path, scenario=sc) if opt_path.is_file() else plan_with("optimum", sc)
    optimum.write_json(opt_path)
    ga = run_ga_seeds(scenario, out, seeds, workers, progress)
    T = np.array([p.motion_time_s for p in ga])
    order = np.argsort(T)
    best, median, worst = ga[order[0]], ga[order[len(order) // 2]], ga[order[-1]]
    best.write_json(out / "ga_best.json")
    best.write_csv(out / "ga_best_trajectory.csv")
    opt_T0 = optimum.motion_time_s
    thesis_T0 = float(sc.reported.get("motion_time_s", thesis.motion_time_s))

    def row(label, p):
        c = p.check
        return {"row": label, "genes": p.genes, "motion_time_s": p.motion_time_s,
                "gap_to_optimum_pct": 100 * (p.motion_time_s / opt_T0 - 1),
                "peak_moment_ratio": c.peak_moment_ratio,
                "peak_motor_torque_ratio": c.peak_motor_torque_ratio,
                "feasible": c.feasible, "generations": p.generations,
                "planner_wall_s": p.planner_wall_s}

    rows = [row("thesis reported genes", thesis), row(f"GA best of {seeds}", best),
            row("GA median", median), row("GA worst", worst), row("family optimum", optimum)]
    within = int(np.sum(T <= opt_T0 * 1.005))
    summary = {
        "scenario": scenario,
        "thesis_reported_motion_time_s": thesis_T0,
        "rows": rows,
        "ga_motion_times_s": T.tolist(),
        "ga_within_0.5pct_of_optimum": within,
        "ga_not_slower_than_thesis": int(np.sum(T <= thesis.motion_time_s)),
        "ga_all_feasible_at_10kHz": bool(all(p.feasible for p in ga)),
        "study_wall_s": time.perf_counter() - t_start,
    }
    progress(f"{scenario}: figures")
    figs = {
        "convergence": plots.convergence(
            {f"seed {i}": p.extra["history_best_motion_time_s"] for i, p in enumerate(ga)},
            out / "ga_convergence.png", thesis_T0=thesis_T0, optimum_T0=opt_T0,
            title=f"{scenario}: GA convergence ({seeds} seeds)"),
        "joint_angles": plots.joint_angles({"GA best": best, "thesis genes": thesis},
                                           out / "joint_angles.png",
                                           title=f"{scenario}: joint angles"),
        "moment": plots.moment({"GA best": best, "thesis genes": thesis, "optimum": optimum},
                               out / "moment.png", title=f"{scenario}: payload moment"),
        "motor_torques": plots.motor_torques({"GA best": best, "thesis genes": thesis},
                                             out / "motor_torques.png",
                                             title=f"{scenario}: motor torques"),
        "loci": plots.loci(best, out / "loci.png", title=f"{scenario}: loci of the GA plan"),
    }
    summary["figures"] = {k: str(v) for k, v in figs.items()}
    if record:
        summary["recording"] = _record(sc, best, out / "transfer.html", progress)
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=1) + "\n")
    write_text_atomic(out / "table.md", markdown_table(summary))
    progress(markdown_table(summary))
    return summary


def _record(sc, plan, path: Path, progress):
    """Co-simulate the plan with a Meshcat recording, if the co-simulation is available."""
    try:
        result = run_simulate(sc, plan, time_scale=1.0, record_path=str(path))
        progress(f"{sc.name}: recording {path} (held={result.get('held')})")
        return {"path": str(path), "held": result.get("held"),
                "max_slip_m": result.get("max_slip_m")}
    except Exception as exc:  # the study's planning results must not be lost to a co-sim error
        progress(f"{sc.name}: no recording ({type(exc).__name__}: {exc})")
        return {"error": f"{type(exc).__name__}: {exc}"}


def markdown_table(summary: dict) -> str:
    lines = [f"### {summary['scenario']}", "",
             "| plan | genes | T0 [s] | vs optimum | moment / limit | motor torque / limit | "
             "feasible (10 kHz) |",
             "|---|---|---|---|---|---|---|"]
    for r in summary["rows"]:
        genes = ", ".join(f"{k}={v:.4f}" for k, v in (r["genes"] or {}).items())
        lines.append(f"| {r['row']} | {genes} | {r['motion_time_s']:.4f} | "
                     f"{r['gap_to_optimum_pct']:+.2f}% | {r['peak_moment_ratio']:.4f} | "
                     f"{r['peak_motor_torque_ratio']:.4f} | {r['feasible']} |")
    lines += ["", f"Thesis reports T0 = {summary['thesis_reported_motion_time_s']} s. GA: "
              f"{summary['ga_within_0.5pct_of_optimum']} of {len(summary['ga_motion_times_s'])} "
              f"seeds within 0.5% of the family optimum, {summary['ga_not_slower_than_thesis']} "
              "not slower than the thesis's genes.", ""]
    return "\n".join(lines)


def main(scenario: str, argv=None) -> int:
    ap = argparse.ArgumentParser(description=f"Reproduce {scenario} of seed 000 into OUT/{scenario}")
    ap.add_argument("--out", default="out")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-record", action="store_true")
    a = ap.parse_args(argv)
    run_chapter(scenario, Path(a.out), seeds=a.seeds, workers=a.workers,
                progress=lambda m: print(m, file=sys.stderr, flush=True), record=not a.no_record)
    return 0
