"""A spatial plan's peak jerk, and a TOPP-RA plan slowed until its jerk is within the scenario's limits.

`peak_jerk(sc, traj, rate_hz)`: the largest |qdd(t_(i+1)) - qdd(t_i)| / (t_(i+1) - t_i) over samples at
rate_hz, per joint (rad/s^3), and its largest ratio to sc.jerk_limit_rad_s3. A TOPP-RA profile has a
constant s-ddot per grid interval, so its acceleration steps at grid points: its jerk is unbounded in
continuous time, and sampled at rate R a step da reads da R. The number is therefore always given
with its rate; a stream sampled at a lower rate than the one checked reads a lower jerk.

`jerk_limited_plan(sc, plan)`: the simplest honest jerk limit: the plan played k times slower
(spatial_trajectory.TimeScaled: positions and the path unchanged, qdd / k^2, jerk of the smooth part
/ k^3, of the steps sampled at a fixed rate / k^2) with the smallest k (bisection to JERK_REL_TOL)
whose peak jerk at the scenario's re-check rate is within the limits; the plan's limits still hold
(slower is within them) and are re-checked. The cost in time is k, stated in the plan's info.
Ruckig (`--method ruckig`) plans jerk-limited motions itself, rest to rest at every task pose.
"""

from __future__ import annotations

import math
import time

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.planners.spatial_plan_io import make_spatial_plan
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.timescale import Grow, search_scale

JERK_REL_TOL = 1e-4
JERK_K_MAX = 1e4


def peak_jerk(sc, traj, rate_hz: float) -> dict:
    """Peak jerk of traj sampled at rate_hz (module docstring)."""
    n = max(int(math.ceil(traj.duration_s * rate_hz)), 2)
    t = np.linspace(0.0, traj.duration_s, n + 1)
    qdd = traj.sample(t)[2]
    j = np.abs(np.diff(qdd, axis=0)).max(axis=0) / (t[1] - t[0])
    return {"peak_jerk_rad_s3": j, "peak_jerk_ratio": float(np.max(j / sc.jerk_limit_rad_s3)),
            "jerk_rate_hz": float(rate_hz)}


def jerk_time_scale(ratio, ratio_before: float, who: str, k_max: float = JERK_K_MAX,
                    rel_tol: float = JERK_REL_TOL) -> float:
    """The smallest time scale k (to rel_tol) with ratio(k) <= 1, given ratio_before = ratio(1): 1 if
    within; else doubling from sqrt(ratio_before) (exact for the smooth part's k^-2 .. k^-3) to
    bracket it, no further than k_max (QmtInputError naming `who`), then bisected (timescale.search_scale)."""
    if not ratio_before > 1.0:  # (a nan ratio too, as before)
        return 1.0
    first = max(math.sqrt(ratio_before), 1.0 + rel_tol)
    found = search_scale(lambda k: ratio(k) <= 1.0, rel_tol=rel_tol,
                         grow=Grow(start=1.0, first=first, factor=2.0, limit=k_max, clip=False, stop_past_limit=True))
    if found.status == "capped":
        raise QmtInputError(f"{who} jerk stays over the limit even {k_max:g} times slower; "
                            "raise actuators.jerk_limit_rad_s3")
    return found.holding


def jerk_limited_plan(sc, plan):
    """`plan` slowed to its scenario's jerk limits (module docstring); the plan itself when within them."""
    t0 = time.perf_counter()
    rate = sc.recheck_rate_hz
    before = peak_jerk(sc, plan.trajectory, rate)

    def ratio(k: float) -> float:
        return peak_jerk(sc, TimeScaled(plan.trajectory, k), rate)["peak_jerk_ratio"]

    hi = jerk_time_scale(ratio, before["peak_jerk_ratio"], f"{sc.name}: the {plan.method} plan's")
    traj = plan.trajectory if hi == 1.0 else TimeScaled(plan.trajectory, hi)
    after = peak_jerk(sc, traj, rate)
    info = {**plan.info, "jerk_limited": True, "jerk_time_scale": hi, "duration_before_jerk_limit_s": plan.duration_s,
            "peak_jerk_ratio_before": before["peak_jerk_ratio"], "peak_jerk_ratio": after["peak_jerk_ratio"],
            "peak_jerk_rad_s3": after["peak_jerk_rad_s3"], "jerk_rate_hz": rate}
    return make_spatial_plan(sc, plan.method, traj, np.asarray(plan.pose_times_s) * hi,
                             planning_s=plan.planning_s + time.perf_counter() - t0, raw_duration_s=plan.raw_duration_s,
                             hold_scale=plan.hold_scale * hi, info=info)
