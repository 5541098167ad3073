"""TOPP-RA on a spatial arm's joint path with 3-D limit terms (e.g. the suction grip), and Drake's Toppra.

The path q(s) is a Drake PiecewisePolynomial (`joint_path`: cubic through IK waypoints with
continuous second derivatives and zero end slopes, s the cumulative joint-space chord length, rad).
`plan_toppra` hands the same object to the `toppra` package (wrapped as its geometric path) with
joint velocity limits, and the joint accelerations and every LimitTerm whose `toppra_w` / `toppra_rows`
exist as rows precomputed for all grid points (`path_grid`: evenly spaced, or on a dense path the
path's knots with its short pieces split; w of all terms by SpatialChain in three batched calls,
limits/toppra_form.py), solved by the one TOPP-RA (planners/toppra_core.py: two passes over toppra's
Seidel LP, the same LPs as toppra's TOPPRA, bit for bit, 1000 grid points with
the UR5's suction rows in about 30 ms instead of 78 ms: studies/bench_spatial.py).
`plan_drake_toppra` runs pydrake's Toppra on the same path and grid with the limits it has (joint
velocity, acceleration and torque). Both return the duration of their parameterisation (constant s-ddot
between grid points) and the planning time. `recheck` samples a plan: the terms' columns at every
grid point and at `refine` points per interval (the plan holds at the grid; between grid points
the path's curvature may add a little).
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.multibody.optimization import Toppra
from pydrake.trajectories import PiecewisePolynomial
from scipy.linalg import block_diag

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.at_rest import describe_at_rest, worst_at_rest, worst_terms_at_rest
from qmt_drake.limits.base import RowOptions
from qmt_drake.limits.toppra_form import rows_constraints
from qmt_drake.planners.toppra_core import parameterise, toppra_path

RANGE_SAMPLES_PER_SEGMENT = 64  # where the C2 cubic is looked at for leaving a joint's range
GRID_CUBIC_TOL = 1e-4  # largest |q'''| ds^2 (max over the joints) on an interval of the "knots" grid (`path_grid`)
GRID_UNIFORM_TOL = 0.01  # "auto" keeps the uniform grid while its |q'''| ds^2 is at most this on every piece
GRIDS = ("auto", "uniform", "knots")  # `path_grid`'s kinds


def joint_path(q_waypoints, lower_rad=None, upper_rad=None) -> PiecewisePolynomial:
    """q(s) through (K, n) waypoints; s = cumulative Euclidean joint-space chord length (rad).

    With the joint ranges (lower_rad, upper_rad (n,)), a C2 cubic that overshoots a range between
    waypoints (seen on RANGE_SAMPLES_PER_SEGMENT points a segment) is replaced by Drake's
    shape-preserving (Fritsch-Carlson) C1 cubic through the same waypoints, which never leaves the
    interval of its neighbouring waypoints, hence the range; the plan's re-check confirms it."""
    Q = np.asarray(q_waypoints, float)
    step = np.linalg.norm(np.diff(Q, axis=0), axis=1)
    if np.any(step <= 0):
        raise QmtInputError("joint path: two neighbouring waypoints are equal; drop one")
    s = np.r_[0.0, np.cumsum(step)]
    zero = np.zeros(Q.shape[1])
    pp = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(s, Q.T, zero, zero)
    if lower_rad is None or upper_rad is None:
        return pp
    u = np.linspace(0.0, 1.0, RANGE_SAMPLES_PER_SEGMENT)
    dense = pp.vector_values((s[:-1, None] + u[None, :] * np.diff(s)[:, None]).ravel()).T
    if np.all(dense >= np.asarray(lower_rad)) and np.all(dense <= np.asarray(upper_rad)):
        return pp
    return PiecewisePolynomial.CubicShapePreserving(s, Q.T, zero_end_point_derivatives=True)


