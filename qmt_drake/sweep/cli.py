"""`qmt-drake sweep SPEC.yaml [--scheduler ADDR] [--out DIR] [--workers N]`.

On one machine nothing is needed: a LocalCluster with one single-threaded worker process per core
is started and stopped by the command. On several machines (each with this package installed,
`pip install -e .`, and the same scenario files if the spec names a path instead of a built-in):

    scheduler host:   dask scheduler --port 8786                # prints tcp://HOST:8786
    each worker host: dask worker tcp://HOST:8786 --nthreads 1 --nworkers auto
    your machine:     qmt-drake sweep SPEC.yaml --scheduler tcp://HOST:8786

Only the client (your machine) writes results, so no shared file system is needed; results land in
OUT/<name>/cases/ as they finish and a rerun submits only the missing ones. On a user's cluster
the retry count after a worker's death is the scheduler's own `distributed.scheduler.allowed-failures`
(set it where the scheduler starts, e.g. DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES=3), and
`distributed.scheduler.worker-saturation: 1.0` keeps a dying worker from taking queued cases with it.

`add_parser(subparsers)` adds the sub-command to qmt_drake/cli.py's parser; `cmd_sweep(args)` runs
it (exit 0: every case finished; 4: some cases failed after Dask's retries, a rerun retries only
those; bad input raises QmtInputError, which the main CLI prints as one line with exit 2).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from qmt_drake.budgets import announce, check_budget
from qmt_drake.config.resolve import SPATIAL, kind_of
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import check_output_dir, check_output_path, write_text_atomic
from qmt_drake.sweep.budget import estimate_spatial_sweep, estimate_sweep
from qmt_drake.sweep.cluster import DEFAULT_DASHBOARD_ADDRESS, check_dashboard_address
from qmt_drake.sweep.runner import check_scheduler_address, format_table, run_sweep
from qmt_drake.sweep.spec import load_spec
from qmt_drake.transfer_scenario import load_scenario

EXIT_CASES_FAILED = 4  # qmt_drake.apps.cli.EXIT_SIMULATION
MAX_WORKERS = 256  # LocalCluster processes
MAX_ALLOWED_FAILURES = 100


def add_parser(subparsers):
    s = subparsers.add_parser(
        "sweep", help="run a grid / Monte Carlo sweep of co-simulated transfers on Dask",
        description="Run every case of SPEC.yaml (see models/sweeps/) on a Dask LocalCluster or on "
                    "the scheduler given by --scheduler; finished cases are stored under "
                    "OUT/<name>/cases/ and skipped by a rerun.")
    s.add_argument("spec", metavar="SPEC.yaml", help="sweep specification (YAML)")
    s.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="a running Dask scheduler (default: a LocalCluster on this machine)")
    s.add_argument("--out", default="out", help="output folder (default: out); results in OUT/<name>/")
    s.add_argument("--dashboard", metavar="HOST:PORT", default=DEFAULT_DASHBOARD_ADDRESS,
                   help="the LocalCluster's Dask dashboard (default 127.0.0.1:0: this machine only, a free port)")
    s.add_argument("--workers", type=int, default=None,
                   help="LocalCluster worker processes, one thread each (default: one per core)")
    s.add_argument("--allowed-failures", type=int, default=3,
                   help="times a case is resubmitted after its worker died (LocalCluster only)")
    s.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    s.add_argument("--quiet", action="store_true", help="no progress line")
    s.add_argument("--json", metavar="PATH|-", help="also write the run's counts and summary rows as JSON")
    s.add_argument("--allow-large", action="store_true",
                   help="run even if the estimate is over the memory and time budget (qmt_drake/budgets.py)")
    s.set_defaults(func=cmd_sweep)
    return s


def cmd_sweep(args) -> int:
    """Every input first (options, spec, scheduler address, budget, output paths), then the run."""
    if args.workers is not None and not 1 <= args.workers <= MAX_WORKERS:
        raise QmtInputError(f"--workers must be between 1 and {MAX_WORKERS}, got {args.workers}")
    if not 0 <= args.allowed_failures <= MAX_ALLOWED_FAILURES:
        raise QmtInputError(f"--allowed-failures must be between 0 and {MAX_ALLOWED_FAILURES}, got "
                            f"{args.allowed_failures}")
    if args.scheduler is not None:
        check_scheduler_address(args.scheduler)
    check_dashboard_address(args.dashboard)
    if not str(args.out).strip():
        raise QmtInputError("--out: empty path; give a folder")
    spec = load_spec(args.spec)
    workers = args.workers or os.cpu_count() or 1
    if kind_of(spec.scenario) == SPATIAL:  # checked in full when its cases are built (sweep/spatial_cases.py)
        est = estimate_spatial_sweep(spec, workers)
    else:
        est = estimate_sweep(spec, load_scenario(spec.scenario), workers)
    est = check_budget(est, allow_large=args.allow_large)
    check_output_dir(Path(args.out) / spec.name, "--out")
    check_output_path(args.json, "--json")
    announce(est)
    out = run_sweep(spec, args.out, scheduler=args.scheduler, workers=args.workers,
                    allowed_failures=args.allowed_failures, progress=not args.quiet,
                    figures=not args.no_figures, dashboard_address=args.dashboard)
    print(format_table(out["rows"], list(spec.grid)))
    rate = f", {out['cases_per_min']:.1f} cases/min" if out["cases_per_min"] else ""
    print(f"{out['cases']} cases: {out['from_store']} from the store, {out['computed']} computed, "
          f"{out['failed']} failed{rate}; results in {out['out_dir']}/")
    for f in out["failures"][:10]:
        print(f"failed: {f.get('label', f.get('plan', ''))}: {f['error']}", file=sys.stderr)
    if args.json:
        data = {k: v for k, v in out.items() if k != "results"}
        text = json.dumps(data, indent=1, default=str)
        if args.json == "-":
            print(text)
        else:
            write_text_atomic(args.json, text + "\n")
    return EXIT_CASES_FAILED if out["failed"] else 0
