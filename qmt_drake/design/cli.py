"""`qmt-drake design TASK.yaml`: choose the joint combination and link lengths for a task (seed 003).

The lead wires `add_parser(subparsers)` into qmt_drake/cli.py; `cmd_design(args)` returns the exit
code (bad input raises QmtInputError before any long computation; the CLI maps it to exit 2): the task
file, every option, the memory and time estimate (budgets.py; --allow-large to exceed it) and the
output folder (created and probed) are checked before the search starts.
Writes OUT/results.json, OUT/table.md and OUT/<type>.urdf for every type's best design.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from qmt_drake.budgets import announce, check_budget, design_estimate
from qmt_drake.design.arm_types import TYPES, check_levels, check_type, levels_from_gene, urdf_text
from qmt_drake.design.problem import BRANCH_MODES, DesignProblem, genes_from_levels, lengths6
from qmt_drake.design.search import METHODS, run_all_types
from qmt_drake.design.tasks import load_task
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic

MAX_WORKERS = 256


def add_parser(subparsers):
    p = subparsers.add_parser("design", help="choose arm type and link lengths for a task by "
                                             "operability (seed 003)")
    p.add_argument("task", help="task YAML (or a name in models/tasks/)")
    p.add_argument("--types", default="all", help="comma-separated types (BP,BB,...) or 'all'")
    p.add_argument("--method", default="auto", choices=METHODS,
                   help="ga: the project's GA (seed 003 settings); exhaustive: every design; "
                        "auto: ga")
    p.add_argument("--branch", default="task", choices=BRANCH_MODES,
                   help="IK branch choice: task = one branch label for every unit task, the best "
                        "over the whole task (the seed's); point = the best branch at each point")
    p.add_argument("--design", default=None, metavar="TYPE:GENE",
                   help="evaluate one design instead of searching, e.g. BP:0db000 (six hex digits) or "
                        "BP:0,13,11,0,0,0 (six levels 0-15 of L1..L6; L5 must be 0)")
    p.add_argument("--workers", type=int, default=2, help="parallel processes (one type each)")
    p.add_argument("--generations", default="400,100", metavar="MAX,STALL",
                   help="GA: at most MAX generations, stop after STALL without improvement (0: never)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-obstacles", action="store_true", help="drop the task's obstacles")
    p.add_argument("--out", default=None, help="output folder (default out/design/<task name>)")
    p.add_argument("--allow-large", action="store_true",
                   help="run even if the estimate is over the memory and time budget (qmt_drake/budgets.py)")
    p.set_defaults(func=cmd_design)
    return p


def _types(arg: str):
    if arg.strip().lower() == "all":
        return TYPES
    out = tuple(check_type(t.strip()) for t in arg.split(",") if t.strip())
    bad = [t for t in out if t not in TYPES]
    if bad or not out:
        raise QmtInputError(f"--types {arg!r}: {', '.join(bad) or 'empty'} not among the seed's ten "
                            f"types {', '.join(TYPES)}")
    return out


def _generations(arg: str) -> tuple:
    try:
        mx, st = (int(x) for x in str(arg).split(","))
    except (ValueError, OverflowError):
        raise QmtInputError(f"--generations {arg!r}: give MAX,STALL as two integers, e.g. 400,100") from None
    if mx < 1 or st < 0:
        raise QmtInputError(f"--generations {arg!r}: MAX must be >= 1 and STALL >= 0")
    return mx, st


def parse_design(arg: str):
    """'BP:0db000' or 'BP:0,13,11,0,0,0' -> (type, levels (6,)); bad input -> QmtInputError."""
    t, sep, g = str(arg).partition(":")
    if not sep or not g.strip():
        raise QmtInputError(f"--design {arg!r}: give TYPE:GENE, e.g. BP:0db000 or BP:0,13,11,0,0,0")
    t = check_type(t.strip())
    if "," in g:
        try:
            lv = [float(x) for x in g.split(",")]
        except ValueError:
            raise QmtInputError(f"--design {arg!r}: levels must be six integers 0-15 separated by commas") from None
        lv = check_levels(lv)
    else:
        lv = levels_from_gene(g)
    if lv[4] != 0:
        raise QmtInputError(f"--design {arg!r}: L5 (level {lv[4]}) must be 0: the wrist is spherical "
                            "(analytic IK; every gene of the seed's tables has L5 = 0)")
    return t, lv


def cmd_design(args) -> int:

    if args.out is not None and not str(args.out).strip():
        raise QmtInputError("--out: empty path; give a folder")
    task = load_task(args.task)
    if args.no_obstacles:
        task = task.without_obstacles()
    types = _types(args.types)
    if not 1 <= args.workers <= MAX_WORKERS:
        raise QmtInputError(f"--workers {args.workers}: must be between 1 and {MAX_WORKERS} (one process "
                            "per arm type)")
    if not 0 <= args.seed < 2 ** 63:
        raise QmtInputError(f"--seed {args.seed}: seeds are integers in [0, 2^63)")
    gens = _generations(args.generations)
    out = Path(args.out or Path("out") / "design" / task.name)
    if args.design:
        design = parse_design(args.design)
        check_output_dir(out, "--out")
        return _evaluate_one(task, args, out, design)
    est = check_budget(design_estimate(method="exhaustive" if args.method == "exhaustive" else "ga",
                                       types=len(types), units=len(task.units), generations=gens[0],
                                       workers=args.workers), allow_large=args.allow_large)
    check_output_dir(out, "--out")
    announce(est)
    res, wall = run_all_types(task, method=args.method, workers=min(args.workers, len(types)), seed=args.seed,
                              types=types, branch=args.branch, ga_generations=gens,
                              progress=lambda line: print(line, file=sys.stderr, flush=True))
    res = sorted(res, key=lambda r: -r.E_per_m)
    rows = ["| type | gene | E [1/m] | designs evaluated | wall [s] |", "|---|---|---|---|---|"]
    for r in res:
        rows.append(f"| {r.type_name} | {r.gene_hex} | {r.E_per_m:.6f} | {r.evaluations} | {r.wall_s:.1f} |")
        write_text_atomic(out / f"{r.type_name}.urdf", urdf_text(r.type_name, lengths6(r.genes)[0]))
    write_text_atomic(out / "table.md", f"# {task.name}: method {args.method}, branch {args.branch}, wall {wall:.1f} s\n\n"
                      + "\n".join(rows) + "\n")
    write_text_atomic(out / "results.json", json.dumps(
        {"task": task.name, "method": args.method, "branch": args.branch, "wall_s": wall,
         "results": [{"type": r.type_name, "gene": r.gene_hex, "E_per_m": r.E_per_m,
                      "lengths_m": lengths6(r.genes)[0].tolist(), "evaluations": r.evaluations,
                      "history_best_E": r.history_best_E} for r in res]}, indent=1) + "\n")
    print("\n".join(rows))
    print(f"best: {res[0].type_name} {res[0].gene_hex} E = {res[0].E_per_m:.6f} 1/m; wrote {out}",
          file=sys.stderr)
    return 0


def _evaluate_one(task, args, out: Path, design) -> int:
    """--design TYPE:GENE: E of one design on the task (with its branch and every unit task)."""
    t, lv = design
    pr = DesignProblem(task, t, branch=args.branch)
    g = genes_from_levels(lv)
    det = pr.details(g)
    write_text_atomic(out / f"{t}_{det['gene']}.json", json.dumps(jsonable(det), indent=1) + "\n")
    write_text_atomic(out / f"{t}_{det['gene']}.urdf", urdf_text(t, lengths6(g)[0]))
    for u in det["units"]:
        print(f"{u['name']}: " + (f"mu {u['mu']:.6f}" if u["reachable"] else "unreachable"))
    print(f"{t} {det['gene']}: E = {det['E_per_m']:.6f} 1/m (branch {args.branch}, label "
          f"{det['branch_label']}); wrote {out}")
    return 0