class DrakePath:
    """A Drake trajectory q(s) with toppra's geometric-path interface (so both solvers see the same
    path); `_toppra_path` makes it one of toppra's geometric paths for its solver. The last array of path
    positions and its values are kept per derivative order: toppra's constraints ask for the same
    grid several times."""

    def __init__(self, pp: PiecewisePolynomial) -> None:
        self.pp = pp
        self._d = [pp, pp.derivative(1), pp.derivative(2)]
        self._last: dict = {}

    def __call__(self, path_positions, order: int = 0):
        s = np.atleast_1d(np.asarray(path_positions, float))
        hit = self._last.get(order)
        if hit is not None and hit[0].shape == s.shape and np.array_equal(hit[0], s):
            out = hit[1]
        else:
            out = self._d[order].vector_values(s).T
            out.flags.writeable = False  # shared between callers
            self._last[order] = (s.copy(), out)
        return out if np.ndim(path_positions) else out[0]

    @property
    def dof(self) -> int:
        return self.pp.rows()

    @property
    def path_interval(self):
        return np.array([self.pp.start_time(), self.pp.end_time()])


def _toppra_path(pp: PiecewisePolynomial):
    """DrakePath as toppra's AbstractGeometricPath (toppra_core.toppra_path)."""
    path = DrakePath(pp)
    return toppra_path(path, path.dof, path.path_interval)


def pick_and_place_waypoints(ik, pick_m, place_m, *, lift_m: float, seed, normal=(0.0, 0.0, -1.0),
                             n_transfer: int = 5) -> np.ndarray:
    """(K, n) joint waypoints of a pick-and-place move with the hand's face normal held: up from
    `pick_m` by lift_m, a straight transfer at that height (n_transfer inner points), down to
    `place_m`; solved by SpatialIK point by point from `seed` (branch kept, jumps refused)."""
    A, B = np.asarray(pick_m, float), np.asarray(place_m, float)
    up = np.array([0.0, 0.0, lift_m])
    pts = [A, A + up] + [(1 - t) * (A + up) + t * (B + up) for t in np.linspace(0, 1, n_transfer + 2)[1:-1]]
    pts += [B + up, B]
    normals = np.repeat(np.asarray(normal, float)[None], len(pts), axis=0)
    return ik.solve_path(np.array(pts), normals=normals, seed=seed, max_joint_step_rad=1.0, what="pick-and-place point")


def _third_derivative(pp) -> np.ndarray:
    """(K-1,) largest |q'''| (rad/rad^3, over the joints) on each piece of the piecewise cubic pp."""
    s = np.asarray(pp.get_segment_times(), float)
    return np.abs(pp.derivative(3).vector_values(0.5 * (s[:-1] + s[1:]))).max(axis=0)


def path_grid(pp, n_grid: int = 1000, grid: str = "auto") -> np.ndarray:
    """TOPP-RA's grid points on the piecewise cubic q(s) pp. "uniform": n_grid evenly spaced points.
    "knots": every knot of pp, each piece split into equal intervals no longer than the uniform spacing
    and short enough that |q'''| ds^2 <= GRID_CUBIC_TOL on it. "auto" (the default): "uniform" while its
    |q'''| ds^2 is at most GRID_UNIFORM_TOL on every piece (every IK'd task path here: at most 3e-4; the
    grid and the plan as before, bit for bit), else "knots".

    Why: TOPP-RA holds its rows at the grid points (both ends of each interval: toppra's Interpolation
    scheme), s-ddot u constant between them. Inside an interval the joint acceleration
    q' u + q'' sdot^2 is a quadratic in s of curvature 5 q''' u, which can rise above its values at the
    ends by (5/8) |q'''| |u| ds^2. A dense path (a 125 Hz stream, a controller's log) has pieces a few
    microradians long where it leaves and reaches rest, and the C2 cubic's zero end slopes give them
    |q'''| ~ 6 / h^2 (h the piece's length): a uniform grid holds several such pieces inside one
    interval, TOPP-RA never sees them, and the re-check then slows the whole plan (x1.6 on a 129-sample
    TALOS stream). More uniform points do not help: the overshoot depends on where the points fall
    on the short pieces, not on how many there are (x2.5 with 5000). GRID_CUBIC_TOL = 1e-4 keeps the
    overshoot near 1e-4 of a limit, inside the margin TOPP-RA keeps at its grid points, so a check at
    10x the re-check rate holds too (1e-2 left 5e-5 above a limit inside a piece shorter than one
    re-check sample, where the re-check's refinement, capped at 64 maxima per column, did not look)."""
    if grid not in GRIDS:
        raise QmtInputError(f"grid {grid!r}: give one of {', '.join(GRIDS)}")
    if not n_grid >= 2:
        raise QmtInputError(f"n_grid {n_grid!r}: TOPP-RA's grid needs at least 2 points (1000 by default)")
    s0, s1 = float(pp.start_time()), float(pp.end_time())
    du = (s1 - s0) / (n_grid - 1)
    q3 = _third_derivative(pp)
    if grid == "uniform" or (grid == "auto" and q3.max() * du * du <= GRID_UNIFORM_TOL):
        return np.linspace(s0, s1, n_grid)
    knots = np.asarray(pp.get_segment_times(), float)
    h = np.diff(knots)
    step = np.minimum(du, np.sqrt(GRID_CUBIC_TOL / np.maximum(q3, np.finfo(float).tiny)))
    m = np.maximum(np.ceil(h / step * (1.0 - 1e-12)).astype(int), 1)  # intervals per piece
    piece = np.repeat(np.arange(len(h)), m)
    j = np.arange(piece.size) - np.repeat(np.cumsum(m) - m, m)  # the interval's index inside its piece
    return np.r_[knots[piece] + h[piece] * j / m[piece], s1]


