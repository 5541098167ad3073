"""Ruckig's time-optimal rest-to-rest motion between two joint positions of a spatial arm: the planner
(planners/spatial_methods) and the plan files (planners/spatial_plan_io, which rebuild a Ruckig plan by
running Ruckig again on the same five inputs) share this one call."""

from __future__ import annotations

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Trajectory

from qmt_drake.errors import QmtInputError


def ruckig_rest_to_rest(qa, qb, max_velocity, max_acceleration, max_jerk):
    """Ruckig's time-optimal rest-to-rest motion qa -> qb (rad) under these joint limits (rad/s,
    rad/s^2, rad/s^3); deterministic, so a plan file rebuilds a segment from these five inputs."""
    n = len(qa)
    inp = InputParameter(n)
    inp.current_position, inp.target_position = np.asarray(qa, float).tolist(), np.asarray(qb, float).tolist()
    inp.current_velocity = inp.current_acceleration = [0.0] * n
    inp.target_velocity = inp.target_acceleration = [0.0] * n
    inp.max_velocity = np.asarray(max_velocity, float).tolist()
    inp.max_acceleration = np.asarray(max_acceleration, float).tolist()
    inp.max_jerk = np.asarray(max_jerk, float).tolist()
    traj = Trajectory(n)
    res = Ruckig(n).calculate(inp, traj)
    if res not in (Result.Working, Result.Finished):
        raise QmtInputError(f"Ruckig found no trajectory between task poses ({res}); check the limits")
    return traj


def ruckig_segment_limits(sc, factor: float):
    """(velocity, acceleration, jerk) limits of a Ruckig segment: acceleration and jerk times factor."""
    return sc.velocity_limit_rad_s, sc.acceleration_limit_rad_s2 * factor, sc.jerk_limit_rad_s3 * factor
