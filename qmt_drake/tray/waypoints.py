"""Seed 002's motion as a stream of servo goal positions.

The line (section 5, 7): 1000 IK waypoints between the start and goal tray points, the tray level,

    p_i = a + (b - a) (i / 1000)        linear spacing, eq. 14
    p_i = a + (b - a) (i / 1000)^p      eased, eq. 15 (p = 1.5 in the seed)

sent one after the other at equal time intervals over the move time (~5 s in the seed; Fig. 9/10:
start at 13/14 s, goal at 18/19 s); each is a goal position the servo holds until the next
(a zero-order hold: the servo firmware's Profile Velocity is 0, so it steps to every new goal).
Then the hold at the goal (5 s) and the return to the initial posture (5 s, Fig. 9/10: 23 -> 28 s).

ASSUMPTIONS (the seed does not say): the return is a joint-space line to the initial posture with
the same spacing law and waypoint count; the initial posture is the arm straight up with the tray
level (theta = 0: CRANE-X7's zero pose). The run begins at the start point after `settle_s` of
holding there (the seed's robot had moved there from the initial posture before, 7 -> 13 s).

Eased spacing starts at zero speed but ends at 1.5x the mean speed (d/ds s^1.5 = 1.5 at s = 1):
the goal then stops abruptly; linear spacing jumps to the mean speed at both ends.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.at_rest import describe_at_rest, worst_at_rest
from qmt_drake.planners.ruckig_core import RuckigProfile, rest_to_rest
from qmt_drake.planners.toppra_core import parameterise
from qmt_drake.systems.dynamixel_servo import CRANE_X7_PLANAR_SERVOS, RPM
from qmt_drake.tray.conditions import (
    contact_wrench,
    level_tray_acceleration_cap_m_s2,
    tray_kinematics,
    tray_ratios,
)
from qmt_drake.tray.crane_ik import SEED_GOAL_XY_M, SEED_START_XY_M, TABLE1, CraneGeometry, tray_fk, tray_ik
from qmt_drake.tray.planning import tray_scenario

SEED_WAYPOINTS = 1000
SEED_MOVE_S = 5.0
SEED_HOLD_S = 5.0
SEED_RETURN_S = 5.0
INITIAL_POSTURE_RAD = (0.0, 0.0, 0.0)  # assumption, see the module docstring


def spacing(n: int, exponent: float) -> np.ndarray:
    """(n + 1,) path fractions (i / n)^exponent, i = 0..n (eq. 14 for exponent 1, eq. 15 otherwise)."""
    if n < 1:
        raise QmtInputError(f"waypoint count {n} must be >= 1")
    if not exponent > 0:
        raise QmtInputError(f"spacing exponent {exponent} must be positive (1 = linear, eq. 14; 1.5 = eq. 15)")
    return (np.arange(n + 1) / n) ** exponent


def line_waypoints(start_xy, goal_xy, n: int = SEED_WAYPOINTS, exponent: float = 1.0,
                   geom: CraneGeometry = TABLE1) -> tuple[np.ndarray, np.ndarray]:
    """(xy (n+1, 2) [m], theta (n+1, 3) [rad]): IK of every waypoint on the line, tray level."""
    a, b = np.asarray(start_xy, float), np.asarray(goal_xy, float)
    s = spacing(n, exponent)
    xy = a + (b - a) * s[:, None]
    tray_ik(*a, geom), tray_ik(*b, geom)  # one-line errors before the loop
    return xy, np.array([tray_ik(x, y, geom) for x, y in xy])


@dataclass
class GoalSchedule:
    """Servo goal positions held from times[k] to times[k + 1] (the last one to the end)."""

    times: np.ndarray  # (K,) [s]
    goals: np.ndarray  # (K, 3) [rad]
    t_end_s: float
    phases: dict = field(default_factory=dict)  # name -> (t0, t1) [s]
    label: str = ""

    def goal_at(self, t) -> np.ndarray:
        k = np.clip(np.searchsorted(self.times, np.asarray(t, float), side="right") - 1, 0, len(self.times) - 1)
        return self.goals[k]

    @property
    def q_start(self) -> np.ndarray:
        return self.goals[0]


def seed_motion(exponent: float, *, start_xy=SEED_START_XY_M, goal_xy=SEED_GOAL_XY_M, n: int = SEED_WAYPOINTS,
                move_s: float = SEED_MOVE_S, settle_s: float = 2.0, hold_s: float = SEED_HOLD_S,
                return_s: float = SEED_RETURN_S, tail_s: float = 1.5, initial_posture=INITIAL_POSTURE_RAD,
                with_return: bool = True, geom: CraneGeometry = TABLE1) -> GoalSchedule:
    """The seed's run: settle at the start, the line in move_s, hold, return to the initial posture."""
    for name, v in (("move_s", move_s), ("settle_s", settle_s), ("hold_s", hold_s), ("return_s", return_s)):
        if not v >= 0 or (name == "move_s" and v <= 0):
            raise QmtInputError(f"{name} = {v} s must be positive")
    _, theta = line_waypoints(start_xy, goal_xy, n, exponent, geom)
    t_line = settle_s + move_s * np.arange(n + 1) / n
    times, goals = [np.array([0.0]), t_line], [theta[:1], theta]
    t = settle_s + move_s
    phases = {"settle": (0.0, settle_s), "move": (settle_s, t)}
    if with_return:
        s = spacing(n, exponent)
        q0 = np.asarray(initial_posture, float)
        back = theta[-1] + (q0 - theta[-1]) * s[:, None]
        t_back = t + hold_s + return_s * np.arange(n + 1) / n
        times.append(t_back[1:])
        goals.append(back[1:])
        phases["hold"] = (t, t + hold_s)
        phases["return"] = (t + hold_s, t + hold_s + return_s)
        t = t + hold_s + return_s
    times = np.concatenate(times)
    goals = np.concatenate(goals)
    keep = np.concatenate([[True], np.diff(times) > 0])  # the start waypoint appears twice
    label = "linear (eq. 14)" if exponent == 1.0 else f"eased p={exponent:g} (eq. 15)"
    return GoalSchedule(times[keep], goals[keep], t + tail_s, phases, label)


