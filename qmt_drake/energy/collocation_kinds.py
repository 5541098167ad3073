"""Direct collocation of seed 001's energy-time cost on the other arms (issue 27 item 6):
`qmt-drake plan thesis-ch4 | crane-tray | ur5-suction-bins | ur5-magnet-part | panda-tray-cup --method collocation
[--c1 C1 --c2 C2 --max-iter N --option knots=K (default 6)]`.

The transcription (a MathematicalProgram solved by SNOPT) is a Hermite-Simpson collocation of the joint-space
double integrator: state (q [rad], qd [rad/s]), input qdd [rad/s^2] first-order hold. Decision variables: the
knots' q, qd, qdd and one time step h_j [s] per segment between consecutive task poses (K = `knots` intervals
per segment, so the total time T = K sum h_j is free and so is each pose's time). For the double integrator
the Hermite-Simpson defects

    qd_{k+1} - qd_k = h (qdd_k + qdd_{k+1}) / 2,   q_{k+1} - q_k = h qd_k + h^2 (qdd_k / 3 + qdd_{k+1} / 6)

are its exact integration under a first-order-hold input, so the collocated motion is the cubic Hermite
spline of (q, qd) at the knots, whose qdd is piecewise linear, continuous and equal to the knots' qdd: the
plan's trajectory is that spline (trajectory.PolynomialTrajectory of Drake's PiecewisePolynomial.CubicHermite).
Boundary conditions from the task: q at the scenario's task poses (start, vias, goal: the IK'd poses the
other planners of the kind use), at rest (qd = 0) at the start and the goal; qdd free there (as the via cubic).
Limits: every ratio column of the kind's re-check <= 1 - MARGIN (the rows of energy/cross_kind: the spatial
SpatialColumns, a grip's column as its polytope's smooth rows; the planar LimitSet columns) at every knot and
interval midpoint, in one batched constraint with its sparsity pattern (each point depends on its interval's
two knots and time step; central differences). After a solve the spline is checked at FINE points per interval
(local maxima refined); every maximum over 1 - MARGIN / 2 is held too and the program solved again from there
(at most REFINE_ROUNDS times). Held as it is, not slowed: a hand's term partly balanced by the motion (a tilted
cup or tray) breaks when the motion is slowed. Cost: z = integral (c1 tau'tau + c2) dt [N^2 m^2 s] by
energy/objective.energy_time_cost (the one implementation), the trapezoid rule on each segment's knots,
tau the kind's joint torques (cross_kind's joint_torques: gravity, the carried part, the rotor inertia).

Start: the cross-kind SNOPT optimum over the family's genes (energy/cross_kind), sampled at the knots; the
collocation then frees the path between the poses. The plan is re-checked as every plan of its kind (spatial:
spatial_search.finish_or_least_violating, planar: baselines/finish.finish_plan, both slowing it by the
smallest factor that makes the re-check hold between samples). Its extra / info holds c1, c2, z (of the final,
re-checked trajectory on cross_kind.SAMPLES points, as cross_kind reports its own), z on the knots, the start's
z (the cross-kind SNOPT optimum's), the knots, the refinement's rounds and points and the solver's status. A
planar family that does not say when it passes more than two task points is refused in one line. Seed 001's own collocation (energy/collocation.py) is unchanged.
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.solvers import MathematicalProgram, SnoptSolver, SolverOptions
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.energy.cross_kind import (
    PAPER_C1,
    PAPER_C2,
    SAMPLES,
    WEIGHTS,
    EnergyTimeOnFamily,
    PlanarEnergyTime,
    SpatialEnergyTime,
    _solve,
)
from qmt_drake.energy.nlp import _ad_wrap
from qmt_drake.energy.objective import energy_time_cost, trapezoid_weights
from qmt_drake.errors import QmtInputError
from qmt_drake.families.via_cubic import ViaCubic
from qmt_drake.planners.baselines.finish import finish_plan
from qmt_drake.planners.baselines.paths import task_joint_points
from qmt_drake.planners.spatial_search import finish_or_least_violating
from qmt_drake.planners.spatial_trajectory import PolyTrajectory
from qmt_drake.problem import PlanningProblem
from qmt_drake.trajectory import PolynomialTrajectory

KNOTS = 6  # collocation intervals per segment between task poses
FD_STEP = 1e-6  # central differences on a knot's q, qd, qdd (absolute, they are O(1))
INTERIOR = (0.5,)  # fractions of each interval where the limits are held too
FINE = 64  # fine check points per interval after a solve
MARGIN = 1e-4  # the limits are held at 1 - MARGIN: a hand's term balanced by the motion (a tilted hand) does not
# hold when slowed, so the re-check must find it held as it is, between its own samples too
REFINE_TOL = -MARGIN / 2  # a ratio above 1 + this between the held points adds the point
NEAR = 1e-3  # local maxima of the fine check above 1 - NEAR are refined between its points
REFINE_ROUNDS = 10  # solves after the first one with points added
H_MIN_S = 1e-4  # a time step's lower bound [s]
H_GROWTH = 20.0  # a time step's upper bound: this many times its start


class Transcription:
    """The collocation program's pieces on one kind (module docstring): P the kind's cross-kind problem
    (its torques and ratio columns), poses (S + 1, n) rad, K intervals per segment."""

    def __init__(self, P: EnergyTimeOnFamily, poses, knots: int, rows=None) -> None:
        self.P, self.poses, self.K = P, np.asarray(poses, float), int(knots)
        self.rows_of = rows or P.column_ratios  # the constraint rows (q, qd, qdd) -> (S, R), each <= 1
        self.S, self.n = self.poses.shape[0] - 1, self.poses.shape[1]
        self.N = self.S * self.K + 1
        self.w = trapezoid_weights(self.K + 1)
        q0 = self.poses[:1]
        self.rows = int(np.asarray(self.rows_of(q0, 0 * q0, 0 * q0)).shape[1])  # constraint rows per point

    def times(self, h) -> np.ndarray:
        """(N,) knot times [s] of segment time steps h (S,)."""
        return np.r_[0.0, np.cumsum(np.repeat(np.asarray(h, float), self.K))]

    def _fd(self, f, Z):
        """f(q, qd, qdd) -> (N, R) at the knots Z (N, 3n), and its (N, R, 3n) per-knot Jacobian by central
        differences, in one batched call of f."""
        N, m = Z.shape
        E = FD_STEP * np.eye(m)
        batch = np.concatenate([Z[:, None, :], Z[:, None, :] + E, Z[:, None, :] - E], axis=1).reshape(-1, m)
        n = self.n
        F = np.asarray(f(batch[:, :n], batch[:, n:2 * n], batch[:, 2 * n:]), float).reshape(N, 1 + 2 * m, -1)
        J = (F[:, 1:1 + m] - F[:, 1 + m:]) / (2 * FD_STEP)
        return F[:, 0], np.transpose(J, (0, 2, 1))

    def z_knots(self, h, tau) -> float:
        """z [N^2 m^2 s] on the knots: energy_time_cost on each segment's K + 1 knots (trapezoid), summed."""
        K = self.K
        return sum(energy_time_cost(tau[j * K:(j + 1) * K + 1], K * h[j], self.P.c1, self.P.c2, self.w)
                   for j in range(self.S))

    def cost(self, v):
        """(z / c2, its gradient) of the packed variables v = (h (S,), Z (N, 3n))."""
        h, Z = v[:self.S], v[self.S:].reshape(self.N, 3 * self.n)
        tau, J = self._fd(self.P.joint_torques, Z)
        K, c1, s = self.K, self.P.c1, 1.0 / self.P.c2
        g_tau = np.zeros_like(tau)
        g_h = np.zeros(self.S)
        for j in range(self.S):
            seg = slice(j * K, (j + 1) * K + 1)
            g_tau[seg] += 2.0 * c1 * K * h[j] * self.w[:, None] * tau[seg]
            g_h[j] = energy_time_cost(tau[seg], K, c1, self.P.c2, self.w)  # dz/dh_j = z_j / h_j
        g_Z = np.einsum("kr,krm->km", g_tau, J)
        return self.z_knots(h, tau) * s, np.r_[g_h, g_Z.ravel()] * s

    def at(self, v, points):
        """(Zp (P, 3n), D (P, 3n, 6n + 1)): (q, qd, qdd) of the collocated cubic at points (P, 2) = (interval k,
        fraction s in [0, 1)) of the packed variables v, and its derivative by (Z_k, Z_k+1, h_j) (the cubic
        of the module docstring: qdd linear, qd and q its integrals)."""
        n, S = self.n, self.S
        Z = v[S:].reshape(self.N, 3 * n)
        k = points[:, 0].astype(int)
        s = points[:, 1][:, None]
        h = v[k // self.K][:, None]
        qk, vk, ak = Z[k, :n], Z[k, n:2 * n], Z[k, 2 * n:]
        ak1 = Z[k + 1, 2 * n:]
        a, b, c, d = s * s / 2 - s ** 3 / 6, s ** 3 / 6, s - s * s / 2, s * s / 2
        Zp = np.hstack([qk + h * s * vk + h * h * (a * ak + b * ak1), vk + h * (c * ak + d * ak1), (1 - s) * ak + s * ak1])
        P, eye = len(k), np.eye(n)
        D = np.zeros((P, 3 * n, 6 * n + 1))
        for r, col, coef in ((0, 0, 1.0 + 0 * s), (0, 1, h * s), (0, 2, h * h * a), (0, 5, h * h * b),
                                              (1, 1, 1.0 + 0 * s), (1, 2, h * c), (1, 5, h * d),
                                              (2, 2, 1 - s), (2, 5, s)):
            D[:, r * n:(r + 1) * n, col * n:(col + 1) * n] = coef[:, :, None] * eye
        D[:, :n, -1] = s * vk + 2 * h * (a * ak + b * ak1)
        D[:, n:2 * n, -1] = c * ak + d * ak1
        return Zp, D

    def columns(self, points):
        """The function v -> (every ratio column at `points`, its Jacobian (P * R, len(v))) and its sparsity
        pattern: one batched call of the kind's columns (central differences) for all points."""
        n, S, K = self.n, self.S, self.K
        k = points[:, 0].astype(int)
        idx = np.hstack([S + 3 * n * k[:, None] + np.arange(3 * n), S + 3 * n * (k + 1)[:, None] + np.arange(3 * n),
                         (k // K)[:, None]])  # (P, 6n + 1) the variables each point depends on
        nv = S + 3 * n * self.N

        def f(v):
            Zp, D = self.at(np.asarray(v, float), points)
            F, J = self._fd(self.rows_of, Zp)
            G = np.einsum("prm,pmv->prv", J, D)  # (P, R, 6n + 1)
            out = np.zeros((F.size, nv))
            rows = np.arange(F.size).reshape(F.shape)
            np.add.at(out, (rows[:, :, None], idx[:, None, :]), G)  # knot points repeat no index; sums if they do
            return F.ravel(), out
        R = self.rows
        pattern = [(int(p * R + r), int(c)) for p in range(len(k)) for r in range(R) for c in np.unique(idx[p])]
        return f, pattern

    def points(self, extra=()) -> np.ndarray:
        """(P, 2) where the limits are held: every knot (the last as interval N - 2 at s = 1), INTERIOR fractions
        of every interval, and `extra` (interval, fraction) points added by the refinement."""
        pts = [(k, 0.0) for k in range(self.N - 1)] + [(self.N - 2, 1.0)]
        pts += [(k, f) for k in range(self.N - 1) for f in INTERIOR] + list(extra)
        return np.array(pts, float)

    def seed(self, traj_sample, pose_times) -> tuple[np.ndarray, np.ndarray]:
        """(h (S,), Z (N, 3n)) from a motion sample(t) -> (q, qd, qdd) whose poses are at pose_times [s]."""
        h = np.diff(np.asarray(pose_times, float)) / self.K
        q, qd, qdd = traj_sample(self.times(h))
        return h, np.hstack([q, qd, qdd])

    def build(self, h0, Z0, max_iter: int, extra=()):
        prog = MathematicalProgram()
        n, N, K = self.n, self.N, self.K
        h = prog.NewContinuousVariables(self.S, "h")
        q = prog.NewContinuousVariables(N, n, "q")
        qd = prog.NewContinuousVariables(N, n, "qd")
        qdd = prog.NewContinuousVariables(N, n, "qdd")
        Zv = np.hstack([q, qd, qdd])
        prog.AddBoundingBoxConstraint(H_MIN_S, H_GROWTH * np.max(h0), h)
        for j, pose in enumerate(self.poses):  # the task's poses; rest at the start and the goal
            prog.AddBoundingBoxConstraint(pose, pose, q[j * K])
        prog.AddBoundingBoxConstraint(np.zeros(n), np.zeros(n), qd[0])
        prog.AddBoundingBoxConstraint(np.zeros(n), np.zeros(n), qd[-1])
        for k in range(N - 1):  # Hermite-Simpson defects of the double integrator (module docstring)
            hk = h[k // K]
            dv = qd[k + 1] - qd[k] - hk * (qdd[k] + qdd[k + 1]) / 2
            dq = q[k + 1] - q[k] - hk * qd[k] - hk * hk * (qdd[k] / 3 + qdd[k + 1] / 6)
            for e in (*dv, *dq):
                prog.AddConstraint(e, 0.0, 0.0)
        allv = np.r_[h, Zv.ravel()]
        f, pattern = self.columns(self.points(extra))
        rows = f(np.r_[h0, Z0.ravel()])[0].size
        con = prog.AddConstraint(_ad_dense(f), lb=np.full(rows, -np.inf), ub=np.full(rows, 1.0 - MARGIN), vars=allv)
        con.evaluator().SetGradientSparsityPattern(pattern)
        prog.AddCost(_ad_wrap(self.cost), vars=allv)
        prog.SetInitialGuess(h, h0)
        prog.SetInitialGuess(Zv, Z0)
        opts = SolverOptions()
        sid = SnoptSolver().solver_id()
        opts.SetOption(sid, "Major optimality tolerance", 1e-6)
        opts.SetOption(sid, "Major feasibility tolerance", 1e-9)
        opts.SetOption(sid, "Major iterations limit", int(max_iter))
        return prog, opts, h, Zv

    def solve(self, h0, Z0, max_iter: int, extra=()):
        """(h, Z, status, success) of SNOPT from (h0, Z0), the limits held at self.points(extra)."""
        prog, opts, h, Zv = self.build(h0, Z0, max_iter, extra)
        solver = SnoptSolver()
        if not solver.available():
            raise QmtInputError("collocation needs SNOPT, which this Drake build lacks; use --method ipopt")
        r = solver.Solve(prog, None, opts)
        return (np.asarray(r.GetSolution(h), float), np.asarray(r.GetSolution(Zv), float),
                str(r.get_solution_result()), bool(r.is_success()))

    def spline(self, h, Z) -> PiecewisePolynomial:
        """q(t): the cubic Hermite spline of the knots' (q, qd) (the collocated motion, module docstring)."""
        n = self.n
        return PiecewisePolynomial.CubicHermite(self.times(h), Z[:, :n].T, Z[:, n:2 * n].T)


def _ad_dense(fun_val_grad):
    """nlp._ad_wrap for a constraint on every variable in their own order (the solver's AutoDiff seed is the
    identity then: no product with it)."""
    def f(v):
        if v.dtype != object:
            return fun_val_grad(np.asarray(v, dtype=float))[0]
        dx = ExtractGradient(v)
        val, g = fun_val_grad(ExtractValue(v).ravel())
        if dx.shape != (v.size, v.size) or not np.array_equal(dx, np.eye(v.size)):
            g = g @ dx
        return InitializeAutoDiff(np.asarray(val).reshape(-1, 1), g).ravel()
    return f


def z_of(P: EnergyTimeOnFamily, traj) -> float:
    """z of a trajectory as cross_kind reports its own: energy_time_cost on SAMPLES points."""
    t = np.linspace(0.0, traj.duration_s, SAMPLES)
    q, qd, qdd = traj.evaluate(t, np.minimum(t, np.nextafter(traj.duration_s, 0.0)))
    return energy_time_cost(P.joint_torques(q, qd, qdd), traj.duration_s, P.c1, P.c2, WEIGHTS)


def grip_rows(columns):
    """The spatial re-check's columns (limits/spatial_columns.SpatialColumns) with each grip term's column (a
    suction cup's or a magnet face's: the largest of its polytope's rows F w / g, kinked where the largest
    switches) replaced by those rows themselves, each smooth: the same limit for an NLP's gradients."""
    grips = [t for t in columns.terms if hasattr(t, "grip")]

    def rows(q, qd, qdd):
        full = columns.columns(q, qd, qdd)
        if not grips:
            return full
        state = columns.chain.evaluate(q, qd, qdd)
        parts, at = [], 0
        for t in grips:
            sl = columns.slices[t.name]
            parts += [full[:, at:sl.start], t.wrench(state) @ (t.grip.F / t.grip.g[:, None]).T]
            at = sl.stop
        return np.concatenate([*parts, full[:, at:]], axis=1)
    return rows


def _check_knots(knots) -> int:
    if isinstance(knots, bool) or not float(knots).is_integer() or not 2 <= int(knots) <= 200:
        raise QmtInputError(f"knots = {knots}: collocation intervals per segment between task poses must be an "
                            f"integer in [2, 200] (default {KNOTS})")
    return int(knots)


def fine_violations(tr: Transcription, h, Z) -> tuple[float, list]:
    """(the largest ratio of the collocated motion (its spline) between its knots, the (interval, fraction) of each interval's
    largest ratio where it exceeds 1 + REFINE_TOL): FINE points per interval, each interval's largest refined by
    the vertex of the parabola through it and its neighbours (a peak between two points)."""
    f = np.arange(FINE + 1) / FINE
    m, tk = tr.N - 1, tr.times(h)
    pp = tr.spline(h, Z)  # the plan's motion itself (equal to the collocated cubic where the defects hold)
    d1, d2 = pp.MakeDerivative(1), pp.MakeDerivative(2)

    def worst(pts):
        k = pts[:, 0].astype(int)
        t = np.clip(tk[k] + pts[:, 1] * (tk[k + 1] - tk[k]), tk[k] + 1e-12, tk[k + 1] - 1e-12)  # inside its piece
        q, qd, qdd = (p.vector_values(t).T for p in (pp, d1, d2))
        return np.asarray(tr.P.column_ratios(q, qd, qdd)).max(axis=1)
    W = worst(np.array([(k, x) for k in range(m) for x in f])).reshape(m, -1)
    kk, ii = np.nonzero((W[:, 1:-1] >= W[:, :-2]) & (W[:, 1:-1] >= W[:, 2:]) & (W[:, 1:-1] > 1.0 - NEAR))
    ii = ii + 1  # every local maximum near a limit, refined to its parabola's vertex
    y0, y1, y2 = W[kk, ii - 1], W[kk, ii], W[kk, ii + 1]
    curv = y0 - 2 * y1 + y2
    step = np.where(curv < 0, 0.5 * (y0 - y2) / np.where(curv < 0, curv, -1.0), 0.0)
    sv = np.clip((ii + np.clip(step, -1, 1)) / FINE, 0.0, 1.0)
    Wv = worst(np.c_[kk, sv]) if len(kk) else np.zeros(0)
    bad = {}  # every local maximum over the limit (several in one interval: each held from the next solve)
    for k, x, w in [*zip(kk, sv, Wv), *((k, f[j], W[k, j]) for k, j in enumerate(np.argmax(W, axis=1)))]:
        if w > 1.0 + REFINE_TOL:
            bad.setdefault((int(k), round(float(x) * FINE)), (int(k), float(x)))
    peak = max(float(W.max()), float(Wv.max()) if len(Wv) else -np.inf)
    bad = sorted(bad.values())
    return peak, bad


def _collocate(P, poses, sample, pose_times, knots, max_iter, x0_z, rows=None, progress=None):
    """(transcription, h, spline, info) of the collocation started from a motion (sample, pose_times); where
    the collocated motion breaks a limit between the held points, those points are held too and it is solved
    again from there (at most REFINE_ROUNDS times). progress: a callable taking one line per solve, or None."""
    tr = Transcription(P, poses, _check_knots(knots), rows)
    h, Z = tr.seed(sample, pose_times)
    extra: list = []
    for rnd in range(REFINE_ROUNDS + 1):
        h, Z, status, ok = tr.solve(h, Z, max_iter, extra)
        peak, bad = fine_violations(tr, h, Z)
        if progress is not None:  # each solve can take minutes on a 7-joint arm: say where the run is
            progress(f"collocation solve {rnd + 1} of at most {REFINE_ROUNDS + 1}: T {float(np.sum(tr.K * h)):.4f} s, "
                     f"peak {peak:.5f} of the limits between the knots, {len(bad)} points held next (above {1 + REFINE_TOL:.5f})")
        if not bad or rnd == REFINE_ROUNDS:
            break
        extra += bad
    tau = P.joint_torques(Z[:, :tr.n], Z[:, tr.n:2 * tr.n], Z[:, 2 * tr.n:])
    info = {"objective": "energy_time", "c1": P.c1, "c2": P.c2, "knots_per_segment": tr.K,
            "z_knots": tr.z_knots(h, tau), "start_z": x0_z, "solver_status": status, "converged": ok,
            "segment_times_s": (tr.K * h).tolist(), "refined_points": len(extra), "refine_rounds": rnd,
            "fine_peak_ratio": peak}
    return tr, h, tr.spline(h, Z), info


def plan_collocation_spatial(sc, *, c1: float = PAPER_C1, c2: float = PAPER_C2, max_iter: int = 200,
                             knots: int = KNOTS, progress=None):
    """The energy-time optimum of spatial scenario sc by direct collocation (module docstring): its
    SpatialPlan, re-checked (spatial_search.finish_or_least_violating)."""
    t0 = time.perf_counter()
    _check_knots(knots)
    P = SpatialEnergyTime(sc, c1, c2)
    x, _ = _solve(P, "snopt", max_iter, sc.name)
    if progress is not None:
        progress(f"collocation: seeded by the via cubic's SNOPT optimum (z {P.z(x):.6g})")
    fam = P.family
    seed = fam.trajectory(x)
    tr, h, pp, info = _collocate(P, sc.q_poses_rad, seed.sample, fam.pose_times(x), knots, max_iter, P.z(x),
                                 grip_rows(P.columns), progress)
    plan = finish_or_least_violating(sc, "collocation", PolyTrajectory(pp), tr.times(h)[::tr.K], t0, info)
    plan.info["z"] = z_of(P, plan.trajectory)
    return plan


def plan_collocation_transfer(scenario, *, c1: float = PAPER_C1, c2: float = PAPER_C2, max_iter: int = 200,
                              knots: int = KNOTS, progress=None):
    """The energy-time optimum of a transfer scenario (planar magnet, tray) by direct collocation (module
    docstring): its Plan, re-checked at the scenario's check rate and slowed until it holds
    (baselines/finish.finish_plan)."""
    t0 = time.perf_counter()
    _check_knots(knots)
    problem = PlanningProblem(scenario)
    fam = problem.family
    poses = task_joint_points(scenario)
    P = PlanarEnergyTime(problem, c1, c2)
    x, _ = _solve(P, "snopt", max_iter, scenario.name)
    T = float(fam.motion_time_s(np.atleast_2d(x))[0])
    if len(poses) == 2:
        pose_times = np.array([0.0, T])
    elif isinstance(fam, ViaCubic):
        pose_times = fam.breakpoints_s(x)[0]
    else:
        raise QmtInputError(f"{scenario.name}: collocation needs the time at which the family passes each of the "
                            f"task's {len(poses)} points; its {type(fam).__name__} family does not say: use --method snopt")
    if progress is not None:
        progress(f"collocation: seeded by the family's SNOPT optimum (z {P.z(x):.6g})")
    tr, h, pp, info = _collocate(P, poses, lambda t: fam.sample(x, t), pose_times, knots, max_iter, P.z(x),
                                 progress=progress)
    plan = finish_plan(scenario, "collocation", PolynomialTrajectory(pp), planner_wall_s=time.perf_counter() - t0,
                       extra=info)
    plan.extra["z"] = z_of(P, plan.trajectory)
    return plan
