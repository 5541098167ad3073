"""Run a sweep on Dask's distributed scheduler, resumably.

`run_sweep(spec, out)`:
  1. validates the spec and builds every case (plain data, cases.py) before starting anything;
  2. skips the cases whose result is already in the store (store.py); with none left, no cluster
     is started at all;
  3. connects (cluster.py): a LocalCluster with one single-threaded worker process per core by
     default, or the scheduler at `--scheduler tcp://HOST:PORT` (an unreachable address is a
     one-line QmtInputError after `connect_timeout_s`);
  4. plans each distinct plan once (a GA takes seconds; its document is stored under plans/ and
     shared by every case that uses it), then submits the cases;
  5. writes each result atomically as it arrives, so a crash of the client, a worker or the
     machine loses only the cases still running; a rerun picks up the rest.

Worker deaths: the scheduler resubmits a task whose worker died up to
`distributed.scheduler.allowed-failures` times (set here for a local cluster; a user's scheduler
uses its own configuration) and then gives up with KilledWorker; such a case runs once more alone
(it may only have shared the worker with the case that killed it), and if it kills its worker
again it is reported as failed, written nowhere, and retried by the next run. Exceptions other than a failed simulation (which
run_case returns as status 'sim_failed') are reported the same way.

Progress: one line on stderr (rewritten in place on a terminal). At the end: summary.json,
summary.md (success probability per plan and grid point with Wilson intervals) and figures.
"""

from __future__ import annotations

import json
import sys
import time
import uuid
from contextlib import contextmanager
from pathlib import Path

from qmt_drake.config.resolve import SPATIAL, kind_of
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import jsonable
from qmt_drake.sweep.cases import build_cases, make_plan_doc, run_case
from qmt_drake.sweep.cluster import (
    CONNECT_TIMEOUT_S,
    DEFAULT_ALLOWED_FAILURES,
    DEFAULT_DASHBOARD_ADDRESS,
    check_dashboard_address,
    check_scheduler_address,
    dask_client,
    probe_scheduler,
)
from qmt_drake.sweep.figures import write_figures
from qmt_drake.sweep.spatial_cases import build_spatial_cases, make_spatial_plan_doc, run_spatial_case
from qmt_drake.sweep.spec import SweepSpec, describe_uncertainty, load_spec
from qmt_drake.sweep.stats import success_rows
from qmt_drake.sweep.store import SweepStore


