"""A spatial plan's peak jerk, and a TOPP-RA plan timed within the scenario's jerk limits.

`peak_jerk(sc, traj, rate_hz)`: the largest |qdd(t_(i+1)) - qdd(t_i)| / (t_(i+1) - t_i) over samples at
rate_hz, per joint (rad/s^3), and its largest ratio to sc.jerk_limit_rad_s3. A TOPP-RA profile has a
constant s-ddot per grid interval, so its acceleration steps at grid points: its jerk is unbounded in
continuous time, and sampled at rate R a step da reads da R. The number is therefore always given
with its rate; a stream sampled at a lower rate than the one checked reads a lower jerk.

`jerk_limited_plan(sc, plan)`: the TOPP-RA plan's path timing seen through one or two moving averages
of widths w (jerk_filter.FilteredTiming: the same path, its jerk bounded and exact in closed form) and
played K times slower (K >= the plan's own hold scale). The jerk scales as 1/K^3, so for given widths the
smallest K is (exact peak jerk ratio)^(1/3); the widths are scanned (`best_windows`: a geometric grid of
JERK_WINDOWS widths per box, then finer around the best) for the shortest K (T + sum w) once the other
limits hold, those ranked by a sampled check at a tenth of the re-check rate. The exact jerk is read at
the re-check rate and on both sides of every breakpoint (where it jumps; smooth between), so the jerk
sampled at any rate stays within it. The other limits are then re-checked and the timing slowed until
they hold (spatial_trajectory.scale_to_hold, refined between samples and on the pieces): the filter
averages (s'', s'^2) over the window while the limits depend on s. Duration K (T_raw + sum w) =
T_raw K + tau, tau = K sum w the windows in the plan's time (info: jerk_filter_windows_s, jerk_time_scale
= K / the plan's hold scale, jerk_recheck_scale the re-check's share of it).

Where the filter cannot bound the jerk (a path that is not C2: its q_ss jumps at a knot, so qdd jumps
whatever the timing; a plan of rest-to-rest segments; a plan that breaks a limit already), the plan is
played k times slower instead (`slowed_plan`: the smallest k, bisection to JERK_REL_TOL, whose sampled
peak jerk at the re-check rate is within the limits; it only bounds the jerk read at that rate).
Ruckig (`--method ruckig`) plans jerk-limited motions itself, rest to rest at every task pose.
"""

from __future__ import annotations

import math
import time

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.jerk_filter import MAX_BOXES, FilteredTiming, exact_peak_jerk
from qmt_drake.planners.spatial_plan_io import make_spatial_plan
from qmt_drake.planners.spatial_trajectory import TimeScaled, ToppraTrajectory, check, scale_to_hold
from qmt_drake.timescale import Grow, search_scale

JERK_REL_TOL = 1e-4
JERK_K_MAX = 1e4
JERK_WINDOWS = 10  # widths scanned (geometric) over [2 / rate, T] for each box, then 5 between the best's neighbours
PROXY_RATE_DIVISOR = 10.0  # the windows' ranking checks the other limits at a tenth of the re-check rate
C2_REL_TOL = 1e-8  # q_ss left vs right of a knot, relative to its largest magnitude: a C2 path


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


def filter_base(traj):
    """(ToppraTrajectory, its time scale) of a TOPP-RA plan's trajectory, or (None, why not filtered)."""
    k = 1.0
    if isinstance(traj, TimeScaled):
        traj, k = traj.inner, traj.k
    if not isinstance(traj, ToppraTrajectory):
        return None, f"a {type(traj).__name__} is not one TOPP-RA timing (rest-to-rest segments)"
    if not is_c2(traj.path.pp):
        return None, "its path is not C2 (the shape-preserving cubic): its acceleration jumps at a knot"
    return traj, k


def is_c2(pp) -> bool:
    """True if the piecewise cubic q(s) has a continuous q_ss: at every inner knot the left piece's q_ss
    (linear on a cubic: extrapolated exactly from two points inside it) equals the right piece's."""
    b = np.asarray(pp.get_segment_times(), float)
    if b.size < 3:
        return True
    dd = pp.derivative(2)
    h = 0.25 * np.diff(b)[:-1]
    x = b[1:-1]
    left = 2.0 * dd.vector_values(x - h) - dd.vector_values(x - 2.0 * h)
    right = dd.vector_values(x)
    return bool(np.abs(left - right).max() <= C2_REL_TOL * max(float(np.abs(right).max()), 1e-300))


