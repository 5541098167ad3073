"""The one Ruckig call: the time-optimal jerk-limited motion from rest to rest between two positions under
per-axis velocity, acceleration and jerk limits (Ruckig community edition, offline). Every Ruckig plan goes
through `rest_to_rest`: the planar baseline (planners/baselines/ruckig_plan.py: Cartesian or joint axes,
phase synchronisation, so the motion stays on the straight line), the spatial arms (planners/spatial_ruckig.py:
joint axes, time synchronisation) and seed 002's tray line (tray/waypoints.py: one axis, the distance
along the line). The seeds' variants are its named option `phase_synchronization`; each caller words its
own refusal from the returned Ruckig result.
"""

from __future__ import annotations

from ruckig import InputParameter, Result, Ruckig, RuckigError, Synchronization, Trajectory


def rest_to_rest(start, goal, max_velocity, max_acceleration, max_jerk, *, phase_synchronization: bool = False):
    """(Ruckig Trajectory or None, Ruckig Result) of the motion start -> goal (n axes, at rest at both ends)
    under the limits (n each, the axes' units per s, s^2, s^3); None when Ruckig finds no trajectory, with
    its Result, or with the first line of its error when it refuses the input (a negative or zero limit).
    phase_synchronization: every axis on the same normalised profile (a straight line in the axes' space),
    else Ruckig's default time synchronisation (all axes end together)."""
    n = len(start)
    inp = InputParameter(n)
    inp.current_position = [float(x) for x in start]
    inp.target_position = [float(x) for x in goal]
    inp.current_velocity = inp.current_acceleration = [0.0] * n
    inp.target_velocity = inp.target_acceleration = [0.0] * n
    inp.max_velocity = [float(x) for x in max_velocity]
    inp.max_acceleration = [float(x) for x in max_acceleration]
    inp.max_jerk = [float(x) for x in max_jerk]
    if phase_synchronization:
        inp.synchronization = Synchronization.Phase
    traj = Trajectory(n)
    try:
        result = Ruckig(n).calculate(inp, traj)
    except RuckigError as exc:  # ruckig raises on inputs it refuses; the callers word their own refusal
        return None, next((line for line in str(exc).splitlines() if line.strip()), "RuckigError")
    return (traj if result in (Result.Working, Result.Finished) else None), result
