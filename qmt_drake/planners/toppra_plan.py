"""TOPP-RA: the time-optimal timing of a fixed geometric joint path under the payload-moment bound
and every motor-torque limit (the `toppra` package), and Drake's own Toppra for comparison.

Constraint (one toppra SecondOrderConstraint, evaluated for the whole grid at once with the
batched ArmModel): along a path q(s), the tip acceleration a = J q'' sdot^2 + J q' sddot + Jdot q'
sdot^2 and the motor torques tau/N (inverse dynamics with the reflected rotor inertia N^2 J_r) are
linear in (u = sddot, x = sdot^2), so they form w = a(s) u + b(s) x with

    w = [a_tip / A (2 rows), tau_i / (N_i * motor_limit_i) (n rows)],  A = moment_limit / (m_o r_G)

(rows near unit scale: toppra's tolerances are absolute). The norm bound |a_tip| <= A is the
polygon n_k . a / A <= cos(pi/P) with P sides (normals n_k): inscribed in the circle, so it never
allows more than the moment limit and costs at most 1/sqrt(cos(pi/P)) - 1 of the motion time
(0.24 % for P = 32). The polygon is turned so that one vertex points along the segment's chord
(start -> goal tip): an even P then also has a vertex at the opposite direction, and on a straight
tip line (whose acceleration is always along the line) the polygon is exact. The time the polygon
costs on the actual path is bounded by a second run with the circumscribed polygon (which allows
slightly more than the limit): T_circumscribed <= T_exact <= T_inscribed; both are reported.

Output: toppra's `ParametrizeConstAccel` timing (constant sddot between grid points: the spline
output overshoots, NOTES.md) evaluated exactly by `PathTimingTrajectory` (breakpoints at the grid
times). Constraints hold at the grid points only; the 10 kHz re-check of `make_plan` judges the
result. With `slow_to_limits=True` (default) a result that breaks a limit on the re-check is
played slower by the exact factor sqrt(peak ratio) (every limit here is inertial: no gravity in the
plane, no velocity limit, so playing lam times slower divides every ratio by lam^2); the raw
overshoot is kept in `extra["raw_check"]`, never hidden.

Infeasible limits never raise: a path that cannot be built (a point out of reach, a straight
segment that leaves a joint range) or a motion longer than the time budget `max_motion_time_s`
(default: the slowest motion the scenario's family allows, all genes at their upper bounds; every
limit can be met by going slowly enough, so "too tight" means "not within that budget") gives a
Plan with feasible=False and the reason in extra["infeasible"] (`infeasible_plan`).

Paths (`path=`):
  "family"         the geometric path of the scenario's thesis family: the straight tip line for
                   chapter 2 (exact IK path, arc length in m), otherwise the joint path traced by the
                   family at the thesis's reported genes;
  "ga_path"        the joint path traced by `reference_plan` (e.g. the GA's plan; without one a
                   short GA run is made and said so);
  "joint_line"     straight joint-space segments between the IK solutions of the task points;
  "cartesian_line" straight tip segments between the task points (tool angle held for 3 joints).
Straight segments meet at corners at the via points, so those paths stop at each via (each segment
is timed rest to rest); the traced paths are smooth and pass the vias without stopping.

Shared with the other planners of this package: the geometric paths, the time-scaled and
concatenated trajectories, `finish_plan` (re-check, exact slow-down, infeasible results) and
`infeasible_plan`.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.interpolate import CubicSpline

from qmt_drake.errors import QmtInputError
from qmt_drake.plan import Plan, make_plan, recheck
from qmt_drake.trajectory import JointTrajectory

PATHS = ("family", "ga_path", "joint_line", "cartesian_line")
TRACED_KNOTS = 1000  # spline knots along a traced joint path (joint-space arc length)


# ============================================================================ geometric paths
class GeometricPath:
    """q(s), q'(s), q''(s) for s in [0, length]; `unit` names what s measures."""

    length: float
    n_dof: int
    unit: str = ""

    def derivatives(self, s):
        """(q, q', q'') each (len(s), n) at path positions s."""
        raise NotImplementedError

    def __call__(self, s, order: int = 0):
        scalar = np.ndim(s) == 0
        out = self.derivatives(np.atleast_1d(np.asarray(s, dtype=float)))[order]
        return out[0] if scalar else out


