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
as toppra's SecondOrderConstraint requires, and `toppra_rows(**options)` -> (F (r, k), g (r,))
with F w <= g, rows near unit scale (toppra's tolerances are absolute).
"""

from __future__ import annotations

import numpy as np

KINDS = ("ratio", "excess")
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

    def toppra_rows(self, **options):
        return None
