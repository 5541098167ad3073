"""LimitTerm: one limit as columns computed from a batched HandState.

A term turns the hand state of S samples into an (S, m) array of columns and says how to read
them: `kind` "ratio" columns are value / limit and hold while <= 1; "excess" columns are how far a
quantity is beyond its bound (rad, m) and hold while <= 0. `scaling` says what playing the same
motion lam times slower does to its columns, which decides whether planners may use the exact
time-scaling shortcut (LimitSet.time_scaling_is_exact):
    "inverse_square"  divided by lam^2 (purely inertial: no gravity, no velocity-only terms);
    "invariant"       unchanged (positions only);
    "none"            neither (gravity, friction against weight, ...): planners must search.
Terms that TOPP-RA can use also give `toppra_w(state)` (S, k), affine in qdd and quadratic in qd
as toppra's SecondOrderConstraint requires, and `toppra_rows(options: RowOptions)` -> (F (r, k),
g (r,)) with F w <= g, rows near unit scale (toppra's tolerances are absolute). RowOptions is typed:
an option no term knows is a one-line error, not silently swallowed.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from qmt_drake.errors import QmtInputError

KINDS = ("ratio", "excess")


@dataclass(frozen=True)
class RowOptions:
    """How the limits are written as TOPP-RA rows (the polygons that stand for circles and cones).

    polygon_sides, angle0_rad: the payload moment's circle |a| <= A as a polygon of that many sides,
    turned so a vertex (vertex_on_chord) or an edge normal points along angle0_rad [rad];
    tray_polygon_sides: the tray's friction cone and tipping disc as polygons of that many sides;
    inscribed: the polygons inside their circle (never allow more than the limit) or outside it."""

    polygon_sides: int = 32
    angle0_rad: float = 0.0
    tray_polygon_sides: int = 4
    inscribed: bool = True
    vertex_on_chord: bool = True

    @classmethod
    def from_keywords(cls, **options) -> RowOptions:
        """RowOptions(**options), with an unknown name as a one-line QmtInputError."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise QmtInputError(f"TOPP-RA row option {unknown[0]!r} is not one of {sorted(known)}")
        return cls(**options)
SCALINGS = ("inverse_square", "invariant", "none")


class LimitTerm:
    name: str = ""
    kind: str = "ratio"
    scaling: str = "none"
    column_names: tuple = ()

    def columns(self, state) -> np.ndarray:  # pragma: no cover - interface
        raise NotImplementedError

    def toppra_w(self, state):
        """(S, k) or None when the term is not a toppra constraint (e.g. joint ranges: the path
        decides them)."""
        return None

    def toppra_rows(self, options: RowOptions):
        """(F, g) with F w <= g, or None when the term has no linear form."""
        return None
