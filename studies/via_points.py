"""Any number of vias: the GA on a five-via task (via5-ch4, 6 genes x 12 bits) over 10 seeds
against the family optimum -> out/via5-ch4/summary.json (+ the plans).

Run: .venv/bin/python -m studies.via_points [--out out] [--seeds 10] [--workers 2] [--plain]
The scenario's GA plays each chromosome at its tight time scale (ga.tight_timing); --plain runs the
thesis's GA instead (into OUT/via5-ch4-plain).
Each GA run is written as it finishes and reused by a rerun (thesis_study.run_ga_seeds).
"""

import argparse
import json
import sys
from pathlib import Path

from qmt_drake.apps.thesis_study import run_ga_seeds
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.planners import plan_with
from qmt_drake.transfer_scenario import load_scenario

SCENARIO = "via5-ch4"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--plain", action="store_true", help="the thesis's GA (ga.tight_timing false)")
    a = ap.parse_args(argv)
    overrides = {"ga": {"tight_timing": False}} if a.plain else None
    out = Path(a.out) / (SCENARIO + ("-plain" if a.plain else ""))
    out.mkdir(parents=True, exist_ok=True)
    progress = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    opt = plan_with("optimum", load_scenario(SCENARIO), seed=0)
    opt.write_json(out / "optimum.json")
    ga = run_ga_seeds(SCENARIO, out, a.seeds, a.workers, progress, overrides=overrides)
    rows = [{"seed": s, "motion_time_s": p.motion_time_s, "vs_optimum": p.motion_time_s / opt.motion_time_s - 1,
             "feasible": p.feasible, "generations": p.generations, "evaluations": p.evaluations,
             "planner_wall_s": p.planner_wall_s} for s, p in enumerate(ga)]
    within = sum(r["vs_optimum"] <= 0.005 and r["feasible"] for r in rows)
    summary = {"scenario": SCENARIO, "optimum_motion_time_s": opt.motion_time_s, "optimum_feasible": opt.feasible,
               "ga": rows, "ga_within_0.5pct_of_optimum": within, "seeds": a.seeds}
    write_text_atomic(out / "summary.json", json.dumps(jsonable(summary), indent=1))
    lines = ["| plan | genes | T0 [s] | vs optimum | moment / limit | motor torque / limit | feasible |",
             "|---|---|---|---|---|---|---|"]
    for label, p in [("family optimum", opt)] + [(f"GA seed {s}", p) for s, p in enumerate(ga)]:
        genes = ", ".join(f"{k}={v:.4f}" for k, v in p.genes.items())
        lines.append(f"| {label} | {genes} | {p.motion_time_s:.4f} | {p.motion_time_s / opt.motion_time_s - 1:+.2%} | "
                     f"{p.check.peak_moment_ratio:.4f} | {p.check.peak_motor_torque_ratio:.4f} | {p.feasible} |")
    lines.append(f"\nGA: {within} of {a.seeds} seeds within 0.5% of the family optimum.")
    write_text_atomic(out / "table.md", "\n".join(lines) + "\n")
    print(f"{SCENARIO}: optimum T0 {opt.motion_time_s:.4f} s; GA within 0.5%: {within} of {a.seeds} seeds "
          f"(worst {max(r['vs_optimum'] for r in rows):+.3%})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
