"""The one Ruckig call: the time-optimal jerk-limited motion from rest to rest between two positions under
per-axis velocity, acceleration and jerk limits (Ruckig community edition, offline). Every Ruckig plan goes
through `rest_to_rest`: the planar baseline (planners/baselines/ruckig_plan.py: Cartesian or joint axes,
phase synchronisation, so the motion stays on the straight line), the spatial arms (planners/spatial_ruckig.py:
joint axes, time synchronisation) and seed 002's tray line (tray/waypoints.py: one axis, the distance
along the line). The seeds' variants are its named option `phase_synchronization`; each caller words its
own refusal from the returned Ruckig result.

`RuckigProfile` is the one evaluator of a Ruckig trajectory (the planar plans' profiles, the spatial
segments, the spatial refusal): Ruckig's own at_time, vectorised, bit for bit (tests/test_one_ruckig.py).
`rest_to_rest_profile` keeps the inputs with it, which the planar plan files store to rebuild it exactly.
"""

from __future__ import annotations

import numpy as np
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
    except ValueError as exc:  # a code the Python enum lacks: -101, ErrorTrajectoryDuration (a limit so small
        # that the motion would outlast Ruckig's numerical range, 7e3 s), came out as "-101 is not a valid Result"
        if "not a valid Result" not in str(exc):
            raise
        return None, ("the motion would outlast Ruckig's numerical range (ErrorTrajectoryDuration: a velocity, "
                      "acceleration or jerk limit far too small)" if str(exc).startswith("-101") else str(exc))
    return (traj if result in (Result.Working, Result.Finished) else None), result


class RuckigProfile:
    """The one evaluator of a Ruckig trajectory (rest to rest, one section, no brake pre-phase): Ruckig's own
    `Trajectory.at_time`, vectorised over times and written out with its arithmetic, so its values are at_time's
    bit for bit (tests/test_one_ruckig.py): per axis, the phase k is the first whose cumulative end time
    (`t_sum`, summed in order as Ruckig does) exceeds t (from the trajectory's duration on: the final state,
    jerk 0), tau = t - t_sum[k-1], and p + tau (v + tau (a / 2 + tau j / 6)), v + tau (a + tau j / 2),
    a + tau j from that phase's start state and jerk. `inputs`: what rest_to_rest was given (a plan file
    rebuilds the trajectory from them, Ruckig being deterministic); `switch_times_s`: every axis's phase
    switches, 0 and the duration."""

    def __init__(self, trajectory, inputs: dict | None = None) -> None:
        if len(trajectory.profiles) != 1:
            raise RuntimeError("a rest-to-rest Ruckig trajectory has one section")
        profs = trajectory.profiles[0]
        if any(pr.brake.duration > 0 for pr in profs):
            raise RuntimeError("ruckig returned a brake pre-phase; rest-to-rest profiles should have none")
        self.inputs = inputs
        self.duration_s = float(trajectory.duration)
        self.n = len(profs)
        self.t_sum = np.array([np.cumsum(pr.t) for pr in profs])  # (n, 7), np.cumsum adds in order as Ruckig
        self.p, self.v, self.a = (np.array([getattr(pr, k) for pr in profs], dtype=float) for k in "pva")  # (n, 8)
        self.j = np.array([[*pr.j, 0.0] for pr in profs], dtype=float)  # (n, 8): after the end, jerk 0
        self.switch_times_s = np.unique(np.clip(np.concatenate([[0.0, self.duration_s], *self.t_sum]),
                                                0.0, self.duration_s))

    def evaluate(self, t_s):
        """Position, velocity, acceleration (len(t), n) at times t [s] (the axes' units), as at_time."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        P, V, Acc = (np.empty((t.size, self.n)) for _ in range(3))
        end = t >= self.duration_s
        for i in range(self.n):
            ts = self.t_sum[i]
            k = np.where(end, 7, np.searchsorted(ts, t, side="right"))  # std::upper_bound; 7: the final state
            tau = np.where(k > 0, t - ts[np.maximum(k - 1, 0)], t)
            p, v, a, j = self.p[i][k], self.v[i][k], self.a[i][k], self.j[i][k]
            P[:, i] = p + tau * (v + tau * (a / 2 + tau * j / 6))
            V[:, i] = v + tau * (a + tau * j / 2)
            Acc[:, i] = a + tau * j
        return P, V, Acc


def rest_to_rest_profile(start, goal, max_velocity, max_acceleration, max_jerk, *,
                         phase_synchronization: bool = False) -> RuckigProfile:
    """`rest_to_rest` as a RuckigProfile that keeps its inputs (so a plan file can rebuild it exactly);
    RuntimeError naming Ruckig's result when it finds no trajectory (callers word their own refusal)."""
    traj, res = rest_to_rest(start, goal, max_velocity, max_acceleration, max_jerk,
                             phase_synchronization=phase_synchronization)
    if traj is None:
        raise RuntimeError(f"ruckig failed: {res}")
    inputs = {"start": start, "goal": goal, "max_velocity": max_velocity, "max_acceleration": max_acceleration,
              "max_jerk": max_jerk, "phase_synchronization": bool(phase_synchronization)}
    return RuckigProfile(traj, {k: (v if isinstance(v, bool) else np.array(v, dtype=float)) for k, v in inputs.items()})