class JointLinePath(GeometricPath):
    """Straight joint-space segment q0 -> q1, s = joint-space arc length in rad."""

    unit = "rad (joint-space arc length)"

    def __init__(self, q0, q1) -> None:
        self.q0 = np.asarray(q0, dtype=float)
        delta = np.asarray(q1, dtype=float) - self.q0
        self.length = float(np.linalg.norm(delta))
        if self.length <= 0:
            raise QmtInputError("a joint-line segment has coinciding ends; remove repeated points")
        self.direction = delta / self.length
        self.n_dof = self.q0.size

    def derivatives(self, s):
        s = np.asarray(s, dtype=float)[:, None]
        q = self.q0 + s * self.direction
        return q, np.broadcast_to(self.direction, q.shape).copy(), np.zeros_like(q)


class CartesianLinePath(GeometricPath):
    """Straight tip segment p0 -> p1 by analytic IK, s = tip arc length in m.

    q' and q'' are exact: J_aug q' = [d, 0] and J_aug q'' = -[Jdot q', 0], where J_aug is the tip
    Jacobian (plus the row [1 1 1] that holds the tool angle for a 3-joint arm) and Jdot q' is the
    tip acceleration at (q, q', 0)."""

    unit = "m (tip arc length)"

    def __init__(self, arm, p0, p1, tool_angle_rad=None, branch="elbow_positive",
                 samples: int = 401) -> None:
        self.arm = arm
        self.p0 = np.asarray(p0, dtype=float)
        delta = np.asarray(p1, dtype=float) - self.p0
        self.length = float(np.hypot(*delta))
        if self.length <= 0:
            raise QmtInputError("a Cartesian segment has coinciding ends; remove repeated points")
        self.direction = delta / self.length
        self.tool = tool_angle_rad
        self.branch = branch
        self.n_dof = arm.n_dof
        # Whole segment reachable, in range and without an IK jump (raises QmtInputError).
        s = np.linspace(0.0, self.length, samples)
        q = arm.inverse_kinematics(self.p0 + s[:, None] * self.direction, tool_angle_rad, branch,
                                   check_range=False, what="Cartesian path point")
        arm.check_joint_range(q, what="the straight tip segment")
        if np.any(np.abs(np.diff(q, axis=0)) > 0.5):
            raise QmtInputError("the IK solution jumps along a straight tip segment (singularity "
                                "or +-pi wrap); choose other points or the other ik_branch")

    def _j_aug(self, q):
        J = self.arm.jacobian(q)
        if self.n_dof == 3:
            J = np.concatenate([J, np.ones(q.shape[:-1] + (1, 3))], axis=-2)
        return J

    def _rhs(self, v2):
        if self.n_dof == 3:
            return np.concatenate([v2, np.zeros(v2.shape[:-1] + (1,))], axis=-1)
        return v2

    def derivatives(self, s):
        s = np.asarray(s, dtype=float)
        xy = self.p0 + s[:, None] * self.direction
        q = self.arm.inverse_kinematics(xy, self.tool, self.branch, check_range=False)
        J = self._j_aug(q)
        qs = np.linalg.solve(J, self._rhs(np.broadcast_to(self.direction, xy.shape))[..., None])[..., 0]
        bias = self.arm.tip_acceleration(q, qs, np.zeros_like(qs))
        qss = np.linalg.solve(J, self._rhs(-bias)[..., None])[..., 0]
        return q, qs, qss


class SplinePath(GeometricPath):
    """Cubic spline (not-a-knot) of q over joint-space arc length: a traced path."""

    unit = "rad (joint-space arc length)"

    def __init__(self, sigma, q) -> None:
        self.spline = CubicSpline(sigma, q, axis=0)
        self.length = float(sigma[-1])
        self.n_dof = q.shape[1]

    def derivatives(self, s):
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.length)
        return self.spline(s), self.spline(s, 1), self.spline(s, 2)


def traced_path(trajectory: JointTrajectory, knots: int = TRACED_KNOTS,
                rate_hz: float = 10000.0) -> SplinePath:
    """The joint path a trajectory traces, re-parameterised by joint-space arc length (its end
    velocities are zero, so a time parameter would make the path degenerate there)."""
    T = trajectory.duration_s
    t = np.union1d(np.linspace(0.0, T, int(np.ceil(T * rate_hz)) + 1), trajectory.breakpoints_s)
    q, qd, _ = trajectory.evaluate(t, np.clip(t, 0.0, T * (1 - 1e-12)))
    speed = np.linalg.norm(qd, axis=1)
    sigma = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t))])
    if sigma[-1] <= 0:
        raise QmtInputError("the reference trajectory does not move")
    sk = np.linspace(0.0, sigma[-1], knots)
    tk = np.interp(sk, sigma, t)
    qk = trajectory.evaluate(tk, np.clip(tk, 0.0, T * (1 - 1e-12)))[0]
    return SplinePath(sk, qk)


