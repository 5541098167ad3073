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

from dataclasses import dataclass, field

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.tray.crane_ik import SEED_GOAL_XY_M, SEED_START_XY_M, TABLE1, CraneGeometry, tray_ik

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
