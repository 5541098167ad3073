"""`qmt-drake design TASK.yaml`: choose the joint combination and link lengths for a task (seed 003).

The lead wires `add_parser(subparsers)` into qmt_drake/cli.py; `cmd_design(args)` returns the exit
code (bad input raises QmtInputError before any long computation; the CLI maps it to exit 2).
Writes OUT/results.json, OUT/table.md and OUT/<type>.urdf for every type's best design.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from qmt_drake.errors import QmtInputError

METHODS = ("auto", "ga", "stand-in", "exhaustive")


def add_parser(subparsers):
    p = subparsers.add_parser("design", help="choose arm type and link lengths for a task by "
                                             "operability (seed 003)")
    p.add_argument("task", help="task YAML (or a name in models/tasks/)")
    p.add_argument("--types", default="all", help="comma-separated types (BP,BB,...) or 'all'")
    p.add_argument("--method", default="auto", choices=METHODS,
                   help="ga: the project's GA (seed 003 settings); exhaustive: every design; "
                        "stand-in: random search + coordinate descent; auto: ga if available")
    p.add_argument("--budget", type=int, default=12000, help="designs for the stand-in's random search")
    p.add_argument("--workers", type=int, default=2, help="parallel processes (one type each)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-obstacles", action="store_true", help="drop the task's obstacles")
    p.add_argument("--out", default=None, help="output folder (default out/design/<task name>)")
    p.set_defaults(func=cmd_design)
    return p


def _types(arg: str):
    from qmt_drake.design.arm_types import TYPES, check_type
    if arg.strip().lower() == "all":
        return TYPES
    out = tuple(check_type(t.strip()) for t in arg.split(",") if t.strip())
    bad = [t for t in out if t not in TYPES]
    if bad or not out:
        raise QmtInputError(f"--types {arg!r}: {', '.join(bad) or 'empty'} not among the seed's ten "
                            f"types {', '.join(TYPES)}")
    return out


def cmd_design(args) -> int:
    from qmt_drake.design.arm_types import urdf_text
    from qmt_drake.design.problem import lengths6
    from qmt_drake.design.search import run_all_types
    from qmt_drake.design.tasks import load_task
    from qmt_drake.plan import write_text_atomic

    task = load_task(args.task)
    if args.no_obstacles:
        task = task.without_obstacles()
    types = _types(args.types)
    if args.budget < 1 or args.workers < 1:
        raise QmtInputError("--budget and --workers must be at least 1")
    out = Path(args.out or Path("out") / "design" / task.name)
    res, wall = run_all_types(task, method=args.method, workers=args.workers, seed=args.seed,
                              budget=args.budget, types=types)
    res = sorted(res, key=lambda r: -r.E_per_m)
    rows = ["| type | gene | E [1/m] | designs evaluated | wall [s] |", "|---|---|---|---|---|"]
    for r in res:
        rows.append(f"| {r.type_name} | {r.gene_hex} | {r.E_per_m:.6f} | {r.evaluations} | {r.wall_s:.1f} |")
        write_text_atomic(out / f"{r.type_name}.urdf", urdf_text(r.type_name, lengths6(r.genes)[0]))
    write_text_atomic(out / "table.md", f"# {task.name}: method {args.method}, wall {wall:.1f} s\n\n"
                      + "\n".join(rows) + "\n")
    write_text_atomic(out / "results.json", json.dumps(
        {"task": task.name, "method": args.method, "wall_s": wall,
         "results": [{"type": r.type_name, "gene": r.gene_hex, "E_per_m": r.E_per_m,
                      "lengths_m": lengths6(r.genes)[0].tolist(), "evaluations": r.evaluations,
                      "history_best_E": r.history_best_E} for r in res]}, indent=1) + "\n")
    print("\n".join(rows))
    print(f"best: {res[0].type_name} {res[0].gene_hex} E = {res[0].E_per_m:.6f} 1/m; wrote {out}",
          file=sys.stderr)
    return 0