# ------------------------------------------------------------------------------------- progress
class Progress:
    """One progress line on stderr: rewritten in place on a terminal, else printed every few s."""

    def __init__(self, name: str, total: int, stored: int, stream=None, enabled: bool = True) -> None:
        self.name, self.total, self.stored = name, total, stored
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.done = self.failed = 0
        self.t0 = time.perf_counter()
        self._last = 0.0

    def update(self, ok: bool, force: bool = False) -> None:
        if ok:
            self.done += 1
        else:
            self.failed += 1
        self.show(force)

    def show(self, force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if not force and now - self._last < (0.5 if self.tty else 5.0):
            return
        self._last = now
        el = now - self.t0
        left = self.total - self.stored - self.done - self.failed
        rate = self.done / el if el > 0 else 0.0
        eta = f", ETA {left / rate:.0f} s" if rate > 0 and left else ""
        line = (f"sweep {self.name}: {self.stored + self.done}/{self.total} cases done "
                f"({self.stored} from the store, {self.failed} failed), {rate * 60:.1f} cases/min{eta}")
        if self.tty:
            self.stream.write("\r" + line + "\033[K" + ("\n" if force else ""))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()


# ----------------------------------------------------------------------------------------- run
def run_sweep(spec: SweepSpec | str | Path | dict, out_dir: str | Path = "out", *, scheduler: str | None = None,
              workers: int | None = None, allowed_failures: int = DEFAULT_ALLOWED_FAILURES,
              case_fn=None, plan_fn=None, progress: bool = True, figures: bool = True,
              connect_timeout_s: float = CONNECT_TIMEOUT_S, client=None,
              dashboard_address: str = DEFAULT_DASHBOARD_ADDRESS) -> dict:
    """Run every case of `spec` not yet in <out_dir>/<spec.name>/ and summarise all of them.

    case_fn(case, plan_doc) -> dict and plan_fn(plan_ref) -> dict run in the workers (tests inject
    cheap ones; default: the planar ones of cases.py, or spatial_cases.py's for a spatial scenario); `client` reuses an open distributed.Client (scheduler/workers are then ignored);
    dashboard_address: the LocalCluster's dashboard (default 127.0.0.1, a free port).
    Returns a dict: counts (cases, from_store, computed, failed), failures, wall times, cases per
    minute of the case phase, the summary rows and the paths written."""
    if not isinstance(spec, SweepSpec):
        spec = load_spec(spec)
    if scheduler:
        check_scheduler_address(scheduler)
    check_dashboard_address(dashboard_address)
    if workers is not None and int(workers) < 1:
        raise QmtInputError(f"--workers must be >= 1, got {workers}")
    store = SweepStore(Path(out_dir) / spec.name)
    t_start = time.perf_counter()
    spatial = kind_of(spec.scenario) == SPATIAL  # the same store and runner, the spatial co-simulation
    cases, plan_refs = (build_spatial_cases if spatial else build_cases)(spec)
    case_fn = case_fn or (run_spatial_case if spatial else run_case)
    plan_fn = plan_fn or (make_spatial_plan_doc if spatial else make_plan_doc)
    keys = [c.key for c in cases]
    if len(set(keys)) != len(keys):
        # Two cases with equal inputs (e.g. a spread of 0 drawn twice) are one simulation.
        unique = {}
        for c in cases:
            unique.setdefault(c.key, c)
        cases = list(unique.values())
    finished = store.finished_keys()
    pending = [c for c in cases if c.key not in finished]
    if pending and scheduler and client is None:  # before anything is written
        probe_scheduler(check_scheduler_address(scheduler), connect_timeout_s)
    store.write_text("spec.json", json.dumps(jsonable({"name": spec.name, "raw": spec.raw,
                                                       "n_cases": len(cases)}), indent=1))
    prog = Progress(spec.name, len(cases), len(cases) - len(pending), enabled=progress)
    failures: list[dict] = []  # cases that finished nowhere (and plans that failed)
    case_wall = 0.0
    computed = 0
    workers_used = None
    if pending:
        needed = {c.plan_key for c in pending}
        with (_reuse(client) if client is not None else
              dask_client(scheduler, workers, allowed_failures=allowed_failures,
                          connect_timeout_s=connect_timeout_s, dashboard_address=dashboard_address)) as cl:
            workers_used = len(cl.scheduler_info().get("workers", {}))
            docs = _plan_phase(cl, store, {k: plan_refs[k] for k in needed}, plan_fn, failures)
            prog.show(force=True)
            t_cases = time.perf_counter()
            computed = _case_phase(cl, store, pending, docs, case_fn, failures, prog)
            case_wall = time.perf_counter() - t_cases
        prog.show(force=True)
    results = [r for r in (store.read_case(c.key) for c in cases) if r is not None]
    summary = summarize(spec, store, results, failures, figures=figures)
    failed = sum(1 for f in failures if "key" in f)
    return dict(name=spec.name, out_dir=str(store.root), cases=len(cases), from_store=len(cases) - len(pending),
                computed=computed, failed=failed, failures=failures, workers=workers_used,
                case_phase_wall_s=case_wall, wall_s=time.perf_counter() - t_start,
                cases_per_min=computed / case_wall * 60 if case_wall > 0 else None,
                rows=summary["rows"], results=results, paths=summary["paths"])


@contextmanager
def _reuse(client):
    yield client


def _plan_phase(cl, store: SweepStore, refs: dict, plan_fn, failures: list) -> dict:
    """Plan documents by plan key: from the store, else planned in the workers and stored."""
    docs, futs = {}, {}
    for k, ref in refs.items():
        doc = store.read_plan(k)
        if doc is not None:
            docs[k] = doc
        else:
            futs[cl.submit(plan_fn, ref, key=f"plan-{k[:16]}-{uuid.uuid4().hex[:8]}", pure=False)] = k
    try:
        finished = list(_completed_while_workers_live(cl, list(futs)))
    except RuntimeError as exc:  # no worker left: the plans not made fail their cases; a rerun resumes
        finished = [f for f in futs if f.done()]
        for f in futs.keys() - set(finished):
            failures.append({"plan_key": futs[f], "plan": _describe_ref(refs[futs[f]]), "error": str(exc)})
    for fut in finished:
        k = futs[fut]
        try:
            doc = fut.result()
        except QmtInputError as exc:
            raise QmtInputError(f"plan {_describe_ref(refs[k])}: {exc}") from None
        except Exception as exc:  # noqa: BLE001 - one plan's failure fails its cases, not the sweep
            failures.append({"plan_key": k, "plan": _describe_ref(refs[k]),
                             "error": f"planning failed: {type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"})
            continue
        store.write_plan(k, doc)
        docs[k] = doc
    return docs


def _identity(x):
    return x


def _describe_ref(ref) -> str:
    return ref.file or f"{ref.method} (seed {ref.seed}, options {ref.options})"


def _case_phase(cl, store: SweepStore, pending: list, docs: dict, case_fn, failures: list, prog: Progress) -> int:
    """Submit the pending cases, store each result as it arrives; returns how many were stored."""
    # Plan documents enter the graph as the result of a task, not scattered: data scattered to a
    # worker that dies is gone for good, a task's result is recomputed from its inputs.
    doc_futs = {k: cl.submit(_identity, d, key=f"plandoc-{k[:16]}-{uuid.uuid4().hex[:8]}", pure=False)
                for k, d in docs.items()}
    futs, stored = {}, 0
    for c in pending:
        if c.plan_key not in doc_futs:
            failures.append({"key": c.key, "label": c.label, "error": "its plan failed"})
            prog.update(False)
            continue
        f = cl.submit(case_fn, c, doc_futs[c.plan_key], key=f"case-{c.key[:16]}-{uuid.uuid4().hex[:8]}",
                      pure=False)
        futs[f] = c
    suspects = []  # cases given up after worker deaths: perhaps only co-located with the killer
    try:
        for fut in _completed_while_workers_live(cl, list(futs)):
            c = futs.pop(fut)
            try:
                res = fut.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker after allowed-failures, or a bug in the case
                if type(exc).__name__ == "KilledWorker":
                    suspects.append(c)
                    continue
                _record_failure(failures, c, exc, prog)
                continue
            stored += _store_result(store, c, res, prog)
            fut.release()
    except RuntimeError as exc:  # no worker left: every unfinished case is failed, a rerun resumes them
        for c in [*futs.values(), *suspects]:
            _record_failure(failures, c, exc, prog)
        return stored
    # The scheduler assigns a case to a worker before the worker is free (cases depend on the plan
    # document, so they are not queued centrally), so an innocent case can share a dying worker.
    # Each suspect runs once more alone: only a case that kills its worker by itself fails.
    for c in suspects:
        fut = cl.submit(case_fn, c, doc_futs[c.plan_key], key=f"case-{c.key[:16]}-{uuid.uuid4().hex[:8]}",
                        pure=False)
        try:
            res = _result_while_workers_live(cl, fut)
        except Exception as exc:  # noqa: BLE001 - as above
            _record_failure(failures, c, exc, prog)
            continue
        stored += _store_result(store, c, res, prog)
        fut.release()
    return stored


NO_WORKER_S = 120.0  # how long a case waits on a cluster with no worker at all before it is failed


def _completed_while_workers_live(cl, futures, poll_s: float = 5.0, no_worker_s: float = NO_WORKER_S):
    """Yield `futures` as they finish (as distributed.as_completed), but not forever: a cluster that has
    lost every worker (a LocalCluster whose nannies could not restart a killed worker, seen under heavy
    load) would leave the sweep waiting for good; after no_worker_s [s] without a worker and without a
    finished future, RuntimeError (the caller fails what is unfinished; a rerun resumes it)."""
    # lazy: Dask (~0.4 s) only when a sweep runs
    from distributed import as_completed
    finished = as_completed(list(futures), loop=cl.loop)
    without, tick = 0.0, min(0.05, poll_s)  # tick [s]: how often finished futures are looked for
    while not finished.is_empty():
        waited = 0.0
        while waited < poll_s and not finished.has_ready():
            time.sleep(tick)
            waited += tick
        if finished.has_ready():
            without = 0.0
            yield from finished.next_batch(block=False)
            continue
        without = 0.0 if cl.scheduler_info().get("workers") else without + poll_s
        if without >= no_worker_s:
            raise RuntimeError(f"no Dask worker alive for {no_worker_s:g} s; run the sweep again to resume")


def _result_while_workers_live(cl, fut, poll_s: float = 5.0, no_worker_s: float = NO_WORKER_S):
    """fut.result(), waiting only while the cluster has a worker (`_completed_while_workers_live`)."""
    for done in _completed_while_workers_live(cl, [fut], poll_s, no_worker_s):
        return done.result()


def _record_failure(failures: list, c, exc: BaseException, prog: Progress) -> None:
    failures.append({"key": c.key, "label": c.label, "index": c.index,
                     "error": f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"})
    prog.update(False)


def _store_result(store: SweepStore, c, res: dict, prog: Progress) -> int:
    store.write_case(c.key, res)
    prog.update(True)
    return 1


# ------------------------------------------------------------------------------------ summary
CARRIED_MEANS = ("the co-simulation's outcome 'carried' (qmt_drake/outcome.py): the part on the hand at the "
                 "end, never lost, slip below the hand's limit, the arm at its goal")

def summarize(spec: SweepSpec, store: SweepStore, results: list[dict], failures: list, *,
              figures: bool = True) -> dict:
    groups = ("label",) + tuple(spec.grid)
    rows = success_rows(results, groups)
    paths = {}
    data = {"name": spec.name, "scenario": spec.scenario, "description": spec.description,
            "uncertainty": spec.uncertainty or describe_uncertainty(spec),
            "uncertainty_drawn": describe_uncertainty(spec), "monte_carlo_cases": spec.mc_cases,
            "monte_carlo_seed": spec.mc_seed, "carried_means": CARRIED_MEANS,
            "cases": len(results), "failures": failures, "rows": rows}
    paths["summary.json"] = str(store.write_text("summary.json", json.dumps(jsonable(data), indent=1)))
    paths["summary.md"] = str(store.write_text("summary.md", summary_markdown(spec, rows, failures)))
    if figures and results:
        paths.update(write_figures(spec, store.root, results, rows))
    return {"rows": rows, "paths": paths}


def summary_markdown(spec: SweepSpec, rows: list[dict], failures: list) -> str:
    grid = list(spec.grid)
    lines = [f"# Sweep {spec.name}", "", f"Scenario {spec.scenario}. Uncertainty: "
             f"{spec.uncertainty or describe_uncertainty(spec)}.", "",
             f"Carried = {CARRIED_MEANS}; interval: Wilson score, "
             f"{int(round(rows[0]['confidence'] * 100)) if rows else 95}%.", "",
             "| plan | " + "".join(f"{g} | " for g in grid) + "motion time [s] | cases | carried | "
             "P(carried) | interval | median slip [mm] |",
             "|" + "---|" * (7 + len(grid))]
    for r in rows:
        T = "—" if r["motion_time_s"] is None else f"{r['motion_time_s']:.4f}"
        slip = "—" if r["median_slip_m"] is None else f"{r['median_slip_m'] * 1e3:.3f}"
        lines.append(f"| {r['label']} | " + "".join(f"{r[g]:g} | " for g in grid)
                     + f"{T} | {r['n']} | {r['carried']} | {r['p']:.3f} | "
                     f"[{r['ci_low']:.3f}, {r['ci_high']:.3f}] | {slip} |")
    if failures:
        lines += ["", f"{len(failures)} case(s) failed and are not in the table (a rerun retries them):"]
        lines += [f"- {f.get('label', f.get('plan', ''))}: {f['error']}" for f in failures[:20]]
    return "\n".join(lines) + "\n"


def format_table(rows: list[dict], grid=()) -> str:
    """A plain-text table of the summary rows (for the terminal)."""
    out = [f"{'plan':24s} " + "".join(f"{g:>12s} " for g in grid) + f"{'T [s]':>8s} {'n':>5s} {'carried':>8s} "
           f"{'P':>6s}  interval"]
    for r in rows:
        T = "-" if r["motion_time_s"] is None else f"{r['motion_time_s']:.4f}"
        out.append(f"{r['label'][:24]:24s} " + "".join(f"{r[g]:12g} " for g in grid)
                   + f"{T:>8s} {r['n']:5d} {r['carried']:8d} {r['p']:6.3f}  [{r['ci_low']:.3f}, {r['ci_high']:.3f}]")
    return "\n".join(out)
