"""Tight timing of spatial motions: the smallest uniform time scale that keeps every limit, in closed form.

Played k times slower, a motion's joint speeds are qd / k and its accelerations qdd / k^2, so every
quantity w that is affine in qdd and quadratic in qd (the toppra form of a LimitTerm: joint torques with
gravity, the suction grip's contact wrench, the tray's) is w0 + (w1 - w0) / k^2, w1 at k = 1 and w0
at rest (qd = qdd = 0, gravity alone). A row F_r w <= g_r then holds for k^2 >= F_r (w1 - w0) /
(g_r - F_r w0) where F_r (w1 - w0) > 0, and at any k where it does not; a row broken at rest
(g_r < F_r w0) holds at no k >= 1 nor in the limit, so the motion has no tight scale (inf), as in
spatial_trajectory.scale_to_hold. Joint speed and acceleration limits give k >= |qd| / v and k^2 >=
|qdd| / a. `tight_scales` takes the largest over `samples` points of each trajectory, all
trajectories in two batched SpatialChain evaluations: the exact tight scale on those samples, where
scale_to_hold bisects with one check per step. Rows that are polygons inside a circle or cone (the
magnet's moment, the tray's) are stricter than the ratio column, so there k is on the safe side.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.base import RowOptions

# samples per motion: about the planners' check rate (200 Hz) over a 2.4 s transfer; the plans are
# then re-checked and held at the re-check rate (10x) like every spatial plan
TIGHT_SAMPLES = 500
# the magnet's moment circle and the tray's cone and disc as 64-gons inside them (RowOptions): the
# scale is then at most ~0.1 % on the safe side where those terms bind (32 and 4 sides: 0.2 %)
TIGHT_ROWS = RowOptions(polygon_sides=64, tray_polygon_sides=64)


def tight_scales(sc, trajectories, samples: int = TIGHT_SAMPLES, options: RowOptions | None = None) -> np.ndarray:
    """(P,) smallest time scale k of each trajectory (k < 1: it may be played faster) at which its
    joint speed/acceleration limits and every term of sc.terms() hold at `samples` points evenly
    spaced in its own time; inf where no scale makes it hold."""
    options = options or TIGHT_ROWS
    trajectories = list(trajectories)
    t_of = [np.linspace(0.0, tr.duration_s, samples) for tr in trajectories]
    Q, QD, QDD = (np.concatenate(parts) for parts in zip(*(tr.sample(t) for tr, t in zip(trajectories, t_of))))
    zero = np.zeros_like(QD)
    at_speed, at_rest = sc.chain.evaluate(Q, QD, QDD), sc.chain.evaluate(Q, zero, zero)
    k2 = np.maximum(np.max((QD / sc.velocity_limit_rad_s) ** 2, axis=1),
                    np.max(np.abs(QDD) / sc.acceleration_limit_rad_s2, axis=1))
    for term in sc.terms():
        rows, w0, w1 = term.toppra_rows(options), term.toppra_w(at_rest), term.toppra_w(at_speed)
        if rows is None or w0 is None:
            raise QmtInputError(f"tight timing: the limit {term.name!r} has no linear form on this arm; "
                                "run the GA without tight timing")
        F, g = rows
        slack = g - np.einsum("sm,km->sk", w0, F)  # einsum: no threaded BLAS on a shared machine
        motion = np.einsum("sm,km->sk", w1 - w0, F)
        with np.errstate(divide="ignore", invalid="ignore"):
            need = np.where(slack > 0, motion / slack, np.where(motion > 0, np.inf, 0.0))
        need[slack < 0] = np.inf
        k2 = np.maximum(k2, need.max(axis=1))
    return np.sqrt(k2.reshape(len(trajectories), samples).max(axis=1))