def toppra_line(bottle, *, start_xy=SEED_START_XY_M, goal_xy=SEED_GOAL_XY_M, n: int = SEED_WAYPOINTS,
                margin: float = 0.8, speed_fraction: float = 0.8, settle_s: float = 1.0, tail_s: float = 1.5,
                stream_period_s: float = 1e-3, time_scale: float = 1.0, geom: CraneGeometry = TABLE1,
                batched: bool = True, polygon_sides: int = 4):
    """The fastest time scaling of the seed's IK line that keeps the bottle (TOPP-RA).

    Path: a cubic spline through the n + 1 IK waypoints (linear spacing) over s in [0, 1]; the grid
    is the waypoints. Constraint: the crane-tray scenario's LimitSet for this bottle
    (tray/planning.py: no slide, no tip, no lift-off with friction and ring radius x `margin` (the
    servos lag the plan, so the plan keeps room), motor torques, joint speeds within
    speed_fraction of each servo's no-load speed) as ONE toppra constraint
    (LimitSet.toppra_constraint; batched=False: toppra's per-grid-point evaluation, for timing).
    The plan is re-checked by sampling it at the stream period (also between grid points) with the
    true mu and ring, through Drake's own kinematics (conditions.tray_kinematics); the goal stream
    is that sampling (ZOH). time_scale > 1 streams the same plan slowed down (q(t / time_scale)).
    Returns (GoalSchedule, info dict) or (None, info) when TOPP-RA finds no parametrisation;
    info["solve_s"] / ["solve_cpu_s"] are the TOPP-RA wall / process CPU time (constraint
    parameters + solve + parametrisation; CPU time is less disturbed by other loads). Solved by the one
    TOPP-RA (planners/toppra_core.parameterise) with toppra's constant-acceleration output."""
    # lazy: toppra loads matplotlib.pyplot, too slow for every CLI start
    import toppra as ta

    if not 0 < margin <= 1:
        raise QmtInputError(f"planning margin {margin} must be in (0, 1]")
    if not time_scale >= 1.0:
        raise QmtInputError(f"time scale {time_scale} must be >= 1 (1 = the TOPP-RA timing)")
    _, theta = line_waypoints(start_xy, goal_xy, n, 1.0, geom)
    ss = np.linspace(0.0, 1.0, n + 1)
    path = ta.SplineInterpolator(ss, theta)
    ls = tray_scenario(bottle, margin, speed_fraction).limit_set
    t0, c0 = _time.perf_counter(), _time.process_time()
    constraint = ls.toppra_constraint(batched=batched, tray_polygon_sides=polygon_sides)
    traj = parameterise(path, [constraint], ss).toppra_trajectory("ParametrizeConstAccel")
    solve_s, solve_cpu_s = _time.perf_counter() - t0, _time.process_time() - c0
    info = {"solve_s": solve_s, "solve_cpu_s": solve_cpu_s, "batched": batched, "margin": margin, "gridpoints": n + 1,
            "friction": bottle.friction, "com_height_m": bottle.com_height_m}
    if traj is None:
        info["feasible"] = False
        rest = np.zeros_like(theta)  # name the limit with the largest ratio at rest on the line
        w = worst_at_rest(ls.columns(theta, rest, rest), ls.column_names, ls.ratio_mask)
        info["infeasible"] = "toppra found no parameterization: " + describe_at_rest(
            w, f"waypoint {w['sample']} of {len(theta) - 1}")
        return None, info
    T = float(traj.duration)
    t = np.arange(0.0, T + 0.5 * stream_period_s, stream_period_s)
    t[-1] = min(t[-1], T)
    q, qd, qdd = traj(t), traj(t, 1), traj(t, 2)
    info["planned_duration_s"] = T
    r = tray_ratios(contact_wrench(tray_kinematics(q, qd, qdd, [0, 0, bottle.com_height_m]), bottle), bottle)
    vmax = np.array([s.no_load_speed_rad_s * speed_fraction for s in CRANE_X7_PLANAR_SERVOS])
    fk = np.array([tray_fk(x, geom) for x in q])
    a, b = np.asarray(start_xy, float), np.asarray(goal_xy, float)
    d = b - a
    off_line = np.abs((fk[:, 0] - a[0]) * d[1] - (fk[:, 1] - a[1]) * d[0]) / np.hypot(*d)
    info.update(feasible=True, duration_s=T, max_slide_ratio=float(np.max(r["slide"])),
                max_tip_ratio=float(np.max(r["tip"])), max_lift_ratio=float(np.max(r["lift"])),
                max_speed_ratio=float(np.max(np.abs(qd) / vmax)), max_off_line_m=float(np.max(off_line)),
                max_tray_tilt_rad=float(np.max(np.abs(fk[:, 2]))))
    Ts = T * time_scale
    ts = np.arange(0.0, Ts + 0.5 * stream_period_s, stream_period_s)
    ts[-1] = min(ts[-1], Ts)
    info["duration_s"] = Ts
    label = f"TOPP-RA line, margin {margin:g}, x{time_scale:g}"
    return _stream(traj(ts / time_scale), ts, settle_s, tail_s, label), info


