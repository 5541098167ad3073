"""Tray co-simulation cost per plant step against a floor of Drake primitives, side by side, and the
resident memory over many runs (issue 20).

    .venv/bin/python -m studies.bench_tray_floor --out out [--runs 200] [--repeats 3]

ours      the default tray diagram (tray/cosim.build_tray_diagram: compiled servo law and motors,
          loggers of plant and primitive ports every 5 ms; the bottle's motion is derived from its
          logged joint state after the run, so no Python system is in the diagram)
python    the same with the Python DynamixelPositionServo and DcMotorWithGear (one call per period)
floor     the default diagram with no monitor and no loggers: the plant, the goal source, the servo
          law and the motors only, all Drake primitives
Each variant simulates the same shaped TOPP-RA transfer (crane-tray, x1.1) `repeats` times, fresh
diagram each time, interleaved; the table gives the best wall time per plant step and the ratio to
the floor. Then `runs` short transfers in one process record the resident set size (RSS) every 20
runs. Prints the figures and writes OUT/bench_tray_floor.json (atomic).
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pydrake.systems.analysis import Simulator  # noqa: E402

import qmt_drake.tray.cosim as cosim  # noqa: E402
from qmt_drake import load_scenario, plan_with  # noqa: E402
from qmt_drake.outputs import check_output_dir, write_text_atomic  # noqa: E402
from qmt_drake.tray.execute import plan_schedule  # noqa: E402


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
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--runs", type=int, default=200)
    args = ap.parse_args(argv)
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
    for k in range(args.runs + 1):
        if k % 20 == 0:
            rss.append({"run": k, "rss_mib": _rss_mib()})
            print(f"run {k}: RSS {rss[-1]['rss_mib']:.1f} MiB", flush=True)
        if k < args.runs:
            cosim.simulate_tray(short, sc.actuator.gains(), sc.bottle, servo_period_s=sc.actuator.control_period_s,
                                keep_series=False)
    data = {"scenario": "crane-tray", "plan": "toppra x1.1, shaped goals", "plant_steps": steps,
            "repeats": args.repeats, "variants": rows, "rss": rss,
            "rss_growth_mib_after_first_20": rss[-1]["rss_mib"] - rss[1]["rss_mib"] if len(rss) > 1 else None}
    write_text_atomic(out / "bench_tray_floor.json", json.dumps(data, indent=1) + "\n")
    print(f"wrote {out / 'bench_tray_floor.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