def toppra_problem(pp, chain, *, velocity_limit, acceleration_limit, terms=(), n_grid: int = 1000,
                   grid: str = "auto", **row_options):
    """(path, constraints, grid points) of `plan_toppra` for toppra (`path_grid(pp, n_grid, grid)`):
    joint speed limits as toppra's
    JointVelocityConstraint (bounds on sdot^2); the joint accelerations qdd = q' sddot + q'' sdot^2 and
    the terms' rows F w <= g as precomputed rows (limits/toppra_form.py), the acceleration rows first,
    then every term's rows stacked, w of all terms from one batched SpatialChain evaluation."""
    # lazy: toppra loads matplotlib.pyplot (about 1 s), which `qmt-drake` must not pay at every start
    import toppra

    path = _toppra_path(pp)
    n = chain.n_dof
    v = np.asarray(velocity_limit, float)
    a = np.asarray(acceleration_limit, float)
    cons = [toppra.constraint.JointVelocityConstraint(np.stack([-v, v], axis=1))]
    eye = np.eye(n)
    cons += rows_constraints(lambda q, qd, qdd: qdd, np.vstack([eye, -eye]), np.r_[a, a], n)
    options = RowOptions.from_keywords(**row_options)
    if terms:
        rows = [term.toppra_rows(options) for term in terms]
        F, g = block_diag(*[r[0] for r in rows]), np.concatenate([r[1] for r in rows])

        def w(q, qd, qdd):
            state = chain.evaluate(q, qd, qdd)
            return np.concatenate([term.toppra_w(state) for term in terms], axis=1)

        cons += rows_constraints(w, F, g, n)
    return path, cons, path_grid(pp, n_grid, grid)


def plan_toppra(pp, chain, *, velocity_limit, acceleration_limit, terms=(), n_grid: int = 1000, grid: str = "auto",
                **row_options):
    """dict(duration_s, planning_s, grid, sd, sdd) or QmtInputError when no parameterisation exists:
    `toppra_problem` solved by the one TOPP-RA (planners/toppra_core.parameterise: TOPP-RA's passes over
    toppra's Seidel LP, equal to toppra's TOPPRA with solver_wrapper="seidel")."""
    t0 = time.perf_counter()
    path, cons, points = toppra_problem(pp, chain, velocity_limit=velocity_limit, acceleration_limit=acceleration_limit,
                                        terms=terms, n_grid=n_grid, grid=grid, **row_options)
    sol = parameterise(path, cons, points)
    planning_s = time.perf_counter() - t0
    if not sol.ok:
        raise QmtInputError(_no_parameterisation(pp, chain, terms, points))
    return {"duration_s": sol.duration_s, "planning_s": planning_s, "grid": sol.grid, "sd": sol.sd,
            "sdd": np.asarray(sol.sdd, float), "n_grid": n_grid}


