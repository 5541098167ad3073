"""Tangent: forward-mode derivatives for the planar recursion (model/planar.py).

A value v and its tangents d, one per seeded input direction: running PlanarChain's Newton-Euler
recursion on Tangents gives the exact partials d tau / d q, d qd, d qdd in the same pass
(`PlanarChain.torque_and_derivatives`), without AutoDiffXd's per-scalar objects.
"""

from __future__ import annotations

import numpy as np


class Tangent:
    """Forward-mode derivative carrier for the planar recursion: value v (...,) and tangents
    d (..., D), one per seeded input direction. Only the arithmetic the recursion uses (+, -, *,
    unary -, cos/sin) is defined; numpy defers to these operators (`__array_ufunc__ = None`)."""

    __slots__ = ("v", "d")
    __array_ufunc__ = None

    def __init__(self, v, d) -> None:
        self.v, self.d = v, d

    def __getitem__(self, key):  # key indexes the value's axes: q[..., i]
        return Tangent(self.v[key], self.d[key + (slice(None),) if isinstance(key, tuple) else (key, slice(None))])

    # A link offset of 0 (a rod along its x axis) multiplies to the constant 0: kept as a plain
    # 0.0 so the tangents skip the work (no tangent array is ever changed in place).
    def __add__(self, o):
        if isinstance(o, Tangent):
            return Tangent(self.v + o.v, self.d + o.d)
        return self if _is_zero(o) else Tangent(self.v + o, self.d)

    __radd__ = __add__

    def __sub__(self, o):
        if isinstance(o, Tangent):
            return Tangent(self.v - o.v, self.d - o.d)
        return self if _is_zero(o) else Tangent(self.v - o, self.d)

    def __rsub__(self, o):
        return Tangent(o - self.v, -self.d)

    def __neg__(self):
        return Tangent(-self.v, -self.d)

    def __mul__(self, o):
        if isinstance(o, Tangent):
            return Tangent(self.v * o.v, self.v[..., None] * o.d + o.v[..., None] * self.d)
        return 0.0 if _is_zero(o) else Tangent(self.v * o, self.d * o)

    __rmul__ = __mul__

    def cos_sin(self):
        c, s = np.cos(self.v), np.sin(self.v)
        return Tangent(c, -s[..., None] * self.d), Tangent(s, c[..., None] * self.d)


def _is_zero(x) -> bool:
    return isinstance(x, float) and x == 0.0