def task_joint_points(scenario) -> np.ndarray:
    """IK of the task points (start, vias, goal), (k, n) rad; raises QmtInputError."""
    t = scenario.task
    return scenario.arm.inverse_kinematics(t.points_m, t.tool_angle_rad, t.ik_branch,
                                           what="task point")


def straight_segments(scenario, kind: str) -> list[GeometricPath]:
    """Straight joint or tip segments between consecutive task points."""
    pts = scenario.task.points_m
    if kind == "joint_line":
        qk = task_joint_points(scenario)
        return [JointLinePath(qk[i], qk[i + 1]) for i in range(len(qk) - 1)]
    if kind == "cartesian_line":
        task_joint_points(scenario)  # every point reachable and in range
        return [CartesianLinePath(scenario.arm, pts[i], pts[i + 1], scenario.task.tool_angle_rad,
                                  scenario.task.ik_branch) for i in range(len(pts) - 1)]
    raise QmtInputError(f"unknown straight path '{kind}'")


def reported_family_plan(scenario):
    """The thesis's own plan (family at the reported genes; midpoint of the bounds if none)."""
    from qmt_drake.plan import family_plan
    from qmt_drake.problem import PlanningProblem
    problem = PlanningProblem(scenario)
    genes = scenario.reported.get("genes")
    g = (problem.genes_vector(genes) if genes else 0.5 * (problem.lower + problem.upper))
    return family_plan(problem, g, "thesis")


def short_ga_plan(scenario, seed: int = 0, max_generations: int = 300,
                  stall_generations: int = 100):
    """A short GA run (for a `ga_path` without a reference plan)."""
    from qmt_drake.plan import family_plan
    from qmt_drake.planners.ga import run_ga
    from qmt_drake.problem import PlanningProblem
    problem = PlanningProblem(scenario)
    res = run_ga(problem, seed=seed, max_generations=max_generations,
                 stall_generations=stall_generations)
    plan = family_plan(problem, res.genes, "ga", planner_wall_s=res.wall_s,
                       evaluations=res.evaluations, generations=res.generations)
    return plan


def path_segments(scenario, path: str, reference_plan=None):
    """(segments, notes) for a path name; every segment is timed rest to rest."""
    notes = []
    if path in ("joint_line", "cartesian_line"):
        segs = straight_segments(scenario, path)
        if len(segs) > 1:
            notes.append(f"{len(segs)} straight segments meet at corners at the via points: "
                         "the motion stops at each via (each segment timed rest to rest)")
        return segs, notes
    if path == "family":
        if scenario.family.kind == "line_cubic_velocity":
            notes.append("chapter 2 line: exact IK path of the straight tip line (s in m)")
            return straight_segments(scenario, "cartesian_line"), notes
        ref = reported_family_plan(scenario)
        notes.append(f"joint path traced by the {scenario.family.kind} family at the thesis's "
                     f"reported genes {ref.genes}, spline over joint arc length "
                     f"({TRACED_KNOTS} knots)")
        return [traced_path(ref.trajectory)], notes
    if path == "ga_path":
        if reference_plan is None:
            reference_plan = short_ga_plan(scenario)
            notes.append("no reference plan given: a short GA run (seed 0, <= 300 generations, "
                         f"stall 100) gave the path, T0 = {reference_plan.motion_time_s:.4f} s")
        notes.append(f"joint path traced by the reference plan ({reference_plan.method}, "
                     f"{reference_plan.motion_time_s:.4f} s), spline over joint arc length "
                     f"({TRACED_KNOTS} knots)")
        return [traced_path(reference_plan.trajectory)], notes
    raise QmtInputError(f"unknown path '{path}'; use one of {', '.join(PATHS)}")


def chord_angle_rad(scenario, segment: GeometricPath) -> float:
    """Angle of the tip chord (start -> end) of a segment, rad."""
    q = segment(np.array([0.0, segment.length]))
    d = np.diff(scenario.arm.tip_position(q), axis=0)[0]
    return float(np.arctan2(d[1], d[0]))


