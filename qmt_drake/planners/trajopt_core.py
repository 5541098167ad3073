"""The one trajopt: Drake's KinematicTrajectoryOptimization from a kind-neutral description.

A `TrajoptProblem` says what every kind's trajopt is: a cubic (order 4) B-spline q(s), s = t / T in
[0, 1], with the duration T a decision variable and the cost T, through given joint positions at
fixed path fractions, at rest at both ends, its control points inside the joint ranges (so, by the
convex hull of a B-spline, the whole path is), optional joint speed/acceleration/jerk bounds, and the
limit rows the scenario's kind supplies:

  - `path_constraints`: Drake constraints on q at a path fraction (the spatial hand's tilt);
  - `ratio_rows`: r(q, q', q'', T) <= 1 at path fractions, written with pydrake.math functions so
    SNOPT gets AutoDiff gradients, on the 4 active control points and T only (the planar payload
    moment);
  - `limit_rows`: rows F w(q, qd, qdd) <= g at path fractions, w a batched numpy function of the
    joint samples in time (the TOPP-RA rows of a limit set: the tray's friction cone, base circle
    and lift, the servos' torques and speeds), their gradients by central differences of w (one
    batched call per evaluation) and the chain rule through the spline (`LimitRows`);
  - `effort`: Drake's AddEffortBoundsAtNormalizedTimes (joint torques by inverse dynamics).

`solve` builds the program in one fixed order and solves it with SNOPT. The planar and spatial
entries (planners/baselines/trajopt_plan.plan_trajopt, planners/spatial_methods.plan_trajopt_spatial)
are adapters that fill the description from their scenario and turn the result into their plan.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import SnoptSolver, SolverOptions
from pydrake.trajectories import BsplineTrajectory

ORDER = 4  # cubic B-splines
FD_STEP = 1e-6  # central-difference step of LimitRows (relative to max(1, |x|))
INFEASIBLE_TOL = 1e-6  # an unsuccessful solve names the constraints its point breaks by more than this


def basis_weights(basis, s: float, order: int = 2):
    """(active indices, weights (order+1, len(active))): q^(k)(s) = P[:, idx] @ weights[k]."""
    m = basis.num_basis_functions()
    eye = [np.eye(m)[:, [i]] for i in range(m)]
    traj = BsplineTrajectory(basis, eye)
    idx = np.array(basis.ComputeActiveBasisFunctionIndices(s))
    W = [traj.value(s)[idx, 0]]
    d = traj
    for _ in range(order):
        d = d.MakeDerivative()
        W.append(d.value(s)[idx, 0])
    return idx, np.array(W)


def samples_with_knots(basis, count: int) -> np.ndarray:
    """`count` uniform path fractions plus every knot: the second derivative of a cubic B-spline has
    a kink at a knot (its jerk jumps there) and an optimiser puts its peaks exactly there."""
    knots = np.clip(np.asarray(basis.knots()), 0.0, 1.0)
    return np.unique(np.round(np.concatenate([np.linspace(0.0, 1.0, count), knots]), 12))


@dataclass
class RatioRows:
    """r(q, q', q'', T) <= 1 (a 1-vector, AutoDiff-ready; q' and q'' per unit path fraction) at each
    path fraction of `samples` (a callable basis -> fractions, or the fractions)."""

    ratio: object
    samples: object
    name: str = "ratio"


@dataclass
class LimitRows:
    """F w(q, qd, qdd) <= g at each path fraction of `samples` (a callable basis -> fractions, or the
    fractions); w: (S, n) x 3 -> (S, k) in time (qd = q' / T, qdd = q'' / T^2), batched numpy."""

    w: object
    F: np.ndarray
    g: np.ndarray
    samples: object
    name: str = "limit rows"


@dataclass
class TrajoptProblem:
    """What a trajopt solves (module docstring). Joint quantities are (n,) in rad, rad/s, rad/s^2,
    rad/s^3; `path_rad` (K, n) at `fractions` (K,), 0 first and 1 last."""

    path_rad: np.ndarray
    fractions: np.ndarray
    lower_rad: np.ndarray
    upper_rad: np.ndarray
    control_points: int
    duration_bounds_s: tuple
    initial_points: object  # (control_points, n) the guess of the control points, or a callable basis -> them
    initial_duration_s: float = 1.0
    rest_derivatives: int = 1  # zero at both ends: 1 the velocity, 2 also the acceleration
    velocity_limit: np.ndarray | None = None
    acceleration_limit: np.ndarray | None = None
    jerk_limit: np.ndarray | None = None
    path_constraints: list = field(default_factory=list)  # (Drake constraint on q, path fraction)
    ratio_rows: list = field(default_factory=list)
    limit_rows: list = field(default_factory=list)
    effort: tuple | None = None  # (plant, samples, lower N m, upper N m)
    snopt_options: dict = field(default_factory=dict)


@dataclass
class TrajoptResult:
    success: bool
    solution_result: str
    info: int
    duration_s: float
    solve_wall_s: float
    trajectory: object  # the BsplineTrajectory in time (ReconstructTrajectory)
    basis: object
    samples: dict  # {rows name: path fractions}
    infeasible_constraints: list | None = None  # not success: the constraints the returned point breaks (tol 1e-6)
    broken_rows: list | None = None  # not success: (description, lower, upper, value) of each of them

    @property
    def usable(self) -> bool:
        """Solved, or SNOPT stopped unsolved (its iteration limit; info 41, the point cannot be improved) on a
        point that meets every constraint within INFEASIBLE_TOL: a trajectory of the program, not proven
        minimal (the plan's re-check then judges it between samples)."""
        return self.success or self.infeasible_constraints == []


def rest_to_rest_fractions(shares) -> np.ndarray:
    """The time fractions at which a rest-to-rest move at constant acceleration magnitude (accelerating to half
    way, then braking) covers the given shares (rising, 0 to 1) of its length: x = sqrt(c / 2) to c = 1/2, then
    1 - sqrt((1 - c) / 2). Points near the ends get more time than their share, as any move from rest gives them
    (a spline at rest at an end reaches a point at a share near that end only through a small basis weight)."""
    c = np.clip(np.asarray(shares, float), 0.0, 1.0)
    return np.where(c <= 0.5, np.sqrt(c / 2.0), 1.0 - np.sqrt((1.0 - c) / 2.0))


def _fractions(samples, basis) -> np.ndarray:
    return np.asarray(samples(basis) if callable(samples) else samples, float)


def _limit_rows_constraint(rows: LimitRows, basis, s: np.ndarray, n: int, ncp: int):
    """The rows at fractions s as one function of all control points and T (value, and AutoDiff
    Jacobian by central differences of w and the chain rule through the spline)."""
    m = basis.num_basis_functions()
    eye = [np.eye(m)[:, [i]] for i in range(m)]
    b0 = BsplineTrajectory(basis, eye)
    b1 = b0.MakeDerivative()
    b2 = b1.MakeDerivative()
    B = [np.stack([b.value(x)[:, 0] for x in s]) for b in (b0, b1, b2)]  # (S, ncp) each
    F, g = np.asarray(rows.F, float), np.asarray(rows.g, float)
    S = len(s)

    def values(x):
        P = x[:n * ncp].reshape(n, ncp)
        T = x[-1]
        q, q1, q2 = B[0] @ P.T, B[1] @ P.T, B[2] @ P.T
        return q, q1, q2, T

    def rows_of(w):  # (S, k) -> (S * R,)
        return (np.einsum("sk,rk->sr", w, F) - g).ravel()

    def f(x):
        if x.dtype != object:
            q, q1, q2, T = values(np.asarray(x, float))
            return rows_of(rows.w(q, q1 / T, q2 / T**2))
        xv, dx = ExtractValue(x)[:, 0], ExtractGradient(x)
        q, q1, q2, T = values(xv)
        z = np.concatenate([q, q1 / T, q2 / T**2], axis=1)  # (S, 3n)
        h = FD_STEP * np.maximum(1.0, np.abs(z))
        pert = [z]
        for j in range(3 * n):
            for sign in (1.0, -1.0):
                zj = z.copy()
                zj[:, j] += sign * h[:, j]
                pert.append(zj)
        Z = np.concatenate(pert)
        w = rows.w(Z[:, :n], Z[:, n:2 * n], Z[:, 2 * n:])
        k = w.shape[1]
        w = w.reshape(1 + 6 * n, S, k)
        dw = (w[1::2] - w[2::2]) / (2.0 * h.T[:, :, None])  # (3n, S, k)
        dr = np.einsum("jsk,rk->jsr", dw, F)  # d rows / d z_j
        # chain rule: z = (B0 P^T, B1 P^T / T, B2 P^T / T^2)
        J = np.zeros((S, F.shape[0], n * ncp + 1))
        for i in range(n):
            for d, scale in ((0, 1.0), (1, 1.0 / T), (2, 1.0 / T**2)):
                J[:, :, i * ncp:(i + 1) * ncp] += dr[d * n + i][:, :, None] * (B[d] * scale)[:, None, :]
        J[:, :, -1] = -np.einsum("isr,si->sr", dr[n:2 * n], q1 / T**2) \
            - 2.0 * np.einsum("isr,si->sr", dr[2 * n:], q2 / T**3)
        val = rows_of(w[0])
        return InitializeAutoDiff(val[:, None], J.reshape(S * F.shape[0], -1) @ dx)[:, 0]

    return f, S * F.shape[0]


def solve(p: TrajoptProblem) -> TrajoptResult:
    """Build the program of `p` (module docstring) and solve it with SNOPT."""
    n = p.path_rad.shape[1]
    ncp = p.control_points
    to = KinematicTrajectoryOptimization(n, ncp, ORDER, p.initial_duration_s)
    basis = to.basis()
    P0 = np.asarray(p.initial_points(basis) if callable(p.initial_points) else p.initial_points, float)
    to.SetInitialGuess(BsplineTrajectory(basis, [P0[i][:, None] for i in range(ncp)]))
    prog = to.get_mutable_prog()
    prog.SetInitialGuess(to.duration(), p.initial_duration_s)
    P, Tvar = to.control_points(), to.duration()
    zero = np.zeros(n)
    used = {}
    to.AddDurationCost(1.0)
    to.AddPositionBounds(p.lower_rad, p.upper_rad)
    for limit, add in ((p.velocity_limit, to.AddVelocityBounds), (p.acceleration_limit, to.AddAccelerationBounds),
                       (p.jerk_limit, to.AddJerkBounds)):
        if limit is not None:
            add(-limit, limit)
    to.AddDurationConstraint(*p.duration_bounds_s)
    for sk, qk in zip(p.fractions, p.path_rad):
        to.AddPathPositionConstraint(qk, qk, float(sk))
    for sk in (0.0, 1.0):
        to.AddPathVelocityConstraint(zero, zero, sk)
        if p.rest_derivatives >= 2:
            to.AddPathAccelerationConstraint(zero, zero, sk)
    for constraint, sk in p.path_constraints:
        to.AddPathPositionConstraint(constraint, float(sk))
    for rows in p.ratio_rows:
        used[rows.name] = s_all = _fractions(rows.samples, basis)
        for s in s_all:
            idx, W = basis_weights(basis, float(s))
            k = len(idx)

            def ratio(x, W=W, k=k, r=rows.ratio):
                Pa = x[:n * k].reshape(n, k)
                return r(Pa @ W[0], Pa @ W[1], Pa @ W[2], x[-1])

            prog.AddConstraint(ratio, [-np.inf], [1.0], np.concatenate([P[:, idx].reshape(-1), [Tvar]]),
                               description=f"{rows.name} s={s:.3f}")
    all_vars = np.concatenate([P.reshape(-1), [Tvar]])
    for rows in p.limit_rows:
        used[rows.name] = s_all = _fractions(rows.samples, basis)
        f, m = _limit_rows_constraint(rows, basis, s_all, n, ncp)
        prog.AddConstraint(f, np.full(m, -np.inf), np.zeros(m), all_vars, description=rows.name)
    if p.effort is not None:
        plant, samples, lo, hi = p.effort
        used["effort"] = s_eff = _fractions(samples, basis)
        to.AddEffortBoundsAtNormalizedTimes(plant, s_eff, lo, hi)
    solver = SnoptSolver()
    opts = SolverOptions()
    for key, value in p.snopt_options.items():
        opts.SetOption(solver.solver_id(), key, value)
    t0 = time.perf_counter()
    result = solver.Solve(prog, None, opts)
    wall = time.perf_counter() - t0
    ok = bool(result.is_success())
    broken = None if ok else [(b.evaluator().get_description(), np.asarray(b.evaluator().lower_bound(), float),
                               np.asarray(b.evaluator().upper_bound(), float), np.asarray(result.EvalBinding(b), float))
                              for b in result.GetInfeasibleConstraints(prog, INFEASIBLE_TOL)]
    return TrajoptResult(ok, str(result.get_solution_result()),
                         int(result.get_solver_details().info), float(result.GetSolution(Tvar)), wall,
                         to.ReconstructTrajectory(result), basis, used,
                         None if ok else list(result.GetInfeasibleConstraintNames(prog, INFEASIBLE_TOL)), broken)
