"""The stacked state SpatialChain steps through its joints (spatial_chain.py): the row layout of a
frame's state, and the small batched helpers that fill and use it (cross products, cos/sin from one
tan, the quadratic forms of the angular velocity as rows on its products Q).
"""

from __future__ import annotations

import numpy as np

# Rows of the stacked state of a frame K (S columns): eight 3-vectors expressed in K, then the six
# products of the angular velocity's components (w x (w x p) and w x (I w) are linear in them),
# then a row of ones. ex, ey, ez: the world axes; d: the world origin relative to K's origin;
# w, alpha: angular velocity and acceleration; v, a: velocity and classical acceleration of K's
# origin minus g. The rows a link's wrench needs (alpha .. Q) are contiguous: DYN.
E, D, W, AL, V, A = slice(0, 9), slice(9, 12), slice(12, 15), slice(15, 18), slice(18, 21), slice(21, 24)
Q = slice(24, 30)  # wx wx, wy wy, wz wz, wx wy, wx wz, wy wz
ONE = 30
NR = 31
DYN, KIN = slice(15, 30), slice(12, 30)  # alpha..Q (wrench), w..Q (hand velocity and acceleration)
QI, QJ = [12, 13, 14, 12, 12, 13], [12, 13, 14, 13, 14, 14]  # rows of w


def cross(a, b):
    """Row-wise cross product of (3, S) arrays."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def cos_sin(q, c, s):
    """cos q and sin q into c, s from t = tan(q / 2) (c = (1 - t^2) / (1 + t^2), s = 2 t / (1 + t^2)):
    one transcendental instead of two, and numpy's tan is several times faster than its cos/sin
    here; the absolute error stays at a few 1e-16 (checked against Drake to 1e-9 in the tests)."""
    t = np.tan(0.5 * q)
    t2 = t * t
    inv = 1.0 / (1.0 + t2)
    np.multiply(np.subtract(1.0, t2, out=t2), inv, out=c)
    np.multiply(2.0 * t, inv, out=s)
    return c, s


def quadratic_rows(mats) -> np.ndarray:
    """(3, 6) coefficients on the products Q of w's components of the three quadratic forms
    w^T M_k w."""
    out = np.empty((3, 6))
    for k, M in enumerate(mats):
        B = 0.5 * (M + M.T)
        out[k] = [B[0, 0], B[1, 1], B[2, 2], 2 * B[0, 1], 2 * B[0, 2], 2 * B[1, 2]]
    return out


def centripetal(p) -> np.ndarray:
    """w x (w x p) = (w w^T - |w|^2 I) p as (3, 6) rows on Q."""
    p = np.asarray(p, float)
    return quadratic_rows([np.outer(np.eye(3)[k], p) - p[k] * np.eye(3) for k in range(3)])


def gyroscopic(inertia) -> np.ndarray:
    """w x (I w) as (3, 6) rows on Q: component k is eps_kij w_i (I w)_j."""
    eps = np.zeros((3, 3, 3))
    eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1.0
    eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1.0
    return quadratic_rows([eps[k] @ inertia for k in range(3)])


def skew(p) -> np.ndarray:
    """[p]x: skew(p) @ x = p x x."""
    return np.array([[0.0, -p[2], p[1]], [p[2], 0.0, -p[0]], [-p[1], p[0], 0.0]])