def _no_parameterisation(pp, chain, terms, grid) -> str:
    """The one-line refusal of an impossible path, naming the limit with the largest ratio at rest
    along it (limits/at_rest.py), the path point and the hand's position there."""
    if terms:
        w, state = worst_terms_at_rest(chain, terms, DrakePath(pp)(grid, 0))
        k = w["sample"]
        where = (f"path point s = {grid[k]:.4g} rad ({100 * (grid[k] - grid[0]) / (grid[-1] - grid[0]):.0f} % along, "
                 f"hand at {np.round(state['position_m'][k], 4).tolist()} m)")
        clause = describe_at_rest(w, where)
        if w["ratio"] > 1.0:
            return (f"TOPP-RA found no parameterisation of the path: {clause}; no timing can hold it there (gravity "
                    "alone breaks it); relax that limit or move the path")
        return (f"TOPP-RA found no parameterisation of the path, although every limit holds at rest along it "
                f"(the largest: {clause}); try more grid points or a smoother path")
    return ("TOPP-RA found no parameterisation of the path under the joint speed and acceleration limits; "
            "try more grid points or a smoother path")


def plan_drake_toppra(pp, plant, *, velocity_limit, acceleration_limit, torque_limit=None,
                      n_grid: int = 1000) -> dict:
    """pydrake's Toppra with joint velocity and acceleration limits and, if given, joint torque limits
    (N m; Drake's own inverse dynamics of `plant`, gravity and any welded carried body included)."""
    t0 = time.perf_counter()
    grid = np.linspace(pp.start_time(), pp.end_time(), n_grid)
    solver = Toppra(pp, plant, grid)
    v, a = np.asarray(velocity_limit, float), np.asarray(acceleration_limit, float)
    solver.AddJointVelocityLimit(-v, v)
    solver.AddJointAccelerationLimit(-a, a)
    if torque_limit is not None:
        tl = np.asarray(torque_limit, float)
        solver.AddJointTorqueLimit(-tl, tl)
    s_traj = solver.SolvePathParameterization()
    planning_s = time.perf_counter() - t0
    if s_traj is None:
        raise QmtInputError("Drake's Toppra found no parameterisation of the path"
                            + _drake_at_rest(pp, plant, grid, torque_limit) + "; relax a limit")
    return {"duration_s": float(s_traj.end_time() - s_traj.start_time()), "planning_s": planning_s,
            "n_grid": n_grid, "s_of_t": s_traj}


def _drake_at_rest(pp, plant, grid, torque_limit) -> str:
    """': <joint torque> needs r of its limit at rest (...)' by Drake's gravity forces along the path
    (plant positions = the path's rows), or '' without torque limits."""
    if torque_limit is None:
        return ""
    ctx = plant.CreateDefaultContext()
    tau = []
    for q in pp.vector_values(grid).T:
        plant.SetPositions(ctx, q)
        tau.append(plant.CalcGravityGeneralizedForces(ctx))  # the torque holding q still is its negative
    tl = np.asarray(torque_limit, float)
    labels = [f"joint_torque[{j}]" for j in range(tl.size)]
    for idx in plant.GetJointIndices():
        j = plant.get_joint(idx)
        if j.num_velocities() == 1 and j.velocity_start() < tl.size:
            labels[j.velocity_start()] = f"joint_torque[{j.name()}]"
    w = worst_at_rest(np.abs(np.array(tau)) / tl, labels, limits_Nm=tl)
    k = w["sample"]
    return ": " + describe_at_rest(w, f"path point s = {grid[k]:.4g} rad")


def recheck(plan: dict, pp, chain, terms, *, refine: int = 10) -> dict:
    """Largest column of each term (and joint speed/acceleration) sampled on the constant-s-ddot
    parameterisation: at the grid points and at `refine` points inside every interval."""
    grid, sd = plan["grid"], plan["sd"]
    ds = np.diff(grid)
    u = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)  # s-ddot of each interval
    frac = np.linspace(0.0, 1.0, refine + 1)
    s = (grid[:-1, None] + frac[None, :] * ds[:, None]).ravel()
    x = (sd[:-1, None] ** 2 + 2.0 * u[:, None] * frac[None, :] * ds[:, None]).ravel()
    uu = np.repeat(u, refine + 1)
    path = DrakePath(pp)
    q, qs, qss = path(s, 0), path(s, 1), path(s, 2)
    qd = qs * np.sqrt(np.maximum(x, 0.0))[:, None]
    qdd = qs * uu[:, None] + qss * x[:, None]
    state = chain.evaluate(q, qd, qdd)
    out = {t.name: float(np.max(t.columns(state))) for t in terms}
    out["max_joint_speed_rad_s"] = np.abs(qd).max(axis=0)
    out["max_joint_acceleration_rad_s2"] = np.abs(qdd).max(axis=0)
    return out
