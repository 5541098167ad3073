"""Planar kinematics of the vertical arm: tip position (seed 001 eq. 4), its Jacobian, the height
of the centre of gravity, the self-motion manifold of a redundant 3-link arm and the start-posture
rule.

Eq. (4): X1 = sum_i l_i cos(theta_1 + ... + theta_i), X2 = sum_i l_i sin(...). X2 is UP here
(gravity along -X2; README.md says why).

Start-posture rule (paper, step I: "the posture with the lowest centre of gravity that satisfies
(4) and (6)"). For a 3-link arm and a tip point X the postures form a one-parameter family: fix
the absolute angle psi of link 3, the wrist W = X - l3 (cos psi, sin psi) is reached by links 1-2
with elbow sign +1 or -1. `lowest_cog_posture` samples psi on a 1/4-degree grid on both elbow
branches, keeps reachable points, takes the lowest mass-weighted centre of gravity and refines it
with a bounded scalar search (Brent) on that branch around the best sample. Ties (a symmetric
manifold) are broken by the smaller joint travel from zero. Angles are wrapped to (-pi, pi].
When X is at full reach (|X| = l1 + l2 + l3 within 1e-9 m) the only posture is the stretched one.

Units: m, rad.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar

from qmt_drake.energy.dynamics import VerticalArm
from qmt_drake.errors import QmtInputError


def tip_position(arm: VerticalArm, q) -> np.ndarray:
    """(..., 2) tip point X of eq. (4) for joint angles (..., n): the project's planar chain of the
    arm's URDF (model/planar.py; its plane coordinates are (x, z) = (X1, X2))."""
    return arm.chain.tip_position(np.asarray(q, dtype=float))


def tip_jacobian(arm: VerticalArm, q) -> np.ndarray:
    """(..., 2, n) dX/dq (model/planar.py)."""
    return arm.chain.jacobian(np.asarray(q, dtype=float))


def cog_height_m(arm: VerticalArm, q) -> np.ndarray:
    """Mass-weighted X2 of links (centre of each rod) and tip mass."""
    phi = np.cumsum(np.asarray(q, dtype=float), axis=-1)
    s = np.sin(phi)
    joint_y = np.concatenate([np.zeros(s.shape[:-1] + (1,)),
                              np.cumsum(arm.length_m * s, axis=-1)], axis=-1)
    h = np.sum(arm.mass_kg * (joint_y[..., :-1] + arm.com_m * s), axis=-1) + arm.tip_mass_kg * joint_y[..., -1]
    return h / (np.sum(arm.mass_kg) + arm.tip_mass_kg)


def check_reachable(arm: VerticalArm, X, what: str) -> None:
    X = np.asarray(X, dtype=float)
    if X.shape != (2,) or not np.all(np.isfinite(X)):
        raise QmtInputError(f"{what} must be two finite numbers (X1, X2) in metres, got {X.tolist()}")
    l = arm.length_m  # noqa: E741 - the paper's link lengths l_i
    r = float(np.hypot(*X))
    r_min = max(0.0, 2 * l.max() - l.sum())
    if r > arm.reach_m + 1e-9 or r < r_min - 1e-9:
        raise QmtInputError(f"{what} ({X[0]:g}, {X[1]:g}) m is out of reach: its distance {r:.4g} m "
                            f"from joint 1 must lie in [{r_min:.4g}, {arm.reach_m:.4g}] m")


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def posture_on_manifold(arm: VerticalArm, X, psi, elbow) -> tuple[np.ndarray, np.ndarray]:
    """Joint angles (K, 3) for last-link absolute angles psi (K,) and elbow sign (+1/-1);
    also a (K,) mask of the reachable ones."""
    l1, l2, l3 = arm.length_m
    psi = np.atleast_1d(np.asarray(psi, dtype=float))
    wx, wy = X[0] - l3 * np.cos(psi), X[1] - l3 * np.sin(psi)
    c2 = (wx ** 2 + wy ** 2 - l1 ** 2 - l2 ** 2) / (2 * l1 * l2)
    ok = np.abs(c2) <= 1.0 + 1e-12
    q2 = elbow * np.arccos(np.clip(c2, -1.0, 1.0))
    q1 = np.arctan2(wy, wx) - np.arctan2(l2 * np.sin(q2), l1 + l2 * np.cos(q2))
    q3 = psi - q1 - q2
    return _wrap(np.stack([q1, q2, q3], axis=-1)), ok


def self_motion_samples(arm: VerticalArm, X, step_deg: float = 0.25) -> np.ndarray:
    """Postures (K, 3) reaching X, sampled along the manifold on both elbow branches."""
    psi = np.radians(np.arange(0.0, 360.0, step_deg))
    out = []
    for e in (1.0, -1.0):
        q, ok = posture_on_manifold(arm, X, psi, e)
        out.append(q[ok])
    return np.concatenate(out)


def lowest_cog_posture(arm: VerticalArm, X) -> np.ndarray:
    """The start-posture rule (module docstring)."""
    X = np.asarray(X, dtype=float)
    check_reachable(arm, X, "start point X(0)")
    if abs(np.hypot(*X) - arm.reach_m) < 1e-9:
        return np.array([np.arctan2(X[1], X[0]), 0.0, 0.0])
    psi = np.radians(np.arange(0.0, 360.0, 0.25))
    best = None
    for e in (1.0, -1.0):
        q, ok = posture_on_manifold(arm, X, psi, e)
        if not ok.any():
            continue
        h = np.where(ok, cog_height_m(arm, q), np.inf)
        k = int(np.argmin(h))
        lo, hi = psi[k] - np.radians(0.5), psi[k] + np.radians(0.5)

        def f(p, e=e):
            qq, okk = posture_on_manifold(arm, X, p, e)
            return float(cog_height_m(arm, qq)[0]) if okk[0] else np.inf
        r = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
        cand = posture_on_manifold(arm, X, r.x, e)[0][0]
        key = (round(float(r.fun), 12), float(np.sum(np.abs(cand))))
        if best is None or key < best[0]:
            best = (key, cand)
    return best[1]
