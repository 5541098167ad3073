"""Issue 27 item 6: every feature on every kind of arm, run, not claimed. For each kind (one built-in
scenario each) and each feature, the cheapest real command that exercises it runs in a fresh process
(short GA runs, few sweep cases, a per-cell timeout) and the cell is classified:

    ok       exit 0, or exit 3 with the plan file written (limits that no plan meets)
    refused  exit 2 and its message (one line: the CLI's QmtInputError or argparse's error)
    error    a traceback, a timeout, another exit code, or exit 0/3 without the expected output

    python -m studies.feature_matrix                 # out/feature_matrix.json + docs/features.md
    python -m studies.feature_matrix --fresh         # run every cell again (with --only: those)
    python -m studies.feature_matrix --only plan-ga --kinds ur5-suction-bins   # a few cells

The JSON is rewritten (atomically) after every cell, and a rerun skips the cells already in it, so an
interrupted run resumes (a cell whose command has changed since runs again). Commands are run as written in the table, with `qmt-drake` standing for
`python -m qmt_drake.apps.cli` and `python` for this interpreter, in a temporary folder; a cell that
needs a plan file (simulate, sweeps, retime, export, build_diagram) uses the kind's base plan, made once
per run (BASE below). A refusal is judged against JUDGEMENTS (physics, or a missing feature, and why);
a refusal whose message no judgement matches is listed as "not judged" for a reader to decide.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

from qmt_drake.outputs import write_text_atomic
from studies.feature_matrix_cells import (  # noqa: F401 - the study's names, used by its tests
    BASE_METHOD,
    CSV_SNIPPET,
    FEATURES,
    KINDS,
    METHODS,
    OUT_JSON,
    OUT_MD,
    ROOT,
    Cell,
    _plan_words,
    _py,
    all_cells,
    cell,
    scenario_copy,
    sweep_spec,
)
from studies.feature_matrix_report import JUDGEMENTS, judge, markdown, short  # noqa: F401
from studies.feature_matrix_run import (  # noqa: F401
    Result,
    _checkpoint_generation,
    check_evidence,
    classify,
    run_interrupted,
    run_step,
    run_steps,
)


def _prepare(c: Cell, d: Path, timeout: float) -> Result | None:
    """Write the cell's yaml/spec/csv files; a failure is the cell's result."""
    name = KINDS[c.kind][0]
    for fname, (what, arg) in c.prep.items():
        if what == "yaml":
            (d / fname).write_text(yaml.safe_dump(scenario_copy(name, arg), sort_keys=False))
        elif what == "sweep":
            (d / fname).write_text(yaml.safe_dump(sweep_spec(name, arg), sort_keys=False))
        elif what == "csv":
            rc, out, err, dt = run_step(_py(CSV_SNIPPET.format(name=name)), d, timeout)
            r = classify(rc, out, err, [] if (d / fname).exists() else [fname], dt, timeout)
            if r.status != "ok":
                r.message = f"preparing {fname} from the base plan: {r.message}"
                return r
    return None


class Bases:
    """The kind's base plan (BASE_METHOD), made once per run and copied into each cell's folder."""

    def __init__(self, root: Path, timeout: float):
        self.root, self.timeout, self.done = root, timeout, {}

    def get(self, kind: str) -> tuple[Path | None, Result]:
        if kind not in self.done:
            name, fam = KINDS[kind]
            d = self.root / f"base-{name}"
            d.mkdir(parents=True, exist_ok=True)
            argv = _plan_words(name, fam, BASE_METHOD[fam]) + ["--json", "base.json"]
            rc, out, err, dt = run_step(argv, d, self.timeout)
            r = classify(rc, out, err, [] if (d / "base.json").exists() else ["base.json"], dt, self.timeout)
            r.message = f"base plan `{' '.join(argv)}`: {r.status} {r.message}".strip()
            self.done[kind] = (d / "base.json" if r.status == "ok" else None, r)
        return self.done[kind]


def run_cell(c: Cell, root: Path, bases: Bases, timeout: float) -> dict:
    d = root / re.sub(r"[^\w.-]+", "_", c.key)
    d.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    res, steps = None, []
    if c.needs_base:
        path, base = bases.get(c.kind)
        if path is None:
            res = Result("error", base.rc, f"no base plan: {base.message}", 0.0, base.one_line)
        else:
            (d / "base.json").write_bytes(path.read_bytes())
    if res is None:
        res = _prepare(c, d, timeout)
    if res is None:
        res, steps = run_steps(c, d, timeout)
    return {"feature": c.feature, "kind": c.kind, "scenario": KINDS[c.kind][0], "command": c.shown(),
            "status": res.status, "rc": res.rc, "message": res.message, "one_line": res.one_line,
            "seconds": round(time.perf_counter() - t0, 2), "steps": steps}


def _commit() -> str:
    """The last commit that changed qmt_drake/ (what the matrix measures; a study's own commits do not count)."""
    try:
        return subprocess.run(["git", "log", "-1", "--format=%h", "--", "qmt_drake"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout.strip() or "?"
    except (OSError, subprocess.CalledProcessError):
        return "?"


def load_results(path: Path) -> dict:
    if not path.is_file():
        return {}
    try:
        return json.loads(path.read_text()).get("cells", {})
    except (OSError, ValueError):
        return {}


def save(path: Path, cells: dict, meta: dict) -> None:
    write_text_atomic(path, json.dumps({**meta, "cells": cells}, indent=1) + "\n")



def main(argv: list | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fresh", action="store_true", help="run the selected cells again even if in the JSON")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per step of a cell (default 300)")
    ap.add_argument("--only", nargs="*", help="features to run (substrings)")
    ap.add_argument("--kinds", nargs="*", help="kinds to run (column name or scenario)")
    ap.add_argument("--json", type=Path, default=OUT_JSON)
    ap.add_argument("--md", type=Path, default=OUT_MD)
    ap.add_argument("--keep", type=Path, help="run in this folder (kept) instead of a temporary one")
    args = ap.parse_args(argv)
    cells = load_results(args.json)
    todo = [c for c in all_cells()
            if (not args.only or any(s in c.feature for s in args.only))
            and (not args.kinds or c.kind in args.kinds or KINDS[c.kind][0] in args.kinds)]
    if args.fresh:
        cells = {k: v for k, v in cells.items() if k not in {c.key for c in todo}}
    meta = {"commit": _commit(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "timeout_s": args.timeout}
    n = len(todo)
    with tempfile.TemporaryDirectory(prefix="feature-matrix-") as tmp:
        root = args.keep or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        bases = Bases(root, args.timeout)
        for k, c in enumerate(todo, 1):
            if c.key in cells and cells[c.key].get("command") == c.shown():  # a changed command runs again
                print(f"[{k}/{n}] {c.kind:14s} {c.feature}: {cells[c.key]['status']} (in the JSON, skipped)",
                      file=sys.stderr, flush=True)
                continue
            row = run_cell(c, root, bases, args.timeout)
            cells[c.key] = {**row, "commit": meta["commit"], "timeout_s": args.timeout}
            save(args.json, cells, meta)
            print(f"[{k}/{n}] {c.kind:14s} {c.feature}: {row['status']} {row['seconds']:.1f} s "
                  f"{row['message'][:100]}", file=sys.stderr, flush=True)
    write_text_atomic(args.md, markdown(cells, meta))
    print(f"{args.json}, {args.md}: {len(cells)} cells", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
