"""Issue 19's GA check on a 6-DOF via-point task: the GA over 10 seeds against the via-cubic family optimum.

    cd <checkout> && PYTHONPATH=. .venv/bin/python -m studies.spatial_ga_seeds [--scenario ur5-suction-bins]
        [--seeds 0 1 ... 9] [--generations 150] [--population 40] [--restarts 2] [--plain] [--out out]

The GA (planners/spatial_methods.plan_ga_spatial, the benchmark's generations) and the family
optimum (plan_family_optimum, Nelder-Mead from `restarts` starts) plan the same via-cubic family
(genes: the segment times). Both time each candidate at its tight scale (planners/spatial_tight.py);
`--plain` runs the thesis's GA instead, which must find the feasibility boundary itself (it stalls
on it: +0.1 to +0.5 % with 150 generations). Both plans are re-checked and time-scaled to hold at 10x
the check rate, and their motion times compared: gap = T_ga / T_opt - 1, with each GA run's wall
time. "Must show": |gap| <= 0.5 % for 9 of 10 seeds.
A negative gap beyond the optimum's own tolerance would mean the optimum is not optimal (the table
says so rather than hiding it). Prints a table and writes OUT/spatial/ga_seeds.json and .md atomically.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic
from qmt_drake.planners.spatial_methods import plan_family_optimum, plan_ga_spatial
from qmt_drake.spatial_task import load_spatial_scenario

WITHIN = 0.005  # issue 19: within 0.5 % of the family optimum
REQUIRED = 9  # ... for 9 of 10 seeds


def run(scenario: str, seeds, generations: int, population: int, restarts: int, progress=None,
        tight_timing: bool = True) -> dict:
    sc = load_spatial_scenario(scenario)
    opt = plan_family_optimum(sc, restarts=restarts)
    rows = []
    for seed in seeds:
        t0 = time.perf_counter()
        p = plan_ga_spatial(sc, seed=seed, generations=generations, population=population, tight_timing=tight_timing)
        gap = p.duration_s / opt.duration_s - 1.0
        rows.append({"seed": int(seed), "T_ga_s": p.duration_s, "gap": gap, "within": abs(gap) <= WITHIN,
                     "segment_times_s": p.info["segment_times_s"], "hold_scale": p.hold_scale,
                     "recheck_max_ratio": p.recheck["max"], "generations": p.info["generations"],
                     "evaluations": p.info["evaluations"], "wall_s": time.perf_counter() - t0})
        if progress:
            progress(f"seed {seed}: T_ga {p.duration_s:.4f} s, gap {gap:+.3%} ({rows[-1]['wall_s']:.0f} s)")
    within = sum(r["within"] for r in rows)
    return {"scenario": sc.name, "generations": generations, "population": population, "restarts": restarts,
            "tight_timing": tight_timing, "optimum_wall_s": opt.planning_s,
            "T_opt_s": opt.duration_s, "optimum_segment_times_s": opt.info["segment_times_s"],
            "optimum_evaluations": opt.info["evaluations"], "optimum_recheck_max_ratio": opt.recheck["max"],
            "rows": rows, "within_0.5pct": within, "seeds": len(rows),
            "must_show_met": within >= REQUIRED * len(rows) / 10}


def table(res: dict) -> str:
    lines = ["| seed | T_ga s | T_opt s | gap % | generations | evaluations | wall s |", "|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        lines.append(f"| {r['seed']} | {r['T_ga_s']:.5f} | {res['T_opt_s']:.5f} | {100 * r['gap']:+.3f} | "
                     f"{r['generations']} | {r['evaluations']} | {r['wall_s']:.1f} |")
    ga = "GA with tight timing" if res.get("tight_timing", True) else "the thesis's GA (--plain)"
    lines.append(f"\n{res['scenario']}: {ga} within 0.5 % of the family optimum for {res['within_0.5pct']} of "
                 f"{res['seeds']} seeds (population {res['population']}, {res['generations']} generations; "
                 f"optimum from {res['restarts']} Nelder-Mead starts in {res.get('optimum_wall_s', float('nan')):.1f} s).")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="ur5-suction-bins")
    ap.add_argument("--seeds", nargs="+", type=int, default=list(range(10)))
    ap.add_argument("--generations", type=int, default=150, help="the spatial benchmark's default")
    ap.add_argument("--population", type=int, default=40)
    ap.add_argument("--restarts", type=int, default=2, choices=(1, 2),
                    help="Nelder-Mead starts of the family optimum (plan_family_optimum has two)")
    ap.add_argument("--plain", action="store_true",
                    help="the thesis's GA: candidates feasible or not as their genes give them (no tight timing)")
    ap.add_argument("--out", default="out")
    a = ap.parse_args(argv)
    try:
        check_output_dir(Path(a.out) / "spatial", "--out")
        for flag, v, lo in (("--generations", a.generations, 1), ("--population", a.population, 2)):
            if v < lo:
                raise QmtInputError(f"{flag} {v}: give an integer >= {lo}")
        if any(s < 0 for s in a.seeds):
            raise QmtInputError(f"--seeds {a.seeds}: seeds are non-negative integers")
        res = run(a.scenario, a.seeds, a.generations, a.population, a.restarts,
                  progress=lambda m: print(m, file=sys.stderr, flush=True), tight_timing=not a.plain)
    except QmtInputError as exc:
        print(f"spatial_ga_seeds: error: {exc}", file=sys.stderr)
        return 2
    md = table(res)
    print(md, end="")
    write_text_atomic(Path(a.out) / "spatial" / "ga_seeds.json", json.dumps(jsonable(res), indent=1))
    write_text_atomic(Path(a.out) / "spatial" / "ga_seeds.md", md)  # the report's spatial section shows *.md
    return 0


if __name__ == "__main__":
    sys.exit(main())
