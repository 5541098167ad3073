"""One outcome vocabulary for every co-simulated transfer (magnet, tray, any later hand).

    carried     the part is on the hand at the end, never lost, slip below the hand's limit,
                and the arm ended within the arrival tolerance of the plan's goal
    slipped     on the hand at the end but it slid beyond the hand's slip limit
    detached    (magnet) the part left the face
    slid_off    (tray) the bottle's base left the tray surface
    tipped      (tray) the bottle tilted past its tipping angle
    unfinished  the part stayed, but the arm did not reach the goal: a transfer not made is not a
                carried one (e.g. a replay too fast for the motors, or a plan cut short)
    collided    the arm or the part it carries touched an obstacle of the scenario's cell (spatial
                scenarios with world.obstacles; limits/clearance.py on the simulated motion)

A collision before the part was lost outranks everything, then a lost part; `held` in every result
is `outcome == "carried"`.

Arrival tolerances, max |q_goal - q| over the joints at the end of the run [rad]:
- DC motors with PID (magnet scenarios): 1e-3 rad; the shipped thesis plans end within 1e-6 rad.
- Dynamixel position servos (tray): 0.1 rad. The firmware's integral term settles the last few
  hundredths of a radian under gravity over seconds (0.07 rad left at the end of the 1.5 s tail for
  the crane-tray TOPP-RA plan at time scale 2.05, 0.007 rad after 8 s), so a tighter bound would
  call every tray run unfinished; an arm that never left the start (about 1.4 rad away) is caught.
"""

from __future__ import annotations

OUTCOMES = ("carried", "slipped", "detached", "slid_off", "tipped", "unfinished", "collided")
LOST_OUTCOMES = ("detached", "slid_off", "tipped")
ARRIVAL_TOLERANCE_DC_MOTOR_RAD = 1e-3
ARRIVAL_TOLERANCE_SERVO_RAD = 0.1


def transfer_outcome(lost: str | None, slipped: bool, final_goal_error_rad: float,
                     arrival_tolerance_rad: float) -> str:
    """The run's one outcome word (module docstring). lost: one of LOST_OUTCOMES or None."""
    if lost is not None:
        if lost not in LOST_OUTCOMES:
            raise ValueError(f"lost must be one of {LOST_OUTCOMES} or None, got {lost!r}")
        return lost
    if slipped:
        return "slipped"
    if not final_goal_error_rad <= arrival_tolerance_rad:  # NaN (not measured) is not arrived
        return "unfinished"
    return "carried"


def with_collision(outcome: str, collided_at_s: float | None, lost_at_s: float | None = None) -> str:
    """'collided' when the run touched an obstacle (collided_at_s) before the part was lost (or never
    lost), else `outcome` (module docstring)."""
    if collided_at_s is None or (outcome in LOST_OUTCOMES and lost_at_s is not None and lost_at_s < collided_at_s):
        return outcome
    return "collided"


def verdict_line(outcome: str, lost_at_s: float | None = None) -> str:
    """What the CLI prints for an outcome: 'carried', or 'LOST (slid off at 1.234 s)', ..."""
    if outcome == "carried":
        return "carried"
    if outcome == "unfinished":
        return "UNFINISHED (the arm did not reach the goal)"
    if outcome == "collided":
        return f"COLLIDED (touched an obstacle{'' if lost_at_s is None else f' at {lost_at_s:.3f} s'})"
    if outcome == "slipped":
        return "LOST (slipped on the hand beyond its limit)"
    at = f" at {lost_at_s:.3f} s" if lost_at_s is not None else ""
    return f"LOST ({outcome.replace('_', ' ')}{at})"
