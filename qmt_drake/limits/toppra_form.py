"""The toppra form of limits: F w(q, qd, qdd) <= g on a fixed path as toppra constraints.

On a path q(s), w(q, q' sdot, q' sddot + q'' sdot^2) = a(s) sddot + b(s) sdot^2 + c(s) for any w
that is affine in qdd and quadratic in qd (joint torques with gravity, the payload moment's
vector, the tray wrench, the suction wrench): c = w(q, 0, 0), a = w(q, 0, q') - c, b = w(q, q', q'')
- c. The parameters of ALL grid points come from three batched calls of w, instead of toppra's
default of three Python calls per grid point.

The rows are handed to toppra already multiplied out, per grid point i and row r: A_ir u + B_ir x +
C_ir <= 0 with (A, B, C) = (F a_i, F b_i, F c_i - g), interpolated (rows of grid points i and i+1,
toppra's Interpolation scheme) and scaled to unit norm (`unit_rows`). Each toppra constraint then
has the identity as its (identical) F, so toppra's Seidel wrapper copies them with one matrix
product instead of three Python np.dot calls per grid point (37 ms of the 78 ms of a 1000-point
suction path); `rows_constraints` splits the rows into blocks so that product (N k_block^2) stays
small. The LP is the same rows in the same order. Used by LimitSet.toppra_constraint (every
scenario's TOPP-RA), seed 001's time-optimal end of the front (energy/time_optimal.py) and the
spatial TOPP-RA (planners/spatial_toppra.py).
"""

from __future__ import annotations

import numpy as np

ROW_BLOCK = 8  # rows per toppra constraint in `rows_constraints`: toppra multiplies by an identity of this size


def path_row_params(w, F, g, path, gridpoints):
    """(A, B, C), each (N+1, 2k): the rows F w <= g of every grid point of `path` as A u + B x + C <= 0
    (u = sddot, x = sdot^2), rows of point i then of point i+1 (the last point repeats its own),
    each scaled to unit norm of (A, B). w batched over (S, n) arrays; F (k, m), g (k,)."""
    s = np.asarray(gridpoints, dtype=float)
    q, qs, qss = path(s), path(s, 1), path(s, 2)
    zero = np.zeros_like(q)
    c = w(q, zero, zero)
    a = w(q, zero, qs) - c
    b = w(q, qs, qss) - c
    F = np.asarray(F, dtype=float)
    k = len(F)
    A, B, C = (np.empty((len(s), 2 * k)) for _ in range(3))
    for out, x in ((A, a), (B, b), (C, c)):  # einsum, not BLAS: a threaded dgemm stalls on a shared machine
        np.einsum("nm,km->nk", x, F, out=out[:, :k])
    C[:, :k] -= np.asarray(g, dtype=float)
    # toppra's Interpolation scheme (canlinear_colloc_to_interpolate): point i+1's rows reached
    # from point i with x_{i+1} = x_i + 2 delta_i u_i; the last point repeats its own rows
    A[:-1, k:] = A[1:, :k] + 2.0 * np.diff(s)[:, None] * B[1:, :k]
    B[:-1, k:], C[:-1, k:] = B[1:, :k], C[1:, :k]
    A[-1, k:], B[-1, k:], C[-1, k:] = A[-1, :k], B[-1, :k], C[-1, :k]
    scale = unit_scale(A, B)
    A *= scale
    B *= scale
    C *= scale
    return A, B, C


def unit_scale(A, B):
    """Factor per row that scales (A, B), the coefficients of (u, x) = (sddot, sdot^2), to unit norm;
    1 for rows with zero coefficients.

    Why: toppra's Seidel LP (cy_seidel_solverwrapper) starts each stage at the corner of its
    +-1e8 box, and when a row is violated there it solves a 1-D LP along that row's line, whose
    abscissa is measured in units of 1/|(a, b)| and bounded by +-1e10. A row with |(a, b)| below
    about 1e-2 (e.g. a torque row that barely depends on u and x: with gravity its constant part
    dominates) puts the box corners beyond 1e10; the 1-D LP then ends on that bound with no active
    row (index -1/-2), which the Cython code compares against an unsigned counter and reports as
    "infeasible": the stage's controllable set becomes NaN and TOPP-RA fails "not controllable"
    on a feasible path (seen on joint lines of a vertical arm; which rows trigger it depends on
    the warm-started row order). A row's set is unchanged by a positive factor, so scaling
    (a, b) to unit norm removes the trigger without changing the problem."""
    nrm = np.sqrt(A * A + B * B)  # not np.hypot: 5x slower, and no row here is near overflow
    nrm[nrm == 0.0] = 1.0
    return 1.0 / nrm


def unit_rows(a, b, F, g):
    """Rows F w <= g per grid point ((N, k, m), (N, k)) scaled as `unit_scale` says, with w = a u + b x + c."""
    scale = unit_scale(np.einsum("nkm,nm->nk", F, a), np.einsum("nkm,nm->nk", F, b))
    return F * scale[:, :, None], g * scale


def rows_constraints(w, F, g, n_dof: int, block: int | None = ROW_BLOCK) -> list:
    """toppra constraints F w(q, qd, qdd) <= g (module docstring): w a batched function of (S, n)
    arrays returning (S, m), affine in qdd and quadratic in qd; F (k, m), g (k,) the same at every
    grid point; `block` rows per constraint (None: all in one). The rows are evaluated once per
    (path, grid) and shared by the blocks."""
    # lazy: toppra loads matplotlib.pyplot, too slow for every CLI start
    from toppra.constraint import ConstraintType, DiscretizationType, LinearConstraint

    F = np.asarray(F, dtype=float)
    g = np.asarray(g, dtype=float)
    k2 = 2 * len(F)  # rows after interpolation
    size = k2 if block is None else max(1, int(block))
    cache: dict = {}

    def rows(path, gridpoints):
        s = np.asarray(gridpoints, dtype=float)
        if cache.get("path") is not path or not np.array_equal(cache.get("grid"), s):
            cache.update(path=path, grid=s.copy(), rows=path_row_params(w, F, g, path, s))
        return cache["rows"]

    class _Rows(LinearConstraint):
        def __init__(self, lo: int, hi: int) -> None:
            super().__init__()
            self.constraint_type = ConstraintType.CanonicalLinear
            self.discretization_type = DiscretizationType.Interpolation
            self.identical = True
            self.dof = n_dof
            self._lo, self._hi = lo, hi
            self._F, self._g = np.eye(hi - lo), np.zeros(hi - lo)
            self._format_string = f"    F w <= g rows {lo}..{hi - 1} of {k2} (unit scale, interpolated)\n"

        def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
            A, B, C = rows(path, gridpoints)
            sl = slice(self._lo, self._hi)
            return A[:, sl], B[:, sl], C[:, sl], self._F, self._g, None, None

    return [_Rows(lo, min(lo + size, k2)) for lo in range(0, k2, size)]


def rows_constraint(w, F, g, n_dof: int):
    """`rows_constraints` as one toppra constraint (all rows in one block: for few rows)."""
    return rows_constraints(w, F, g, n_dof, block=None)[0]
