"""The one bisection over a time scale: the smallest k in [lo, hi] (to a relative tolerance) at which
a plan played k times slower still holds, given that it holds at hi and not at lo.

Used by the spatial "slow until it holds" (planners/spatial_trajectory.scale_to_hold), the controller
stream's --hold (export.py) and the jerk limit (jerk.py). The planar baselines' search
(planners/baselines/finish.py) bisects geometrically and keeps its own loop, which its published
numbers depend on.
"""

from __future__ import annotations

from collections.abc import Callable


def smallest_holding_scale(lo: float, hi: float, holds: Callable[[float], bool], rel_tol: float) -> float:
    """Bisect [lo, hi] at arithmetic midpoints until hi / lo - 1 <= rel_tol; returns hi (a scale that
    holds). `holds(k)` says whether the plan k times slower keeps its limits."""
    while hi / lo - 1.0 > rel_tol:
        mid = 0.5 * (lo + hi)
        if holds(mid):
            hi = mid
        else:
            lo = mid
    return hi