def _stream(q: np.ndarray, t: np.ndarray, settle_s: float, tail_s: float, label: str) -> GoalSchedule:
    times = np.concatenate([[0.0], settle_s + t])
    goals = np.vstack([q[:1], q])
    T = float(t[-1])
    phases = {"settle": (0.0, settle_s), "move": (settle_s, settle_s + T)}
    return GoalSchedule(times, goals, settle_s + T + tail_s, phases, label)


def ruckig_line(bottle, *, start_xy=SEED_START_XY_M, goal_xy=SEED_GOAL_XY_M, margin: float = 0.8,
                jerk_m_s3: float = 20.0, speed_fraction: float = 0.8, settle_s: float = 1.0, tail_s: float = 1.5,
                stream_period_s: float = 1e-3, time_scale: float = 1.0, geom: CraneGeometry = TABLE1):
    """Jerk-limited time-optimal motion along the line (Ruckig, 1 DOF: the distance travelled).

    The tray stays level on a horizontal line, so the bottle sees only the tray's horizontal
    acceleration a: it sticks while |a| <= mu g and stands while |a| <= (r_c / h_G) g (conditions.py
    at w = alpha = 0). Limits: |a| <= margin min(mu, r_c / h_G) g, |jerk| <= jerk_m_s3, speed within
    speed_fraction of the servos' no-load speeds through the IK Jacobian along the line (the worst
    waypoint). Each streamed sample is solved by IK; time_scale > 1 streams it slowed down
    (speed / k, acceleration / k^2, jerk / k^3). Returns (GoalSchedule, info)."""
    if not 0 < margin <= 1 or not jerk_m_s3 > 0:
        raise QmtInputError(f"margin {margin} must be in (0, 1] and jerk {jerk_m_s3} m/s^3 positive")
    a, b = np.asarray(start_xy, float), np.asarray(goal_xy, float)
    L = float(np.hypot(*(b - a)))
    xy, theta = line_waypoints(a, b, 200, 1.0, geom)
    dtheta_dx = np.abs(np.diff(theta, axis=0)) / (L / 200)
    vmax_joint = np.array([s.no_load_speed_rpm * RPM * speed_fraction for s in CRANE_X7_PLANAR_SERVOS])
    v_max = float(np.min(vmax_joint / np.maximum(dtheta_dx, 1e-9)))
    a_max = level_tray_acceleration_cap_m_s2(bottle, margin)
    traj, _ = rest_to_rest([0.0], [L], [v_max], [a_max], [jerk_m_s3])  # planners/ruckig_core
    if traj is None:
        raise QmtInputError("Ruckig found no trajectory for the tray line; check the limits")
    if not time_scale >= 1.0:
        raise QmtInputError(f"time scale {time_scale} must be >= 1 (1 = the Ruckig timing)")
    T = float(traj.duration) * time_scale
    t = np.arange(0.0, T + 0.5 * stream_period_s, stream_period_s)
    t[-1] = min(t[-1], T)
    dist = RuckigProfile(traj).evaluate(t / time_scale)[0][:, 0]  # the one Ruckig evaluator
    pts = a + np.outer(dist / L, b - a)
    q = np.array([tray_ik(x, y, geom) for x, y in pts])
    info = {"duration_s": T, "planned_duration_s": float(traj.duration), "a_max_m_s2": a_max, "v_max_m_s": v_max,
            "jerk_m_s3": jerk_m_s3, "margin": margin}
    return _stream(q, t, settle_s, tail_s, f"Ruckig line, margin {margin:g}, jerk {jerk_m_s3:g}"), info
