"""The discrete closed loop of a held joint law, and the gains chosen for its period (docs/spatial_drives.md).

A law sampled every T = m h and held over the plant's m steps of h (sim/spatial_actuation, a held law behind a
current amplifier: the motors' torque is the law's held command) on the arm linearised at rest, M the full mass
matrix [kg m^2] (reflected rotor inertia and the part included), per plant step (the discrete plant, the damping
D_plant [N m s/rad] stepped implicitly, sim/actuation.add_implicit_damping_actuation):

    v+ = (M + h D_plant)^-1 (M v + h tau),   q+ = q + h v+,      tau = -K q - D v   at the sample, held

`held_loop_poles` is the one-hold map's eigenvalues; `least_damping` the smallest damping ratio among them
(z = exp(s T): zeta = -ln|z| / |ln z|). Decentralised joint gains designed on the diagonal of M for a continuous
loop lose damping when held: the coupled modes' inertia is smaller than the diagonal's, and the hold's half-period
delay costs phase (measured: the Panda's 30 rad/s loops at 8 ms have least damping 0.11, at 10 ms they are
unstable). `period_scale` is the largest s in (0, 1] for which K s^2, D s keep HELD_MIN_DAMPING: the loop slowed by
s (its natural frequencies times s, its damping ratios kept) until its period can hold it.
"""

from __future__ import annotations

import numpy as np

HELD_MIN_DAMPING = 0.7  # the least damping ratio a held loop's discrete poles keep (period_scale)
SCALE_STEP = 0.98  # period_scale's search: s = 1, 0.98, 0.98^2, ...
SCALE_FLOOR = 0.05  # below it the period cannot hold the loop at all (refused)


def held_loop_poles(M, K, D, h: float, m: int, D_plant=None) -> np.ndarray:
    """Eigenvalues of the one-hold map (module docstring) of the law tau = -K q - D v [N m] (K, D per joint or
    matrices) held over m plant steps of h [s]; D_plant: the joint damping stepped implicitly by the plant."""
    M = np.atleast_2d(np.asarray(M, float))
    n = len(M)
    K = np.diag(K) if np.ndim(K) == 1 else np.asarray(K, float)
    D = np.diag(D) if np.ndim(D) == 1 else np.asarray(D, float)
    Dp = np.zeros((n, n)) if D_plant is None else np.diag(np.broadcast_to(np.asarray(D_plant, float), (n,)))
    W = np.linalg.inv(M + h * Dp)
    A = np.block([[np.eye(n), h * W @ M], [np.zeros((n, n)), W @ M]])  # one step of (q, v), torque zero
    B = np.vstack([h * h * W, h * W])  # ... and of a torque held over it
    Phi, Gam = np.eye(2 * n), np.zeros((2 * n, n))
    for _ in range(int(m)):
        Phi, Gam = A @ Phi, A @ Gam + B
    return np.linalg.eigvals(Phi - Gam @ np.hstack([K, D]))


def least_damping(z) -> float:
    """The smallest damping ratio of discrete poles z (a pole outside the unit circle: negative)."""
    z = np.asarray(z, complex)
    lz = np.log(np.where(np.abs(z) < 1e-300, 1e-300, z))
    return float(np.min(-lz.real / np.maximum(np.abs(lz), 1e-300)))


def period_scale(M, K, D, h: float, m: int, D_plant=None) -> float:
    """The largest s = SCALE_STEP^k <= 1 with least_damping(held_loop_poles(M, K s^2, D s, h, m)) >=
    HELD_MIN_DAMPING; ValueError below SCALE_FLOOR (no slowing of the loop holds it at this period)."""
    K, D = np.asarray(K, float), np.asarray(D, float)
    s = 1.0
    while s >= SCALE_FLOOR:
        if least_damping(held_loop_poles(M, K * s * s, D * s, h, m, D_plant)) >= HELD_MIN_DAMPING:
            return s
        s *= SCALE_STEP
    raise ValueError(f"no slowing of the loop keeps damping {HELD_MIN_DAMPING} held over {m} steps of {h} s")
