"""The few operations a model formula needs, for floats, numpy arrays and drake symbolic Expressions,
so that each formula is written once and runs in Python, on whole logged series, and compiled into a
SymbolicVectorSystem (evaluated in C++ every plant step, no Python call).

`FLOAT` evaluates a branch only when it is taken (a formula may divide by zero in the other);
`NUMPY` computes both branches element-wise; `SYMBOLIC` builds both and lets if_then_else choose at
evaluation. Branches are passed as zero-argument callables for that reason.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake import symbolic
from pydrake.systems.primitives import SymbolicVectorSystem


class FLOAT:
    sqrt, acos, tanh, atan2 = (staticmethod(f) for f in (math.sqrt, math.acos, math.tanh, math.atan2))

    @staticmethod
    def where(condition, then_value, else_value):
        return then_value() if condition else else_value()

    @staticmethod
    def clip(v, lo, hi):
        return min(max(v, lo), hi)


class NUMPY:
    """Element-wise over numpy arrays (both branches are computed; pick only branches that are finite)."""

    sqrt, acos, tanh, atan2 = (staticmethod(f) for f in (np.sqrt, np.arccos, np.tanh, np.arctan2))

    @staticmethod
    def where(condition, then_value, else_value):
        return np.where(condition, then_value(), else_value())

    @staticmethod
    def clip(v, lo, hi):
        return np.minimum(np.maximum(v, lo), hi)


class SYMBOLIC:
    sqrt, acos, tanh, atan2 = (staticmethod(f) for f in (symbolic.sqrt, symbolic.acos, symbolic.tanh, symbolic.atan2))

    @staticmethod
    def where(condition, then_value, else_value):
        return symbolic.if_then_else(condition, then_value(), else_value())

    @staticmethod
    def clip(v, lo, hi):
        return symbolic.min(symbolic.max(v, lo), hi)


def symbolic_law(inputs: list, outputs: list, *, host_has_continuous_state: bool = False):
    """A stateless SymbolicVectorSystem y = outputs(inputs). host_has_continuous_state: True when the
    diagram it goes into has continuous state (an integrator, a PidController, motors with
    inductance): Drake 1.51's SymbolicVectorSystem without state aborts when a simulator asks every
    subsystem for time derivatives ("dynamics_.size() > 0" failed), so it gets one constant
    continuous state (d/dt = 0) that lets it answer."""
    idle = [symbolic.Variable("idle")] if host_has_continuous_state else []
    return SymbolicVectorSystem(state=idle, dynamics=[symbolic.Expression(0.0)] * len(idle), input=inputs,
                                output=outputs)
