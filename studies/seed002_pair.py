"""Seed 002's pair at the seed's set-up: when and where is the bottle lost?

The seed (section 7): with P-only servos (P = 800) and the linear waypoint spacing (eq. 14) the
bottle fell "at the start of the move from the end point back to the initial posture" (Fig. 9:
initial posture 7 s, start 13 s, end 18 s, 5 s hold, initial posture at 28 s); with PID (P
1000/1040/1000, I 150, D 200/250/200) and the eased spacing (eq. 15, p = 1.5) it was carried.
The study's default (studies/crane_tray.py) loses it in the P-only run only at friction
0.125-0.175, and then at the arrival at the end point, not at the return start.

Each set-up below changes one thing the seed leaves open (or states and the default does not
model) and runs both cases through the co-simulation (qmt_drake/tray/cosim.py, 1 ms step); the
table gives, per run, the outcome, the time and phase where the bottle first slid 1 mm and where it
was lost, and where on the tray (its base centre's offset from its seat, tray frame: x along the
transfer, from the start towards the end point; y across).

Run: PYTHONPATH=. python -m studies.seed002_pair [--only NAME,NAME] [--mu MU]
(about 20 s wall per run on an idle core; each set-up is two runs).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from qmt_drake.systems.dynamixel_servo import (
    CRANE_X7_PLANAR_SERVOS,
    SEED_GAINS_AFTER,
    SEED_GAINS_BEFORE,
    motor_params,
)
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.tray.cosim import SEATING_S, required_friction, simulate_tray
from qmt_drake.tray.crane_ik import SEED_GOAL_XY_M, SEED_START_XY_M, fit_tool_offset, tray_ik
from qmt_drake.tray.waypoints import SEED_WAYPOINTS, GoalSchedule, spacing

CASES = {"P-only, linear": (1.0, SEED_GAINS_BEFORE), "PID, eased": (1.5, SEED_GAINS_AFTER)}
SLID_M = 1e-3   # "first slid": the base centre 1 mm from its seat


def schedule(exponent: float, *, tool_offset_m=None, pre_move_s: float = 0.0, pre_wait_s: float = 1.0,
             settle_s: float = 1.0, move_s: float = 5.0, hold_s: float = 5.0, return_s: float = 5.0,
             return_mode: str = "spaced", tail_s: float = 1.5) -> GoalSchedule:
    """The seed's run as a servo goal stream (zero-order hold), as tray/waypoints.seed_motion, with
    the options the seed leaves open:
    tool_offset_m: IK for the frame the seed's printed joints fit (crane_ik.fit_tool_offset), not
        the tray (None: Table 1's L0 + L3);
    pre_move_s > 0: start at the initial posture (theta = 0, where the seed sets the tray down at
        7 s) and move there to the line's start in a joint line with the same spacing law, then
        wait pre_wait_s (the seed: 7 -> 13 s);
    return_mode: "spaced" (a joint line to the initial posture with the same spacing law and
        waypoint count: the default's assumption), "step" (the initial posture sent as one goal:
        each servo runs to it as fast as its loop makes it) or "trapezoid" (the same MoveIt-style
        joint move in both runs, `_trapezoid_fraction`)."""
    n = SEED_WAYPOINTS
    s = spacing(n, exponent)
    a, b = np.asarray(SEED_START_XY_M), np.asarray(SEED_GOAL_XY_M)
    line = np.array([tray_ik(*(a + (b - a) * si), tool_offset_m=tool_offset_m) for si in s])
    q0 = np.zeros(3)
    times, goals, phases = [], [], {}
    t = 0.0
    if pre_move_s > 0:
        times.append([0.0])
        goals.append(q0[None])
        t = settle_s
        times.append(t + pre_move_s * np.arange(1, n + 1) / n)
        goals.append(q0 + (line[0] - q0) * s[1:, None])
        phases["pre-move"] = (t, t + pre_move_s)
        t += pre_move_s + pre_wait_s
        times.append(t + move_s * np.arange(1, n + 1) / n)
        goals.append(line[1:])
    else:
        times.append([0.0])
        goals.append(line[:1])
        t = settle_s
        times.append(t + move_s * np.arange(1, n + 1) / n)
        goals.append(line[1:])
    phases["move"] = (t, t + move_s)
    t += move_s
    phases["hold"] = (t, t + hold_s)
    t += hold_s
    if return_mode == "spaced":
        times.append(t + return_s * np.arange(1, n + 1) / n)
        goals.append(line[-1] + (q0 - line[-1]) * s[1:, None])
    elif return_mode == "step":
        times.append([t + 1e-3])
        goals.append(q0[None])
    elif return_mode == "trapezoid":
        # a MoveIt-style joint-space move: trapezoidal speed along the joint line, the joint that
        # travels furthest accelerating at MOVEIT_ACCEL_RAD_S2 (crane_x7_moveit_config), goals
        # streamed every 4 ms (the arm controller's 250 Hz)
        u = _trapezoid_fraction(np.arange(1, int(round(return_s / 4e-3)) + 1) * 4e-3, return_s,
                                float(np.max(np.abs(line[-1] - q0))))
        times.append(t + np.arange(1, u.size + 1) * 4e-3)
        goals.append(line[-1] + (q0 - line[-1]) * u[:, None])
    else:
        raise ValueError(return_mode)
    phases["return"] = (t, t + return_s)
    t += return_s
    return GoalSchedule(np.concatenate(times), np.concatenate(goals), t + tail_s, phases,
                        f"p={exponent:g}")


MOVEIT_ACCEL_RAD_S2 = 8.0   # rt-net/crane_x7_ros crane_x7_moveit_config/config/joint_limits.yaml


def _trapezoid_fraction(t, T: float, travel_rad: float) -> np.ndarray:
    """Path fraction u(t) in [0, 1] of a trapezoidal speed profile lasting T whose largest joint
    travel travel_rad accelerates at MOVEIT_ACCEL_RAD_S2."""
    a = MOVEIT_ACCEL_RAD_S2 / travel_rad            # path fraction per s^2
    ta = T / 2 - np.sqrt(max(T * T / 4 - 1.0 / a, 0.0))   # u(T) = 1: a ta (T - ta) = 1
    t = np.clip(t, 0.0, T)
    v = a * ta
    return np.where(t < ta, 0.5 * a * t * t,
                    np.where(t < T - ta, 0.5 * a * ta * ta + v * (t - ta), 1.0 - 0.5 * a * (T - t) ** 2))


def _where(t, phases) -> str:
    """'phase +dt s' for time t (the last phase that started at or before t)."""
    best = None
    for name, (t0, _) in phases.items():
        if t0 <= t and (best is None or t0 >= best[1]):
            best = (name, t0)
    return f"{best[0]} +{t - best[1]:.2f} s" if best else f"{t:.2f} s"


def describe(r) -> dict:
    ser = r.series
    t = ser["t"]
    slide = ser["slide"]
    dist = np.hypot(slide[0], slide[1])
    after = t >= SEATING_S
    k1 = np.flatnonzero(after & (dist > SLID_M))
    first = None if k1.size == 0 else float(t[k1[0]])
    m1 = r.phases["move"][1]
    r0 = r.phases["return"][0]
    need = {"arrival": required_friction(ser, m1, m1 + 1.0), "return start": required_friction(ser, r0, r0 + 0.5)}
    # |f_t| / f_n means the friction a run needs only while the bottle sticks (run with --mu 1)
    need_text = ("-" if r.outcome != "on_tray" or r.slipped
                 else f"{need['arrival']:.3f} / {need['return start']:.3f}")
    out = {"need": need, "need_text": need_text, "outcome": r.outcome, "slip_mm": 1e3 * r.slip_m, "max_slide_mm": 1e3 * r.max_slide_m,
           "first_slid": "-" if first is None else f"{first:.2f} s ({_where(first, r.phases)})",
           "lost": "-", "place_mm": "-", "max_tilt_deg": float(np.degrees(r.max_tilt_rad))}
    if r.lost_at_s is not None:
        k = int(np.searchsorted(t, r.lost_at_s))
        out["lost"] = f"{r.lost_at_s:.2f} s ({_where(r.lost_at_s, r.phases)})"
        out["place_mm"] = f"({1e3 * slide[0][k]:.0f}, {1e3 * slide[1][k]:.0f})"
    else:
        k = int(np.argmax(dist * after))
        out["place_mm"] = f"max at ({1e3 * slide[0][k]:.0f}, {1e3 * slide[1][k]:.0f}), {t[k]:.2f} s ({_where(t[k], r.phases)})"
    return out


def setups(mu: float) -> dict:
    h_fit = fit_tool_offset()[0]
    bottle = BottleSpec.pet_500ml(friction=mu)
    switched = motor_params(CRANE_X7_PLANAR_SERVOS, lossless_equivalent=False)
    return {
        "default": ("the study's default (Table 1 IK, start at the line's start, spaced joint-line return)",
                    {}, {}),
        "printed_joints": (f"IK for the frame the seed's printed joints fit (tool offset {h_fit:.4f} m)",
                           {"tool_offset_m": h_fit}, {}),
        "full_timeline": ("the whole run: tray set at the initial posture, 5 s to the start, 1 s wait",
                          {"pre_move_s": 5.0}, {}),
        "return_step": ("the return sent as one goal (the initial posture)", {"return_mode": "step"}, {}),
        "switched_eta": ("the servos' datasheet gear efficiency switched at zero speed (not the lossless "
                         "equivalent)", {}, {"motor": switched}),
        "servo_4ms": ("the servos' control loop at 4 ms instead of 1 ms (both runs)", {}, {"servo_period_s": 4e-3}),
        "servo_8ms": ("the servos' control loop at 8 ms (both runs)", {}, {"servo_period_s": 8e-3}),
        "bottle_outer": ("the bottle stood 60 mm off-centre towards the end point (tray +x)", {},
                         {"bottle_offset_xy": (0.06, 0.0)}),
        "bottle_inner": ("the bottle stood 60 mm off-centre towards the start (tray -x)", {},
                         {"bottle_offset_xy": (-0.06, 0.0)}),
        "return_fast": ("the return in 2.5 s (each run its own spacing law)", {"return_s": 2.5}, {}),
        "return_2s": ("the return in 2 s (each run its own spacing law)", {"return_s": 2.0}, {}),
        "return_moveit": ("the same MoveIt-style trapezoid return in both runs (8 rad/s^2, 5 s)",
                          {"return_mode": "trapezoid"}, {}),
        "return_moveit_fast": ("the same MoveIt-style trapezoid return in both runs, 2.5 s",
                               {"return_mode": "trapezoid", "return_s": 2.5}, {}),
        "all_seed": ("printed joints + whole run + switched efficiency", {"tool_offset_m": h_fit, "pre_move_s": 5.0},
                     {"motor": switched}),
    }, bottle


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma list of set-ups (default: all)")
    ap.add_argument("--mu", type=float, default=0.3, help="bottle-tray friction (the scenario's 0.3)")
    a = ap.parse_args(argv)
    table, bottle = setups(a.mu)
    names = [n for n in a.only.split(",") if n] or list(table)
    for n in names:
        if n not in table:
            print(f"unknown set-up '{n}'; choose from {', '.join(table)}", file=sys.stderr)
            return 2
    print(f"friction {a.mu:g}; place: the base centre's offset from its seat in the tray frame (x towards "
          "the end point); friction used: max |f_t| / f_n in the 1 s after the arrival and the 0.5 s after "
          "the return starts, shown for runs where the bottle sticks (--mu 1: what each run needs)")
    print("| set-up | case | outcome | slip (mm) | first slid 1 mm | lost at | place (mm) | friction used: arrival / "
          "return start | wall s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in names:
        desc, skw, rkw = table[n]
        for case, (expo, gains) in CASES.items():
            w0 = time.perf_counter()
            r = simulate_tray(schedule(expo, **skw), gains, bottle, **rkw)
            d = describe(r)
            print(f"| {n}: {desc} | {case} | {d['outcome']} | {d['slip_mm']:.1f} | {d['first_slid']} | "
                  f"{d['lost']} | {d['place_mm']} | {d['need_text']} | "
                  f"{time.perf_counter() - w0:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
