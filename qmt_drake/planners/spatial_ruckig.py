"""Ruckig's time-optimal rest-to-rest motion between two joint positions of a spatial arm: the planner
(planners/spatial_methods) and the plan files (planners/spatial_plan_io, which rebuild a Ruckig plan by
running Ruckig again on the same five inputs) share this one call. `ruckig_refusal` is the planner's
one line when no reduction of a segment's limits makes it hold: the limit that binds, named."""

from __future__ import annotations

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.at_rest import describe_at_rest, worst_terms_at_rest
from qmt_drake.planners.ruckig_core import RuckigProfile, rest_to_rest

REFUSAL_SAMPLES = 201  # positions along a refused segment where its limits are looked at at rest


def ruckig_rest_to_rest(qa, qb, max_velocity, max_acceleration, max_jerk):
    """Ruckig's time-optimal rest-to-rest motion qa -> qb (rad) under these joint limits (rad/s,
    rad/s^2, rad/s^3; planners/ruckig_core.rest_to_rest, time synchronisation); deterministic, so a plan
    file rebuilds a segment from these five inputs."""
    traj, res = rest_to_rest(qa, qb, max_velocity, max_acceleration, max_jerk)
    if traj is None:
        raise QmtInputError(f"Ruckig found no trajectory between task poses ({res}); check the limits")
    return traj


def ruckig_segment_limits(sc, factor: float):
    """(velocity, acceleration, jerk) limits of a Ruckig segment: acceleration and jerk times factor."""
    return sc.velocity_limit_rad_s, sc.acceleration_limit_rad_s2 * factor, sc.jerk_limit_rad_s3 * factor


def ruckig_refusal(sc, segment: int, slowest, factor: float, binding: str, ratio: float) -> str:
    """The one-line refusal of a Ruckig segment (`segment` 0-based, between task poses segment and segment+1)
    that no reduction of its acceleration and jerk limits makes hold: the limit with the largest ratio at
    rest along `slowest` (Ruckig's trajectory at the smallest factor tried, limits/at_rest.py) when gravity
    alone breaks it, else the `binding` column of that slowest motion's check and its `ratio`."""
    T = float(slowest.duration)
    t = np.linspace(0.0, T, REFUSAL_SAMPLES)
    q = RuckigProfile(slowest).evaluate(t)[0]  # the one evaluator (Ruckig's at_time, vectorised)
    terms = list(sc.terms())
    head = (f"Ruckig: no reduction of the acceleration and jerk limits makes segment {segment + 1} (task pose "
            f"{segment} -> {segment + 1}) hold its limits")
    if terms:
        w, state = worst_terms_at_rest(sc.chain, terms, q)
        k = w["sample"]
        where = (f"{100 * k / (len(t) - 1):.0f} % along the segment, hand at "
                 f"{np.round(state['position_m'][k], 4).tolist()} m")
        if w["ratio"] > 1.0:
            return (f"{head}: {describe_at_rest(w, where)}; no timing can hold it there (gravity alone breaks it); "
                    "relax that limit or move the pose")
    return (f"{head}: {binding} stays at {ratio:.4g} of its limit with the acceleration and jerk limits times "
            f"{factor:.3g}; relax that limit")
