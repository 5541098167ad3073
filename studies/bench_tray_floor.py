"""Tray co-simulation cost per plant step against a floor of Drake primitives, side by side, and the
resident memory over many runs (issue 20).

    .venv/bin/python -m studies.bench_tray_floor --out out [--runs 200] [--repeats 3] [--trim] [--tracemalloc]

ours      the default tray diagram (tray/cosim.build_tray_diagram: compiled servo law and motors,
          loggers of plant and primitive ports every 5 ms; the bottle's motion is derived from its
          logged joint state after the run, so no Python system is in the diagram)
python    the same with the Python DynamixelPositionServo and DcMotorWithGear (one call per period)
floor     the default diagram with no monitor and no loggers: the plant, the goal source, the servo
          law and the motors only, all Drake primitives
Each variant simulates the same shaped TOPP-RA transfer (crane-tray, x1.1) `repeats` times, fresh
diagram each time, interleaved; the table gives the best wall time per plant step and the ratio to
the floor. Then `runs` short transfers in one process record, every 20 runs, the resident set size
(RSS), the bytes glibc's heap has handed out and not got back (mallinfo2 uordblks + hblkhd: grows
only if something is kept, a leak) and the number of Python objects the collector tracks (after a
gc.collect()). RSS can also grow without a leak, as freed memory fragments the heap until the pattern
repeats (qmt_drake/malloc_tuning.py keeps up to 256 MiB of freed memory mapped); --trim calls glibc's
malloc_trim(0) after every run to tell the two apart; --tracemalloc also records the memory Python
itself holds (tracemalloc, started before the loop; it slows the runs). The JSON's `rss_plateau` fits the slope of RSS
and of the heap in use over the last half of the runs and calls it a plateau when RSS grew by less
than PLATEAU_MIB over that half. Prints the figures and writes OUT/bench_tray_floor.json (atomic).
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import json
import resource
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pydrake.systems.analysis import Simulator  # noqa: E402

import qmt_drake.tray.cosim as cosim  # noqa: E402
from qmt_drake import load_scenario, malloc_tuning, plan_with  # noqa: E402
from qmt_drake.outputs import check_output_dir, write_text_atomic  # noqa: E402
from qmt_drake.tray.execute import plan_schedule  # noqa: E402

RSS_EVERY = 20  # runs between samples
PLATEAU_MIB = 1.0  # RSS growth over the last half of the runs below this: a plateau


class _MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                "fsmblks", "uordblks", "fordblks", "keepcost")]


def _libc():
    """glibc with mallinfo2 (2.33+) and malloc_trim, or None (another libc: heap figures left out)."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallinfo2.restype = _MallInfo2
        libc.malloc_trim.argtypes = [ctypes.c_size_t]
    except (OSError, AttributeError):
        return None
    return libc


LIBC = _libc()


def heap_mib() -> dict:
    """glibc's main-arena heap [MiB]: in use (handed out, incl. mmapped blocks), free inside it, its size."""
    if LIBC is None:
        return {}
    m = LIBC.mallinfo2()
    return {"heap_in_use_mib": (m.uordblks + m.hblkhd) / 2**20, "heap_free_mib": m.fordblks / 2**20,
            "heap_arena_mib": m.arena / 2**20}


def slope_per_run(rows: list[dict], key: str, first_run: int) -> float | None:
    """Least-squares slope of rows[key] against the run number over runs >= first_run [unit / run]."""
    pts = [(r["run"], r[key]) for r in rows if r["run"] >= first_run and key in r]
    if len(pts) < 2:
        return None
    k, v = np.array(pts, float).T
    return float(np.polyfit(k, v, 1)[0])


