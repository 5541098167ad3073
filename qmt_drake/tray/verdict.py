"""The verdict of a CRANE-X7 tray run from its logged series (tray/cosim.logged_series): the bottle's
slip against its creep, the friction it needed, its tipping angle, the outcome word and the margin."""

from __future__ import annotations

import math

import numpy as np

from qmt_drake.margin import criterion, verdict_margin
from qmt_drake.systems.tray_object import TRAY_SIZE_M, BottleSpec

# Real slip vs creep: SAP's regularised friction lets a sticking contact creep, faster the nearer
# the tangential force is to the cone's edge: measured 0.06 mm/s at 0.57 of the cone (the P-only
# hold, tray tilted by the sag; studies/crane_tray.py) and 0.2-0.3 mm/s at 0.9 of it
# (tests/test_tray_object.py). Over a 17 s run creep alone reaches ~1 mm, so a distance threshold
# cannot separate them; the sliding SPEED does: samples faster than SLIP_SPEED_M_S (10x the
# creep speed at 0.9 of the cone) count as slip, the rest as creep.
SLIP_SPEED_M_S = 3e-3
SLIP_THRESHOLD_M = 1e-3  # slipped: the slip distance (not the creep) exceeds this
# The first samples see the bottle's feet just touching (zero force) while the contact takes up
# its weight: statistics start after this seating time.
SEATING_S = 0.2


def split_slip_creep(series: dict, until_s: float | None = None) -> tuple[float, float]:
    """(slip, creep) [m]: path length of the base centre on the tray, split by sliding speed, up to
    until_s (the time the bottle was lost: after that it is falling, not sliding)."""
    t = series["t"]
    m = (t >= SEATING_S) & (t <= (np.inf if until_s is None else until_s))
    xy = series["slide"][:, m]
    step = np.hypot(np.diff(xy[0]), np.diff(xy[1]))
    speed = step / np.maximum(np.diff(t[m]), 1e-12)
    fast = speed > SLIP_SPEED_M_S
    return float(np.sum(step[fast])), float(np.sum(step[~fast]))


def required_friction(series: dict, t0: float, t1: float) -> float:
    """max |f_t| / f_n over [t0, t1): the friction coefficient a sticking bottle needed (run with
    a high mu so that it sticks; friction is lagged in SAP, so this can exceed the run's mu)."""
    t = series["t"]
    m = (t >= max(t0, SEATING_S)) & (t < t1)
    f = series["contact_force"][:, m]
    return float(np.max(np.hypot(f[0], f[1]) / np.maximum(f[2], 1e-9)))


def tipping_angle_rad(bottle: BottleSpec) -> float:
    """Tilt at which the centre of mass passes over the ring's edge: atan(r_c / h_G)."""
    return math.atan2(bottle.contact_radius_m, bottle.com_height_m)


def classify(series: dict, bottle: BottleSpec) -> tuple[str, float | None]:
    """(outcome, time lost) from the logged slide and tilt (module docstring)."""
    t = series["t"]
    slide = series["slide"]
    tilt = series["tilt"][0]
    half = np.array(TRAY_SIZE_M[:2]) / 2
    off = np.any(np.abs(slide.T + 0.0) > half, axis=1)
    tipped = tilt > tipping_angle_rad(bottle)
    lost = off | tipped
    if not lost.any():
        return "on_tray", None
    k = int(np.argmax(lost))
    return ("slid_off" if off[k] and not tipped[k] else "tipped"), float(t[k])


def tray_margin(summary: dict) -> dict:
    """The CRANE-X7 tray run's margin (tray/execute.simulate_tray_plan's summary, tray/cosim's thresholds)."""
    return verdict_margin(summary["outcome"], [
        criterion("max_slip_m", summary.get("max_slip_m"), SLIP_THRESHOLD_M, "slipped"),
        criterion("max_tilt_rad", summary.get("max_tilt_rad"), summary.get("tipping_angle_rad", math.nan), "tipped"),
        criterion("max_edge_ratio", summary.get("max_edge_ratio"), 1.0, "slid_off"),
        criterion("final_goal_error_rad", summary.get("final_goal_error_rad"), summary["arrival_tolerance_rad"],
                  "unfinished")])
