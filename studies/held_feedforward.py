"""The held law's feedforward lag and its compensation (issue 29 item 2; docs/spatial_drives.md).

    PYTHONPATH=$PWD .venv/bin/python -m studies.held_feedforward --out out [--only panda-tray-cup]
        [--periods-ms 2 4 8] [--feedforward shaped full] [--scale ur5-magnet-part=1.4 ur5-suction-bins=1.05]
        [--compensation mean midpoint none] [--amplifier current voltage]

For ur5-magnet-part, ur5-suction-bins and panda-tray-cup, the TOPP-RA plan (api.plan_with) is co-simulated on the
DC-motor drive (sim/spatial_actuation.SpatialMotorDrive) with the law sampled and held at each loop period, its
feedforward evaluated at the sample instant ("none", the uncompensated law), at the middle of the hold's plant
steps ("midpoint") or on the reference's mean over them ("mean", the default; joint_tracking.HoldCompensatedReference);
plus the every-step law (period None) as
the reference row. A plan may be played slower (--scale NAME=K; default: the magnet's 1.4x, carried by the plain
plan's every-step law, whose fastest carried scale is 1.305, and the suction's 1.05x: at 1x its plan rides its
limit, ratio 1.0000 on the every-step law, and every held law behind a voltage amplifier loses the part within 100 ms
whatever its feedforward), so that every row compares the whole motion. --amplifier: what the held law commands
(sim/spatial_actuation HELD_AMPLIFIERS: "current", the default since session 17, or "voltage", the law the table of
session 16 measured). Each row: outcome, largest hand ratio while held (the tray: also the cup's largest slide [m]), largest and RMS tracking error |q_ref - q| [rad] during the motion, goal error [rad].

Writes OUT/held_feedforward/held_feedforward.json atomically.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from qmt_drake.api import load_scenario, plan_with
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_actuation import HELD_AMPLIFIERS, SpatialMotorDrive
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.systems.joint_tracking import HOLD_COMPENSATIONS

SCENARIOS = ("ur5-magnet-part", "ur5-suction-bins", "panda-tray-cup")
PERIODS_MS = (2.0, 4.0, 8.0)
SCALES = {"ur5-magnet-part": 1.4, "ur5-suction-bins": 1.05}


def row(sc, traj, feedforward: str, period_s, compensation: str, scale: float = 1.0,
        amplifier: str = HELD_AMPLIFIERS[0]) -> dict:
    t0 = time.time()
    drive = SpatialMotorDrive.for_scenario(sc, traj.sample([0.0])[0][0], feedforward, control_period_s=period_s,
                                           hold_compensation=compensation, amplifier=amplifier)
    r = simulate_spatial(sc, traj, actuator="dc_motor", feedforward=feedforward, drive=drive)
    return {"scenario": sc.name, "time_scale": scale, "feedforward": feedforward, "loop_period_s": period_s,
            "hold_compensation": compensation if period_s is not None else "(every step)",
            "amplifier": amplifier if period_s is not None else "(every step)",
            "outcome": r["outcome"], "lost_at_s": r["lost_at_s"],
            "contact_ratio_first_above_1_s": r.get("contact_ratio_first_above_1_s"), "max_slide_m": r.get("max_slide_m"),
            "max_hand_ratio_while_held": r["max_grip_ratio_while_held"],
            "max_tracking_error_rad": r["max_tracking_error_rad"],
            "rms_tracking_error_rad": r["rms_tracking_error_rad"],
            "final_goal_error_rad": r["final_goal_error_rad"], "wall_s": time.time() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("out"))
    ap.add_argument("--only", nargs="*", choices=SCENARIOS)
    ap.add_argument("--periods-ms", nargs="*", type=float, default=list(PERIODS_MS))
    ap.add_argument("--scale", nargs="*", default=[f"{k}={v:g}" for k, v in SCALES.items()],
                    help="NAME=K: play scenario NAME's plan K times slower")
    ap.add_argument("--feedforward", nargs="*", default=["shaped", "full"], choices=["shaped", "full"])
    ap.add_argument("--compensation", nargs="*", default=list(HOLD_COMPENSATIONS), choices=HOLD_COMPENSATIONS)
    ap.add_argument("--amplifier", nargs="*", default=[HELD_AMPLIFIERS[0]], choices=HELD_AMPLIFIERS)
    args = ap.parse_args(argv)
    try:
        scales = {k: float(v) for k, v in (x.split("=") for x in args.scale)}
    except ValueError:
        ap.error(f"--scale {' '.join(args.scale)}: give NAME=K pairs, e.g. ur5-magnet-part=1.4")
    check_output_dir(args.out, "--out")
    out_dir = args.out / "held_feedforward"
    rows = []
    for name in args.only or SCENARIOS:
        sc = load_scenario(name)
        traj = plan_with("toppra", sc).trajectory
        scale = scales.get(name, 1.0)
        traj = traj if scale == 1.0 else TimeScaled(traj, scale)
        for ff in args.feedforward:
            cases = [(None, "none", HELD_AMPLIFIERS[0])] + [
                (p * 1e-3, c, a) for a in args.amplifier for p in args.periods_ms
                for c in reversed(HOLD_COMPENSATIONS) if c in args.compensation]
            for period_s, comp, amp in cases:
                rows.append(row(sc, traj, ff, period_s, comp, scale, amp))
                r = rows[-1]
                print(f"{name:18s} {ff:6s} {'-' if period_s is None else period_s * 1e3:>4} ms {r['amplifier']:8s} "
                      f"{r['hold_compensation']:12s}"
                      f" {r['outcome']:9s} ratio {r['max_hand_ratio_while_held']:.4f}  max err "
                      f"{r['max_tracking_error_rad']:.3e}  rms {r['rms_tracking_error_rad']:.3e}  ({r['wall_s']:.0f} s)",
                      flush=True)
    write_text_atomic(out_dir / "held_feedforward.json", json.dumps(jsonable({"rows": rows}), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