def best_windows(sc, base, k_hold: float, rate_hz: float, boxes: int = MAX_BOXES) -> dict:
    """{'windows_s' (in the base's time), 'scale' K, 'duration_s', 'estimate_s'}: one box or two (at most
    `boxes`), scanned on a geometric grid of widths from 2 / rate_hz to T, then finer around the best. K is the
    smallest scale >= k_hold whose exact peak jerk (jerk_filter.exact_peak_jerk) is within the limits, and
    the best has the shortest estimate of the plan's duration once its other limits hold: K (T + sum of
    windows) times sqrt of the largest ratio of a sampled check at rate_hz / PROXY_RATE_DIVISOR (an
    inertial ratio falls as 1/k^2; only a ranking: the plan's own scale is then found by the re-check)."""
    def trial(w):
        f = FilteredTiming(base, w)
        r = exact_peak_jerk(sc, f, rate_hz * k_hold)["peak_jerk_ratio"]  # at scale 1, read as densely as at k_hold
        K = max(k_hold, r ** (1.0 / 3.0) * (1.0 + JERK_REL_TOL))
        limits = check(sc, TimeScaled(f, K), rate_hz / PROXY_RATE_DIVISOR)["max_timed"]
        T = K * f.duration_s
        return {"windows_s": tuple(w), "scale": float(K), "duration_s": float(T),
                "estimate_s": float(T * math.sqrt(max(limits, 1.0)))}

    widths = np.geomspace(2.0 / rate_hz, base.duration_s, JERK_WINDOWS)
    step = widths[1] / widths[0]
    coarse = [(w1,) for w1 in widths] + [(w1, w2) for i, w1 in enumerate(widths) for w2 in widths[:i + 1] if boxes > 1]
    best = min((trial(w) for w in coarse), key=lambda x: x["estimate_s"])
    w = best["windows_s"]
    near = np.geomspace(1.0 / step, step, 5)
    finer = [(w[0] * a,) + tuple(x * b for x in w[1:]) for a in near for b in (near if len(w) > 1 else [1.0])]
    return min([best, *(trial(x) for x in finer)], key=lambda x: x["estimate_s"])


def filtered_plan(sc, plan, base, k_hold: float):
    """`plan` (a TOPP-RA plan, `base` its timing played k_hold times slower) as a box-filtered timing within
    the jerk limits and re-checked (module docstring)."""
    t0 = time.perf_counter()
    rate = sc.recheck_rate_hz
    best = best_windows(sc, base, k_hold, rate)
    f = FilteredTiming(base, best["windows_s"])
    _, k_more = scale_to_hold(sc, TimeScaled(f, best["scale"]), rate, refine=True)
    K = best["scale"] * k_more
    after = exact_peak_jerk(sc, TimeScaled(f, K), rate)
    if after["peak_jerk_ratio"] > 1.0:  # read at other instants than the search's: raise K by the excess
        K *= after["peak_jerk_ratio"] ** (1.0 / 3.0) * (1.0 + JERK_REL_TOL)
        after = exact_peak_jerk(sc, TimeScaled(f, K), rate)
    traj = TimeScaled(f, K)
    s_poses = f.base_position(np.asarray(plan.pose_times_s, float) / k_hold)
    info = {**plan.info, "jerk_limited": "box_filter", "jerk_filter_windows_s": [K * w for w in f.windows_s],
            "jerk_time_scale": K / k_hold, "jerk_recheck_scale": k_more,
            "duration_before_jerk_limit_s": plan.duration_s,
            "peak_jerk_ratio_before": peak_jerk(sc, plan.trajectory, rate)["peak_jerk_ratio"],
            "peak_jerk_ratio": after["peak_jerk_ratio"], "peak_jerk_rad_s3": after["peak_jerk_rad_s3"],
            "jerk_rate_hz": rate}
    return make_spatial_plan(sc, plan.method, traj, f.time_at(s_poses) * K,
                             planning_s=plan.planning_s + time.perf_counter() - t0, raw_duration_s=plan.raw_duration_s,
                             hold_scale=K, info=info)


def slowed_plan(sc, plan, why: str):
    """`plan` played k times slower to its jerk limits at the re-check rate (module docstring: the fallback)."""
    t0 = time.perf_counter()
    rate = sc.recheck_rate_hz
    before = peak_jerk(sc, plan.trajectory, rate)

    def ratio(k: float) -> float:
        return peak_jerk(sc, TimeScaled(plan.trajectory, k), rate)["peak_jerk_ratio"]

    hi = jerk_time_scale(ratio, before["peak_jerk_ratio"], f"{sc.name}: the {plan.method} plan's")
    traj = plan.trajectory if hi == 1.0 else TimeScaled(plan.trajectory, hi)
    after = peak_jerk(sc, traj, rate)
    info = {**plan.info, "jerk_limited": "time_scale", "jerk_filter_not_used": why, "jerk_time_scale": hi,
            "duration_before_jerk_limit_s": plan.duration_s,
            "peak_jerk_ratio_before": before["peak_jerk_ratio"], "peak_jerk_ratio": after["peak_jerk_ratio"],
            "peak_jerk_rad_s3": after["peak_jerk_rad_s3"], "jerk_rate_hz": rate}
    return make_spatial_plan(sc, plan.method, traj, np.asarray(plan.pose_times_s) * hi,
                             planning_s=plan.planning_s + time.perf_counter() - t0, raw_duration_s=plan.raw_duration_s,
                             hold_scale=plan.hold_scale * hi, info=info)


def jerk_limited_plan(sc, plan):
    """`plan` timed within its scenario's jerk limits (module docstring): the filtered timing, or where the
    filter cannot bound the jerk, the plan slowed; the plan itself when its sampled jerk is within them."""
    if peak_jerk(sc, plan.trajectory, sc.recheck_rate_hz)["peak_jerk_ratio"] <= 1.0:
        return slowed_plan(sc, plan, "already within the jerk limits")
    base, k_hold = filter_base(plan.trajectory)
    if base is None:
        return slowed_plan(sc, plan, str(k_hold))
    if plan.recheck["max"] > 1.0:
        return slowed_plan(sc, plan, "the plan breaks a limit already (least violating)")
    return filtered_plan(sc, plan, base, float(k_hold))