# ============================================================================ trajectories
class PathTimingTrajectory(JointTrajectory):
    """q(s(t)) with s(t) piecewise quadratic: constant sddot = u_i between grid points s_i
    (toppra's ParametrizeConstAccel), evaluated exactly; breakpoints at the grid times."""

    def __init__(self, path: GeometricPath, gridpoints, sd) -> None:
        self.path = path
        s = np.asarray(gridpoints, dtype=float)
        sd = np.maximum(np.asarray(sd, dtype=float), 0.0)
        ds = np.diff(s)
        self.u = 0.5 * (sd[1:] ** 2 - sd[:-1] ** 2) / ds
        dt = 2 * ds / (sd[1:] + sd[:-1])
        self.ts = np.concatenate([[0.0], np.cumsum(dt)])
        self.s, self.sd = s, sd
        self.duration_s = float(self.ts[-1])
        self.breakpoints_s = self.ts.copy()
        self.n_dof = path.n_dof

    def timing(self, t_s, t_piece_s):
        """s, sdot, sddot at t (piece chosen by t_piece)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        tp = np.broadcast_to(t_piece_s, t.shape)
        rest = tp >= self.duration_s
        j = np.clip(np.searchsorted(self.ts, tp, side="right") - 1, 0, len(self.ts) - 2)
        tau = np.clip(t, self.ts[j], self.ts[j + 1]) - self.ts[j]
        u = self.u[j]
        s = np.minimum(self.s[j] + self.sd[j] * tau + 0.5 * u * tau**2, self.s[-1])
        sd = self.sd[j] + u * tau
        s = np.where(rest, self.s[-1], s)
        sd = np.where(rest, 0.0, sd)
        u = np.where(rest, 0.0, u)
        return s, sd, u

    def evaluate(self, t_s, t_piece_s):
        s, sd, sdd = self.timing(t_s, t_piece_s)
        q, qs, qss = self.path.derivatives(s)
        return q, qs * sd[:, None], qs * sdd[:, None] + qss * (sd**2)[:, None]


class CallableTrajectory(JointTrajectory):
    """A trajectory given by a function f(t, order) -> (len(t), n) (e.g. toppra's spline output);
    derivatives are continuous inside the given breakpoints."""

    def __init__(self, f, duration_s, breakpoints_s, n_dof) -> None:
        self.f = f
        self.duration_s = float(duration_s)
        self.breakpoints_s = np.unique(np.clip(np.concatenate(
            [[0.0, self.duration_s], breakpoints_s]), 0.0, self.duration_s))
        self.n_dof = n_dof

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        rest = np.broadcast_to(t_piece_s, t.shape) >= self.duration_s
        te = np.clip(t, 0.0, self.duration_s)
        q = self.f(te, 0)
        qd = np.where(rest[:, None], 0.0, self.f(te, 1))
        qdd = np.where(rest[:, None], 0.0, self.f(te, 2))
        return q, qd, qdd


class TimeScaledTrajectory(JointTrajectory):
    """`inner` played `factor` times slower: q(t) = q_in(t/factor) (every inertial ratio / factor^2)."""

    def __init__(self, inner: JointTrajectory, factor: float) -> None:
        self.inner, self.factor = inner, float(factor)
        self.duration_s = inner.duration_s * self.factor
        self.breakpoints_s = inner.breakpoints_s * self.factor
        self.n_dof = inner.n_dof

    def evaluate(self, t_s, t_piece_s):
        f = self.factor
        q, qd, qdd = self.inner.evaluate(np.asarray(t_s) / f, np.asarray(t_piece_s) / f)
        return q, qd / f, qdd / f**2


class ConcatenatedTrajectory(JointTrajectory):
    """Rest-to-rest pieces played one after another (via points chained segment by segment)."""

    def __init__(self, parts: list[JointTrajectory]) -> None:
        self.parts = parts
        self.offsets = np.concatenate([[0.0], np.cumsum([p.duration_s for p in parts])])
        self.duration_s = float(self.offsets[-1])
        self.breakpoints_s = np.unique(np.concatenate(
            [p.breakpoints_s + o for p, o in zip(parts, self.offsets[:-1])]))
        self.n_dof = parts[0].n_dof

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        tp = np.broadcast_to(t_piece_s, t.shape)
        k = np.clip(np.searchsorted(self.offsets, tp, side="right") - 1, 0, len(self.parts) - 1)
        n = self.n_dof
        q, qd, qdd = np.empty((t.size, n)), np.empty((t.size, n)), np.empty((t.size, n))
        for i, p in enumerate(self.parts):
            m = k == i
            if np.any(m):
                o = self.offsets[i]
                q[m], qd[m], qdd[m] = p.evaluate(t[m] - o, tp[m] - o)
        return q, qd, qdd


class RestTrajectory(JointTrajectory):
    """Holding q for `duration_s` (0 by default): the trajectory of a plan that found no motion."""

    def __init__(self, q, duration_s: float = 0.0) -> None:
        self.q = np.asarray(q, dtype=float)
        self.duration_s = float(duration_s)
        self.breakpoints_s = np.array([0.0, self.duration_s])
        self.n_dof = self.q.size

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        q = np.broadcast_to(self.q, (t.size, self.n_dof)).copy()
        return q, np.zeros_like(q), np.zeros_like(q)


# ============================================================================ plans
def slowest_allowed_motion_s(scenario) -> float:
    """The slowest motion the scenario's family allows (all genes at their upper bounds), s:
    the time budget every planner here must meet (a longer motion is an infeasible result)."""
    from qmt_drake.families import make_family
    try:
        fam = make_family(scenario)
    except QmtInputError:
        return float("inf")  # the family cannot even be built (its points are out of reach)
    return float(fam.motion_time_s(scenario.family.gene_bounds[:, 1][None])[0])


def start_configuration(scenario) -> np.ndarray:
    try:
        return task_joint_points(scenario)[0]
    except QmtInputError:
        return np.zeros(scenario.arm.n_dof)


def infeasible_plan(scenario, method: str, reason: str, *, planner_wall_s: float = 0.0,
                    trajectory: JointTrajectory | None = None, extra: dict | None = None) -> Plan:
    """A Plan with feasible=False and the reason in extra['infeasible'] (no exception). Without a
    trajectory the arm rests at the start (motion time 0)."""
    traj = trajectory if trajectory is not None else RestTrajectory(start_configuration(scenario))
    ex = dict(extra or {})
    ex["infeasible"] = reason
    return make_plan(scenario, method, traj, planner_wall_s=planner_wall_s, valid=False, extra=ex)


def worst_ratio(check) -> float:
    return max(check.peak_moment_ratio, check.peak_motor_torque_ratio)


def finish_plan(scenario, method: str, trajectory: JointTrajectory, *, planner_wall_s: float,
                extra: dict, slow_to_limits: bool = True, max_motion_time_s: float | None = None,
                evaluations: int = 0) -> Plan:
    """Re-check the planner's raw output at the check rate; record it in extra['raw_check'];
    optionally slow it by the exact factor until the re-check passes; flag a motion longer than
    `max_motion_time_s` (default: the family's slowest allowed motion) as infeasible (such a
    plan keeps no motion: the arm rests at the start, extra['found_motion_time_s'] holds the
    duration the planner found)."""
    extra = dict(extra)
    limit_T = slowest_allowed_motion_s(scenario) if max_motion_time_s is None else max_motion_time_s
    extra["max_motion_time_s"] = limit_T
    if trajectory.duration_s > limit_T:
        # Not re-checked (a very slow motion would take millions of samples): no motion is kept.
        extra["found_motion_time_s"] = trajectory.duration_s
        return infeasible_plan(
            scenario, method, f"the fastest motion found takes {trajectory.duration_s:.4g} s, longer "
            f"than the slowest allowed motion {limit_T:.4f} s (family genes at their upper "
            "bounds): the limits are too tight", planner_wall_s=planner_wall_s, extra=extra)
    raw = recheck(scenario, trajectory)
    extra["raw_check"] = {"motion_time_s": raw.motion_time_s,
                          "peak_moment_ratio": raw.peak_moment_ratio,
                          "peak_motor_torque_ratio": raw.peak_motor_torque_ratio,
                          "joint_range_ok": raw.joint_range_ok}
    traj, factor = trajectory, 1.0
    if slow_to_limits and raw.joint_range_ok and worst_ratio(raw) > 1.0:
        check = raw
        for _ in range(4):
            factor *= np.sqrt(worst_ratio(check)) * (1 + 1e-9)
            traj = TimeScaledTrajectory(trajectory, factor)
            check = recheck(scenario, traj)
            if worst_ratio(check) <= 1.0:
                break
        extra["slowdown_factor"] = factor
        extra["note_slowdown"] = (f"the planner's own output broke a limit on the re-check (peak "
                                  f"moment ratio {raw.peak_moment_ratio:.5f}, motor "
                                  f"{raw.peak_motor_torque_ratio:.5f}); played {factor:.6f} "
                                  "times slower (exact for inertial limits)")
    if not raw.joint_range_ok:
        return infeasible_plan(scenario, method, "the path leaves a joint range",
                               planner_wall_s=planner_wall_s, trajectory=traj, extra=extra)
    if traj.duration_s > limit_T:
        return infeasible_plan(
            scenario, method, f"slowed to keep the limits, the motion takes {traj.duration_s:.4f} s, "
            f"longer than the slowest allowed motion {limit_T:.4f} s: the limits are too tight",
            planner_wall_s=planner_wall_s, trajectory=traj, extra=extra)
    return make_plan(scenario, method, traj, planner_wall_s=planner_wall_s, extra=extra,
                     evaluations=evaluations)


# ============================================================================ TOPP-RA (toppra)
def _constraint(scenario, angle0_rad: float, sides: int, inscribed: bool,
                vertex_on_chord: bool = True):
    """The moment polygon and motor-torque rows as one vectorised toppra SecondOrderConstraint.
    vertex_on_chord: a vertex (else an edge normal) points along angle0."""
    from toppra.constraint import DiscretizationType, SecondOrderConstraint
    from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate

    arm = scenario.arm
    n = arm.n_dof
    A = scenario.limits.moment_limit_Nm / scenario.moment_per_accel_kgm  # m/s^2
    scale_motor = arm.gear_ratio * scenario.limits.motor_torque_limit_Nm  # joint-side N*m
    offset = np.pi / sides if vertex_on_chord else 0.0
    theta = angle0_rad + offset + 2 * np.pi * np.arange(sides) / sides  # vertex at angle0
    normals = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    F = np.zeros((sides + 2 * n, 2 + n))
    F[:sides, :2] = normals
    F[sides:sides + n, 2:] = np.eye(n)
    F[sides + n:, 2:] = -np.eye(n)
    g = np.ones(sides + 2 * n)
    g[:sides] = np.cos(np.pi / sides) if inscribed else 1.0

    def w(q, qd, qdd):
        a, tau = arm.tip_acceleration_and_joint_torque(q, qd, qdd)
        return np.concatenate([a / A, tau / scale_motor], axis=-1)

    class _Rows(SecondOrderConstraint):
        def compute_constraint_params(self, path, gridpoints):
            q, qs, qss = path.derivatives(np.asarray(gridpoints, dtype=float))
            zero = np.zeros_like(q)
            c = w(q, zero, zero)
            a = w(q, zero, qs) - c
            b = w(q, qs, qss) - c
            Fv = np.broadcast_to(F, (len(q),) + F.shape).copy()
            gv = np.broadcast_to(g, (len(q),) + g.shape).copy()
            if self.discretization_type == DiscretizationType.Interpolation:
                return canlinear_colloc_to_interpolate(a, b, c, Fv, gv, None, None, gridpoints)
            return a, b, c, Fv, gv, None, None

    return _Rows(w, lambda q: F, lambda q: g, n, discretization_scheme=DiscretizationType.Interpolation)


class _ToppraPath:
    """Adapter: a GeometricPath as toppra's AbstractGeometricPath."""

    def __new__(cls, path: GeometricPath):
        from toppra.interpolator import AbstractGeometricPath

        class _P(AbstractGeometricPath):
            def __call__(self, s, order=0):
                return path(s, order)

            def derivatives(self, s):
                return path.derivatives(s)

            @property
            def dof(self):
                return path.n_dof

            @property
            def path_interval(self):
                return np.array([0.0, path.length])

        return _P()


def toppra_segment(scenario, segment: GeometricPath, *, polygon_sides: int = 32,
                   grid_points: int = 200, inscribed: bool = True,
                   parametrizer: str = "ParametrizeConstAccel", vertex_on_chord: bool = True):
    """Time one rest-to-rest segment; (trajectory or None, return code, solve wall s)."""
    from toppra.algorithm import TOPPRA
    t0 = time.perf_counter()
    c = _constraint(scenario, chord_angle_rad(scenario, segment), polygon_sides, inscribed,
                    vertex_on_chord)
    grid = np.linspace(0.0, segment.length, int(grid_points))
    tp = _ToppraPath(segment)
    algo = TOPPRA([c], tp, gridpoints=grid, parametrizer=parametrizer)
    traj_out = algo.compute_trajectory(0.0, 0.0)
    wall = time.perf_counter() - t0
    code = str(algo.problem_data.return_code)
    if traj_out is None:
        return None, code, wall
    sd = algo.problem_data.sd_vec
    if parametrizer == "ParametrizeConstAccel":
        traj = PathTimingTrajectory(segment, grid, sd)
        # Same formulas as toppra's ParametrizeConstAccel: the durations must agree.
        assert abs(traj.duration_s - traj_out.duration) <= 1e-9 * max(1.0, traj.duration_s)
    else:
        ts = traj_out.waypoints[0] if traj_out.waypoints is not None else []
        traj = CallableTrajectory(lambda t, k: np.atleast_2d(traj_out(t, k)), traj_out.duration,
                                  ts, segment.n_dof)
    return traj, code, wall


def plan_toppra(scenario, path: str = "family", polygon_sides: int = 32, grid_points: int = 200,
                reference_plan: Plan | None = None, *, parametrizer: str = "ParametrizeConstAccel",
                measure_polygon_cost: bool = True, slow_to_limits: bool = True,
                max_motion_time_s: float | None = None, vertex_on_chord: bool = True) -> Plan:
    """TOPP-RA (toppra package) on a geometric path; returns a re-checked Plan ("toppra").

    path: one of PATHS (module docstring). polygon_sides: sides P of the inscribed moment polygon
    (even; vertex along each segment's chord). grid_points: toppra grid points per segment
    (uniform in the path parameter). reference_plan: the plan whose path "ga_path" times.
    parametrizer: "ParametrizeConstAccel" (default) or "ParametrizeSpline" (toppra's default,
    known to overshoot: for demonstration). measure_polygon_cost: also time the path with the
    circumscribed polygon (a lower bound for the exact norm bound). slow_to_limits: see module
    docstring. max_motion_time_s: time budget (default: the family's slowest allowed motion).
    vertex_on_chord: False turns the polygon by half a side (an edge normal along the chord: on a
    straight line the motion is then 1/sqrt(cos(pi/P)) times slower; for tests and studies).
    """
    if polygon_sides < 4 or polygon_sides % 2:
        raise QmtInputError(f"polygon_sides must be an even number >= 4, got {polygon_sides}")
    if grid_points < 3:
        raise QmtInputError(f"grid_points must be at least 3, got {grid_points}")
    if parametrizer not in ("ParametrizeConstAccel", "ParametrizeSpline"):
        raise QmtInputError("parametrizer must be ParametrizeConstAccel or ParametrizeSpline")
    method = "toppra"
    t_start = time.perf_counter()
    extra = {"path": path, "polygon_sides": int(polygon_sides), "grid_points": int(grid_points),
             "parametrizer": parametrizer,
             "polygon_worst_case_time_cost": 1 / np.sqrt(np.cos(np.pi / polygon_sides)) - 1,
             "polygon": "inscribed, " + ("one vertex" if vertex_on_chord else "one edge normal")
                        + " along each segment's tip chord"}
    try:
        segs, notes = path_segments(scenario, path, reference_plan)
    except QmtInputError as exc:
        if path not in PATHS:
            raise
        return infeasible_plan(scenario, method, f"no path: {exc}",
                               planner_wall_s=time.perf_counter() - t_start, extra=extra)
    extra["notes"] = notes
    extra["path_unit"] = segs[0].unit
    parts, solve_wall, codes, outer_T = [], 0.0, [], 0.0
    for seg in segs:
        traj, code, wall = toppra_segment(scenario, seg, polygon_sides=polygon_sides,
                                          grid_points=grid_points, parametrizer=parametrizer,
                                          vertex_on_chord=vertex_on_chord)
        solve_wall += wall
        codes.append(code)
        if traj is None:
            return infeasible_plan(scenario, method, f"toppra found no parameterization ({code})",
                                   planner_wall_s=time.perf_counter() - t_start, extra=extra)
        parts.append(traj)
        if measure_polygon_cost:
            outer, _, _ = toppra_segment(scenario, seg, polygon_sides=polygon_sides,
                                         grid_points=grid_points, inscribed=False,
                                         vertex_on_chord=vertex_on_chord)
            outer_T += outer.duration_s if outer is not None else np.nan
    traj = parts[0] if len(parts) == 1 else ConcatenatedTrajectory(parts)
    extra["toppra_solve_wall_s"] = solve_wall
    extra["return_codes"] = codes
    if measure_polygon_cost:
        extra["circumscribed_polygon_motion_time_s"] = outer_T
        extra["polygon_time_cost_bound_s"] = traj.duration_s - outer_T
    wall = time.perf_counter() - t_start
    return finish_plan(scenario, method, traj, planner_wall_s=wall, extra=extra,
                       slow_to_limits=slow_to_limits, max_motion_time_s=max_motion_time_s)


# ============================================================================ Drake's Toppra
def plan_toppra_drake(scenario, path: str = "family", grid_points: int = 200,
                      reference_plan: Plan | None = None, *, box: str = "inscribed",
                      path_knots: int = 400, slow_to_limits: bool = True,
                      max_motion_time_s: float | None = None) -> Plan:
    """Drake's pydrake.multibody.optimization.Toppra on the same paths ("toppra-drake").

    Drake's frame-acceleration limit is a per-component box on the hand's spatial acceleration in
    the world frame, not a norm bound. box="inscribed": |a_x|, |a_y| <= A/sqrt(2) (the square
    inside the circle: never above the moment limit, up to 2^(1/4)-1 = 19 % slower on a line along
    an axis); box="circumscribed": |a_x|, |a_y| <= A (the square around the circle: exact for a
    line along x or y, otherwise up to sqrt(2) times the moment limit). Motor torques: joint
    torque limits N * motor limit (Drake's inverse dynamics includes the reflected rotor inertia).
    The path is handed to Drake as a C2 cubic spline through `path_knots` samples of q(s) per
    segment; the result is q(s(t)) with Drake's s(t), re-checked like every plan.
    """
    from pydrake.multibody.optimization import Toppra
    from pydrake.trajectories import PiecewisePolynomial

    if box not in ("inscribed", "circumscribed"):
        raise QmtInputError("box must be 'inscribed' or 'circumscribed'")
    method = "toppra-drake"
    t_start = time.perf_counter()
    arm = scenario.arm
    A = scenario.limits.moment_limit_Nm / scenario.moment_per_accel_kgm
    half = A / np.sqrt(2) if box == "inscribed" else A
    extra = {"path": path, "grid_points": int(grid_points), "box": box,
             "frame_acceleration_box_m_s2": half,
             "what": "Drake Toppra: per-component box on the hand's translational acceleration "
                     f"({box} square of the norm bound), joint torque limits N*motor limit"}
    try:
        segs, notes = path_segments(scenario, path, reference_plan)
    except QmtInputError as exc:
        if path not in PATHS:
            raise
        return infeasible_plan(scenario, method, f"no path: {exc}",
                               planner_wall_s=time.perf_counter() - t_start, extra=extra)
    extra["notes"] = notes
    big = 1e6
    lower = np.array([-big, -big, -big, -half, -half, -big])
    upper = -lower
    upper[3:5] = half
    tau_lim = arm.gear_ratio * scenario.limits.motor_torque_limit_Nm
    parts, solve_wall = [], 0.0
    for seg in segs:
        s = np.linspace(0.0, seg.length, path_knots)
        q, qs, _ = seg.derivatives(s)
        pp = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
            s, q.T, qs[0][:, None], qs[-1][:, None])
        t0 = time.perf_counter()
        grid = np.linspace(0.0, seg.length, int(grid_points))
        top = Toppra(pp, arm.plant, grid)
        top.AddFrameAccelerationLimit(arm.hand_frame, lower, upper)
        top.AddJointTorqueLimit(-tau_lim, tau_lim)
        s_of_t = top.SolvePathParameterization()
        solve_wall += time.perf_counter() - t0
        if s_of_t is None:
            return infeasible_plan(scenario, method, "Drake Toppra found no parameterization",
                                   planner_wall_s=time.perf_counter() - t_start, extra=extra)
        parts.append(_drake_timed(pp, s_of_t))
    extra["toppra_solve_wall_s"] = solve_wall
    traj = parts[0] if len(parts) == 1 else ConcatenatedTrajectory(parts)
    return finish_plan(scenario, method, traj, planner_wall_s=time.perf_counter() - t_start,
                       extra=extra, slow_to_limits=slow_to_limits,
                       max_motion_time_s=max_motion_time_s)


