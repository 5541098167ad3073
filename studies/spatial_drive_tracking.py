"""A plan on its limit through the spatial drives: the plain reference against the closed-loop-aware one
(issue 29 item 2; sim/spatial_reference.py, docs/spatial_drives.md).

    .venv/bin/python -m studies.spatial_drive_tracking --out out [--only ur5-magnet-part] [--window 0.042]

For ur5-magnet-part, ur5-suction-bins and panda-tray-cup, the TOPP-RA plan (api.plan_with) is co-simulated
(sim/spatial_cosim.simulate_spatial) with
  - ideal        Drake's InverseDynamicsController on ideal joint torques, the plain plan;
  - dc_motor     the DC motors, PD law with the full feedforward (back-EMF + inverse dynamics) on the plain
                 plan (the shipped default before this study: the "old reference");
  - dc_motor shaped   the same drive on the closed-loop-aware reference (feedforward 'shaped');
  - ideal shaped      the ideal controller on the shaped reference (is the gain the drive's or the reference's?).
Each row: at the planned speed the outcome, the largest hand ratio (required wrench over its limit) while
held and the largest tracking error |q_ref - q| [rad] against the reference the loop was sent; then the
fastest carried time scale k (timescale.smallest_holding_scale, to REL_TOL) and the executed motion time
k T (+ the shaping window) over the TOPP-RA plan's T.

Writes OUT/spatial_drive_tracking/spatial_drive_tracking.json and .png atomically.
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import sys
import time
from pathlib import Path

import numpy as np

from qmt_drake.api import load_scenario, plan_with
from qmt_drake.outputs import check_output_dir, jsonable, write_bytes_atomic, write_text_atomic
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim import spatial_reference
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_motor import check_integral_rate
from qmt_drake.timescale import smallest_holding_scale

SCENARIOS = ("ur5-magnet-part", "ur5-suction-bins", "panda-tray-cup")
VARIANTS = (("ideal", "full"), ("dc_motor", "full"), ("dc_motor", "shaped"), ("ideal", "shaped"))
REL_TOL = 0.005
FIRST_HI, MAX_HI = 1.5, 3.0


def run(sc, traj, actuator, feedforward, k=1.0):
    return simulate_spatial(sc, traj if k == 1.0 else TimeScaled(traj, k), actuator=actuator, feedforward=feedforward)


def fastest_carried(sc, traj, actuator, feedforward, at_one: dict) -> tuple[float | None, int]:
    """(smallest carried time scale, runs): 1 when carried as planned; None if not carried at MAX_HI."""
    if at_one["held"]:
        return 1.0, 0
    runs, hi = 0, FIRST_HI
    while True:
        runs += 1
        if run(sc, traj, actuator, feedforward, hi)["held"]:
            break
        if hi >= MAX_HI:
            return None, runs
        hi = min(MAX_HI, hi * 1.5)
    count = [runs]

    def holds(k):
        count[0] += 1
        return run(sc, traj, actuator, feedforward, k)["held"]

    return smallest_holding_scale(1.0, hi, holds, REL_TOL), count[0]


def row(sc, plan, actuator, feedforward, window_s) -> dict:
    t0 = time.time()
    traj, T = plan.trajectory, plan.trajectory.duration_s
    r = run(sc, traj, actuator, feedforward)
    k, runs = fastest_carried(sc, traj, actuator, feedforward, r)
    extra = window_s if feedforward == "shaped" else 0.0
    out = {"scenario": sc.name, "actuator": actuator, "feedforward": feedforward,
           "reference": "shaped" if feedforward == "shaped" else "plan", "plan_time_s": T,
           "outcome_at_1x": r["outcome"], "lost_at_s": r["lost_at_s"],
           "max_hand_ratio_while_held_at_1x": r["max_grip_ratio_while_held"],
           "max_tracking_error_rad_at_1x": r["max_tracking_error_rad"],
           "final_goal_error_rad_at_1x": r["final_goal_error_rad"],
           "fastest_carried_scale": k, "searched_runs": runs,
           "fastest_carried_time_s": None if k is None else k * T + extra,
           "fastest_carried_time_over_plan": None if k is None else (k * T + extra) / T,
           "wall_s": time.time() - t0}
    if "max_motor_torque_over_limit" in r:
        out["max_motor_torque_over_limit_at_1x"] = r["max_motor_torque_over_limit"]
    return out


def figure_png(rows: list[dict], note: str = "") -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [n for n in SCENARIOS if any(r["scenario"] == n for r in rows)]
    variants = [v for v in VARIANTS if any((r["actuator"], r["feedforward"]) == v for r in rows)]  # the run's only
    labels = [f"{a}\n{'shaped' if f == 'shaped' else 'plain'} ref." for a, f in variants]
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.8))
    width = 0.8 / len(variants)
    panels = (("max_tracking_error_rad_at_1x", 1e3, "max tracking error at 1x [mrad] (log)", None),
              ("max_hand_ratio_while_held_at_1x", 1.0, "largest hand ratio while held at 1x [-]", (0.9, 1.08)),
              ("fastest_carried_time_over_plan", 1.0, "fastest carried time / TOPP-RA plan time [-]", (0.9, 1.45)))
    for ax, (key, unit, title, ylim) in zip(axes, panels):
        for j, (a, f) in enumerate(variants):
            vals = []
            for n in names:
                r = next((r for r in rows if (r["scenario"], r["actuator"], r["feedforward"]) == (n, a, f)), None)
                v = None if r is None else r[key]
                vals.append(np.nan if v is None else v * unit)
            ax.bar(np.arange(len(names)) + (j - (len(variants) - 1) / 2) * width, vals, width, label=labels[j],
                   color=f"C{VARIANTS.index((a, f))}")  # a variant keeps its colour in every run's figure
        ax.set_xticks(np.arange(len(names)), names, fontsize=8)
        ax.set_ylabel(title)
        if ylim is None:
            ax.set_yscale("log")
        else:
            ax.set_ylim(*ylim)
        ax.set_xlabel("scenario (TOPP-RA plan)")
        if key != "max_tracking_error_rad_at_1x":
            ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.grid(axis="y", alpha=0.3)
    axes[2].axhline(1.03, color="r", lw=0.8, ls=":", label="goal 1.03")
    fig.legend(*axes[2].get_legend_handles_labels(), loc="lower center", ncol=5, fontsize=8)
    fig.suptitle("Spatial drives: plain plan vs closed-loop-aware (shaped) reference, DC motors and ideal actuators"
                 + (f" ({note})" if note else ""))
    fig.tight_layout(rect=(0, 0.1, 1, 1))
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def _note(args) -> str:
    """The title's note on a non-default drive law (--integral-rate)."""
    return "" if args.integral_rate is None else f"DC drive PID, integral rate {args.integral_rate:g} 1/s"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--only", choices=SCENARIOS, action="append")
    ap.add_argument("--window", type=float, default=spatial_reference.SHAPING_WINDOW_S,
                    help="the shaped reference's kernel width [s] (two boxes of half of it)")
    ap.add_argument("--replot", action="store_true", help="redraw the PNG from the JSON already in OUT, run nothing")
    ap.add_argument("--integral-rate", type=float, default=None, metavar="PER_S",
                    help="the DC drive's PID integral rate Ki/K [1/s] (default: the scenario's, 0); runs the dc_motor "
                         "variants only")
    args = ap.parse_args(argv)
    check_output_dir(args.out, "--out")
    folder = Path(args.out) / "spatial_drive_tracking"
    if args.replot:
        write_bytes_atomic(folder / "spatial_drive_tracking.png", figure_png(
            json.loads((folder / "spatial_drive_tracking.json").read_text())["rows"], _note(args)))
        print(f"wrote {folder}/spatial_drive_tracking.png")
        return 0
    if not args.window > 0:
        print(f"--window {args.window}: give a positive width in seconds, e.g. 0.042", file=sys.stderr)
        return 2
    # the study's window for every shaped run (closed_loop_reference's default argument)
    spatial_reference.closed_loop_reference.__defaults__ = (None, None, args.window)
    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.only or SCENARIOS:
        sc = load_scenario(name)
        plan = plan_with("toppra", sc)
        variants = VARIANTS
        if args.integral_rate is not None:  # the law designed with the integral (the scenario's motor section)
            rate = check_integral_rate(args.integral_rate, "--integral-rate", sc.n_dof)
            sc = dataclasses.replace(sc, motor=dataclasses.replace(sc.motor, integral_rate_per_s=rate))
            variants = [v for v in VARIANTS if v[0] == "dc_motor"]
        for actuator, feedforward in variants:
            r = row(sc, plan, actuator, feedforward, args.window)
            rows.append(r)
            print(f"{name:18s} {actuator:8s} {feedforward:6s} 1x: {r['outcome_at_1x']:9s} ratio "
                  f"{r['max_hand_ratio_while_held_at_1x']:.4f} track {r['max_tracking_error_rad_at_1x']:.2e} rad | "
                  f"fastest carried k {r['fastest_carried_scale']} time/plan {r['fastest_carried_time_over_plan']} "
                  f"({r['searched_runs']} runs, {r['wall_s']:.0f} s)", flush=True)
    doc = {"window_s": args.window, "rel_tol": REL_TOL, "rows": rows,
           "command": "python -m studies.spatial_drive_tracking " + " ".join(argv if argv is not None else sys.argv[1:])}
    write_text_atomic(folder / "spatial_drive_tracking.json", json.dumps(jsonable(doc), indent=1))
    write_bytes_atomic(folder / "spatial_drive_tracking.png", figure_png(rows, _note(args)))
    print(f"wrote {folder}/spatial_drive_tracking.json and .png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
