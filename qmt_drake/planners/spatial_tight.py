"""Tight timing of spatial motions: the smallest uniform time scale k that keeps every limit.

Played k times slower (v = 1/k), a motion's joint speeds are v qd and its accelerations v^2 qdd; the
hand's twist scales with v, its accelerations with v^2, and every quantity w affine in qdd and at
most quadratic in qd (joint torques with gravity and joint damping, the contact wrench of the carried
body) is w0 + v w_lin + v^2 w_quad: w0 at rest (gravity alone), w_lin = (w(qd) - w(-qd)) / 2 (the
damping), w_quad = (w(qd) + w(-qd)) / 2 - w0, with w(+-qd) at (+-qd, qdd). Three batched SpatialChain
evaluations therefore give the hand state at any v (`_state_at`).

A row F_r w <= g_r of a term's toppra form holds from v = 0 (at rest, where it must) up to the first
root of Q v^2 + L v - s = 0 (Q = F_r w_quad, L = F_r w_lin, s = g_r - F_r w0), v_r = 2 s / (L +
sqrt(L^2 + 4 Q s)) where that is positive, and for every v where there is none; joint speed and
acceleration limits are rows of the same kind. k_rows = 1 / min_r v_r is then exact on the samples
where the rows are the term's limit (the suction polyhedron, joint torques). Where they are polygons
inside its circles (the tray's friction cone and base circle, the magnet's moment circle) the terms'
ratio columns hold at k_rows with room to spare; k is then bisected on the columns themselves between
k_rows and the joint limits' own scale (timescale.bisect_batch: the Illinois regula falsi, in v = 1/k). `tight_scales` does this for many trajectories at
`samples` points each: the scale at which their largest ratio is 1 on those samples, where
spatial_trajectory.scale_to_hold bisects with a full check per step.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.base import RowOptions
from qmt_drake.model.spatial_chain import HandSample
from qmt_drake.timescale import bisect_batch

# samples per motion: about the planners' check rate (200 Hz) over a 2.4 s transfer; the plans are
# then re-checked and held at the re-check rate (10x) like every spatial plan
TIGHT_SAMPLES = 500
TIGHT_REL_TOL = 1e-9  # the columns' refinement stops when its bracket in v is this narrow (relative)
TIGHT_MAX_STEPS = 60


def _first_root(Q, L, s):
    """Largest v >= 0 up to which Q v^2 + L v <= s (s > 0) holds from v = 0; inf when it always does."""
    disc = L * L + 4.0 * Q * s
    with np.errstate(invalid="ignore", divide="ignore"):
        den = L + np.sqrt(np.maximum(disc, 0.0))
        v = np.where((disc >= 0.0) & (den > 0.0), 2.0 * s / np.where(den > 0.0, den, 1.0), np.inf)
    return v


def _state_at(parts, v, sel) -> HandSample:
    """The hand state of samples `sel` at speed factors v (len(sel),) from the three evaluations
    (rest, +qd, -qd)."""
    rest, plus, minus = ({k: x[sel] for k, x in p.items()} for p in parts)
    v1, v2 = v[:, None], (v * v)[:, None]
    lin = 0.5 * (plus["joint_torque_Nm"] - minus["joint_torque_Nm"])
    quad = 0.5 * (plus["joint_torque_Nm"] + minus["joint_torque_Nm"]) - rest["joint_torque_Nm"]
    return HandSample(position_m=rest["position_m"], rotation=rest["rotation"],
                      angular_velocity_rad_s=plus["angular_velocity_rad_s"] * v1,
                      linear_velocity_m_s=plus["linear_velocity_m_s"] * v1,
                      angular_acceleration_rad_s2=plus["angular_acceleration_rad_s2"] * v2,
                      linear_acceleration_m_s2=plus["linear_acceleration_m_s2"] * v2,
                      joint_torque_Nm=rest["joint_torque_Nm"] + lin * v1 + quad * v2)


def _column_max(sc, terms, parts, QD, QDD, v, which, samples: int):
    """(len(which),) the largest ratio over the samples of trajectories `which` at speed factors v."""
    sel = (np.asarray(which)[:, None] * samples + np.arange(samples)).ravel()
    vs = np.repeat(v, samples)
    state = _state_at(parts, vs, sel)
    worst = np.maximum(np.max(np.abs(QD[sel]) / sc.velocity_limit_rad_s, axis=1) * vs,
                       np.max(np.abs(QDD[sel]) / sc.acceleration_limit_rad_s2, axis=1) * vs * vs)
    for term in terms:
        worst = np.maximum(worst, np.max(term.columns(state), axis=1))
    return worst.reshape(len(which), samples).max(axis=1)


def tight_scales(sc, trajectories, samples: int = TIGHT_SAMPLES) -> np.ndarray:
    """(P,) smallest time scale k of each trajectory (k < 1: it may be played faster) at which its
    joint speed/acceleration limits and every term of sc.terms() hold at `samples` points evenly
    spaced in its own time; inf where no scale makes it hold (a limit broken at rest). The terms'
    rows are RowOptions' defaults: polygons inside the circles, never looser than the columns."""
    options = RowOptions()
    trajectories = list(trajectories)
    P = len(trajectories)
    terms = sc.terms()
    t_of = [np.linspace(0.0, tr.duration_s, samples) for tr in trajectories]
    Q, QD, QDD = (np.concatenate(x) for x in zip(*(tr.sample(t) for tr, t in zip(trajectories, t_of))))
    zero = np.zeros_like(QD)
    parts = (sc.chain.evaluate(Q, zero, zero), sc.chain.evaluate(Q, QD, QDD), sc.chain.evaluate(Q, -QD, QDD))
    v_joint = np.minimum(_first_root(0.0, np.max(np.abs(QD) / sc.velocity_limit_rad_s, axis=1), 1.0),
                         _first_root(np.max(np.abs(QDD) / sc.acceleration_limit_rad_s2, axis=1), 0.0, 1.0))
    v_rows = v_joint.copy()
    for term in terms:
        rows = term.toppra_rows(options)
        w0, wp, wm = (term.toppra_w(p) for p in parts)
        if rows is None or w0 is None:
            raise QmtInputError(f"tight timing: the limit {term.name!r} has no linear form on this arm; "
                                "run the GA without tight timing")
        F, g = rows
        s = g - np.einsum("sm,km->sk", w0, F)  # einsum: no threaded BLAS on a shared machine
        L = np.einsum("sm,km->sk", 0.5 * (wp - wm), F)
        Qr = np.einsum("sm,km->sk", 0.5 * (wp + wm) - w0, F)
        v = np.where(s > 0.0, _first_root(Qr, L, np.where(s > 0.0, s, 1.0)), 0.0)
        v[(s == 0.0) & (Qr <= 0.0) & (L <= 0.0)] = np.inf  # on the row at rest, and moving eases it
        v_rows = np.minimum(v_rows, v.min(axis=1))
    # lo: every row holds, so every column; hi: the joint limits' own bound (the slowest sample of each)
    lo, hi = v_rows.reshape(P, samples).min(axis=1), v_joint.reshape(P, samples).min(axis=1)
    ready = np.flatnonzero(np.isfinite(lo) & (lo > 0.0) & (hi > lo))

    def excess(v, which):  # largest ratio - 1 of trajectories `which` (indices into ready) at v
        return _column_max(sc, terms, parts, QD, QDD, v, ready[which], samples) - 1.0

    if len(ready):
        g_lo = excess(lo[ready], np.arange(len(ready)))
        loose = np.flatnonzero(g_lo < -1e-9)  # polygon rows inside the columns' circles: room left
        if len(loose):
            g_hi = excess(hi[ready][loose], loose)
            done = g_hi <= 0.0  # the joint limits bind first
            lo[ready[loose[done]]] = hi[ready[loose[done]]]
            rest = loose[~done]
            if len(rest):
                lo[ready[rest]] = bisect_batch(lambda v, i: excess(v, rest[i]), lo[ready[rest]].copy(),
                                               hi[ready[rest]].copy(), g_lo[rest].copy(), g_hi[~done].copy(),
                                               rel_tol=TIGHT_REL_TOL, max_steps=TIGHT_MAX_STEPS, midpoint="illinois")
    with np.errstate(divide="ignore"):
        return 1.0 / lo