def rss_plateau(rows: list[dict], runs: int) -> dict:
    """Slopes of RSS and heap in use over the last half of the runs, and whether RSS plateaued there."""
    half = (runs // 2 // RSS_EVERY) * RSS_EVERY
    tail = [r for r in rows if r["run"] >= half]
    growth = tail[-1]["rss_mib"] - tail[0]["rss_mib"] if len(tail) > 1 else None
    rss_slope = slope_per_run(rows, "rss_mib", half)
    heap_slope = slope_per_run(rows, "heap_in_use_mib", half)
    traced_slope = slope_per_run(rows, "python_traced_mib", half)
    return {"from_run": half, "to_run": runs, "rss_growth_mib": growth, "rss_slope_mib_per_run": rss_slope,
            "heap_in_use_slope_kib_per_run": None if heap_slope is None else heap_slope * 1024,
            "python_traced_slope_kib_per_run": None if traced_slope is None else traced_slope * 1024,
            "python_objects_growth": (tail[-1]["python_objects"] - tail[0]["python_objects"]) if len(tail) > 1 else None,
            "plateau_mib": PLATEAU_MIB, "plateau": growth is not None and growth < PLATEAU_MIB}


def _rss_mib() -> float:
    """Current resident set size [MiB] (from /proc; ru_maxrss is the peak)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_once(sched, sc, variant: str) -> float:
    act = sc.actuator
    kw = dict(servo_period_s=act.control_period_s)
    if variant == "python":
        kw["compiled_servo"] = False
    if variant == "floor":
        kw["log_period_s"] = 0.0
    td = cosim.build_tray_diagram(sched, act.gains(), sc.bottle, **kw)
    sim = Simulator(td.diagram)
    cosim.set_initial_state(td, sim.get_mutable_context())
    sim.Initialize()
    t0 = time.perf_counter()
    sim.AdvanceTo(sched.t_end_s)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    tuned = malloc_tuning.tune()  # as the command line does (qmt_drake/malloc_tuning.py)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--trim", action="store_true", help="malloc_trim(0) after every run of the RSS loop")
    ap.add_argument("--tracemalloc", action="store_true", help="record Python's traced memory in the RSS loop")
    args = ap.parse_args(argv)
    if args.runs < 2 * RSS_EVERY or args.repeats < 1:
        print(f"--runs {args.runs} / --repeats {args.repeats}: give --runs >= {2 * RSS_EVERY} and --repeats >= 1",
              file=sys.stderr)
        return 2
    check_output_dir(args.out, "--out")
    out = Path(args.out)
    sc = load_scenario("crane-tray")
    plan = plan_with("toppra", sc)
    sched = plan_schedule(plan, time_scale=1.1, period_s=sc.actuator.control_period_s, shaped_for=sc)
    steps = sched.t_end_s / cosim.TIME_STEP_S
    walls = {v: [] for v in ("ours", "python", "floor")}
    for _ in range(args.repeats):
        for v in walls:
            walls[v].append(run_once(sched, sc, v))
    us = {v: 1e6 * min(w) / steps for v, w in walls.items()}
    rows = {v: {"us_per_step": us[v], "ratio_to_floor": us[v] / us["floor"],
                "real_time_factor": sched.t_end_s / min(walls[v])} for v in walls}
    for v, r in rows.items():
        print(f"{v:7s} {r['us_per_step']:8.1f} us/step  x{r['ratio_to_floor']:.3f} of the floor  "
              f"real-time factor {r['real_time_factor']:.2f}", flush=True)
    short = plan_schedule(plan, time_scale=1.1, period_s=sc.actuator.control_period_s, shaped_for=sc,
                          settle_s=0.05, tail_s=0.05)
    rss = []
    if args.tracemalloc:
        tracemalloc.start()
    for k in range(args.runs + 1):
        if k % RSS_EVERY == 0:
            gc.collect()
            rss.append({"run": k, "rss_mib": _rss_mib(), **heap_mib(), "python_objects": len(gc.get_objects())})
            if args.tracemalloc:
                rss[-1]["python_traced_mib"] = tracemalloc.get_traced_memory()[0] / 2**20
            print(f"run {k}: RSS {rss[-1]['rss_mib']:.1f} MiB, heap in use {rss[-1].get('heap_in_use_mib', 0):.2f} "
                  f"MiB, {rss[-1]['python_objects']} Python objects", flush=True)
        if k < args.runs:
            cosim.simulate_tray(short, sc.actuator.gains(), sc.bottle, servo_period_s=sc.actuator.control_period_s,
                                keep_series=False)
            if args.trim and LIBC is not None:
                LIBC.malloc_trim(0)
    plateau = rss_plateau(rss, args.runs)
    print(f"runs {plateau['from_run']}-{plateau['to_run']}: RSS {plateau['rss_growth_mib']:+.2f} MiB "
          f"({plateau['rss_slope_mib_per_run']:+.5f} MiB/run), heap in use "
          f"{plateau['heap_in_use_slope_kib_per_run'] or 0:+.4f} KiB/run, plateau {plateau['plateau']}", flush=True)
    data = {"scenario": "crane-tray", "plan": "toppra x1.1, shaped goals", "plant_steps": steps,
            "repeats": args.repeats, "variants": rows, "rss": rss, "malloc_trim_after_each_run": bool(args.trim),
            "malloc_tuned": tuned, "rss_plateau": plateau,
            "rss_growth_mib_after_first_20": rss[-1]["rss_mib"] - rss[1]["rss_mib"] if len(rss) > 1 else None}
    write_text_atomic(out / "bench_tray_floor.json", json.dumps(data, indent=1) + "\n")
    print(f"wrote {out / 'bench_tray_floor.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