def _drake_timed(pp, s_of_t) -> JointTrajectory:
    """q(s(t)) from Drake's path q(s) and its s(t), breakpoints at s(t)'s segment times."""
    d1, d2 = pp.derivative(1), pp.derivative(2)
    s1, s2 = s_of_t.derivative(1), s_of_t.derivative(2)
    t0 = s_of_t.start_time()
    T = s_of_t.end_time() - t0
    s_end = pp.end_time()

    def f(t, order):
        t = np.asarray(t, dtype=float) + t0
        s = np.clip(s_of_t.vector_values(t)[0], 0.0, s_end)
        if order == 0:
            return pp.vector_values(s).T
        sd = s1.vector_values(t)[0]
        if order == 1:
            return (d1.vector_values(s) * sd).T
        sdd = s2.vector_values(t)[0]
        return (d1.vector_values(s) * sdd + d2.vector_values(s) * sd**2).T

    bp = np.asarray(s_of_t.get_segment_times()) - t0
    return _OneSided(f, T, bp, pp.rows())


class _OneSided(CallableTrajectory):
    """CallableTrajectory whose pieces are evaluated 1e-9 s inside (one-sided at breakpoints)."""

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        tp = np.broadcast_to(t_piece_s, t.shape)
        bp = self.breakpoints_s
        j = np.clip(np.searchsorted(bp, tp, side="right") - 1, 0, len(bp) - 2)
        te = np.clip(t, bp[j] + 1e-9, bp[j + 1] - 1e-9)
        return super().evaluate(te, tp)
