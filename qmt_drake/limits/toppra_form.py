"""The toppra form of limits: F w(q, qd, qdd) <= g on a fixed path as one toppra constraint.

On a path q(s), w(q, q' sdot, q' sddot + q'' sdot^2) = a(s) sddot + b(s) sdot^2 + c(s) for any w
that is affine in qdd and quadratic in qd (joint torques with gravity, the payload moment's
vector, the tray wrench): c = w(q, 0, 0), a = w(q, 0, q') - c, b = w(q, q', q'') - c. The
parameters of ALL grid points come from three batched calls of w, instead of toppra's default of
three Python calls per grid point. Used by LimitSet.toppra_constraint (every scenario's TOPP-RA)
and by seed 001's time-optimal end of the front (energy/time_optimal.py).
"""

from __future__ import annotations

import numpy as np


def rows_constraint(w, F, g, n_dof: int):
    """A toppra SecondOrderConstraint F w(q, qd, qdd) <= g: w a batched function of (S, n) arrays
    returning (S, m), affine in qdd and quadratic in qd; F (k, m), g (k,) the same at every grid
    point; Interpolation discretisation; rows scaled to unit norm per grid point (`unit_rows`)."""
    from toppra.constraint import DiscretizationType, SecondOrderConstraint
    from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate

    F = np.asarray(F, dtype=float)
    g = np.asarray(g, dtype=float)

    class _Rows(SecondOrderConstraint):
        def compute_constraint_params(self, path, gridpoints):
            s = np.asarray(gridpoints, dtype=float)
            q, qs, qss = path(s), path(s, 1), path(s, 2)
            zero = np.zeros_like(q)
            c = w(q, zero, zero)
            a = w(q, zero, qs) - c
            b = w(q, qs, qss) - c
            Fv = np.broadcast_to(F, (len(q),) + F.shape).copy()
            gv = np.broadcast_to(g, (len(q),) + g.shape).copy()
            if self.discretization_type == DiscretizationType.Interpolation:
                a, b, c, Fv, gv, _, _ = canlinear_colloc_to_interpolate(a, b, c, Fv, gv, None, None, s)
            Fv, gv = unit_rows(a, b, Fv, gv)
            return a, b, c, Fv, gv, None, None

    def w_one(q, qd, qdd):  # toppra's own per-point interface (unused by the batched parameters)
        return w(np.atleast_2d(q), np.atleast_2d(qd), np.atleast_2d(qdd))[0]

    return _Rows(w_one, lambda q: F, lambda q: g, n_dof, discretization_scheme=DiscretizationType.Interpolation)


def unit_rows(a, b, F, g):
    """Each row k of F w <= g at grid point i divided by |(F_ik . a_i, F_ik . b_i)|, the norm of
    its coefficients of (u, x) = (sddot, sdot^2); rows with zero coefficients are left as they are.

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
    A = np.einsum("nkm,nm->nk", F, a)
    B = np.einsum("nkm,nm->nk", F, b)
    nrm = np.hypot(A, B)
    scale = np.where(nrm > 0.0, 1.0 / np.where(nrm > 0.0, nrm, 1.0), 1.0)
    return F * scale[:, :, None], g * scale
