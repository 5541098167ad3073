"""Geometric paths for the time-optimal baselines, and a path timed by a TOPP-RA profile.

A path maps a parameter s (arc length along a tip line in m, or a normalised joint-space length)
to joint positions with its first two derivatives. Paths (`path_segments(scenario, path)`):
  "family"         the geometric path of the scenario's thesis family: the straight tip line for
                   chapter 2 (exact IK path), otherwise the joint path traced by the family at the
                   thesis's reported genes;
  "ga_path"        the joint path traced by a reference plan (e.g. the GA's);
  "joint_line"     straight joint-space segments between the IK solutions of the task points;
  "cartesian_line" straight tip segments between the task points (tool angle held for 3 joints).
Straight segments meet at corners at the via points, so they are timed rest to rest.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline

from qmt_drake.errors import QmtInputError
from qmt_drake.plan import family_plan
from qmt_drake.plan_files import register_rebuild
from qmt_drake.planners.ga import run_ga
from qmt_drake.problem import PlanningProblem
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
        self.q1 = np.asarray(q1, dtype=float)

    def derivatives(self, s):
        s = np.asarray(s, dtype=float)[:, None]
        q = self.q0 + s * self.direction
        return q, np.broadcast_to(self.direction, q.shape).copy(), np.zeros_like(q)

    def file_spec(self) -> dict:
        return {"kind": "joint_line", "q0_rad": self.q0, "q1_rad": self.q1}


class CartesianLinePath(GeometricPath):
    """Straight tip segment p0 -> p1 by analytic IK, s = tip arc length in m.

    q' and q'' are exact: J_aug q' = [d, 0] and J_aug q'' = -[Jdot q', 0], where J_aug is the tip
    Jacobian (plus the row [1 1 1] that holds the tool angle for a 3-joint arm) and Jdot q' is the
    tip acceleration at (q, q', 0)."""

    unit = "m (tip arc length)"

    def __init__(self, arm, p0, p1, tool_angle_rad=None, branch="elbow_positive",
                 samples: int = 401) -> None:
        self.arm = arm
        self.p0, self.p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
        delta = self.p1 - self.p0
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

    def derivatives(self, s):
        """q, q' = dq/ds, q'' = d2q/ds2: the tip moving at unit speed with zero acceleration."""
        s = np.asarray(s, dtype=float)
        d = np.broadcast_to(self.direction, s.shape + (2,))
        return self.arm.joint_motion_on_tip_path(self.p0 + s[:, None] * self.direction, d, np.zeros_like(d),
                                                 self.tool, self.branch)

    def file_spec(self) -> dict:
        return {"kind": "cartesian_line", "p0_m": self.p0, "p1_m": self.p1, "tool_angle_rad": self.tool,
                "ik_branch": self.branch}


class SplinePath(GeometricPath):
    """Cubic spline (not-a-knot) of q over joint-space arc length: a traced path."""

    unit = "rad (joint-space arc length)"

    def __init__(self, sigma, q) -> None:
        self.spline = CubicSpline(sigma, q, axis=0)
        self.sigma, self.q = np.asarray(sigma, dtype=float), np.asarray(q, dtype=float)  # its file form
        self.length = float(sigma[-1])
        self.n_dof = q.shape[1]

    def file_spec(self) -> dict:
        return {"kind": "spline", "sigma": self.sigma, "q_rad": self.q}

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
    problem = PlanningProblem(scenario)
    genes = scenario.reported.get("genes")
    g = (problem.genes_vector(genes) if genes else 0.5 * (problem.lower + problem.upper))
    return family_plan(problem, g, "thesis")


def short_ga_plan(scenario, seed: int = 0, max_generations: int = 300,
                  stall_generations: int = 100):
    """A short GA run (for a `ga_path` without a reference plan)."""
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

    def file_spec(self) -> dict:
        """What rebuilds it exactly (plan_files.rebuild_spec): its path's own data, the grid and s-dot."""
        return {"kind": "path_timing", "path": self.path.file_spec(), "grid": self.s, "sd": self.sd}


def _finite(spec: dict, key: str, ndim: int) -> np.ndarray:
    a = np.asarray(spec[key], dtype=float)
    if a.ndim != ndim or a.size == 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"'{key}' must be a finite {ndim}-D array")
    return a


def path_from_file(spec: dict, scenario) -> GeometricPath:
    """The path a `file_spec` describes (the same inputs, so the same values bit for bit)."""
    kind = spec["kind"]
    if kind == "joint_line":
        return JointLinePath(_finite(spec, "q0_rad", 1), _finite(spec, "q1_rad", 1))
    if kind == "cartesian_line":
        tool = spec["tool_angle_rad"]
        return CartesianLinePath(scenario.arm, _finite(spec, "p0_m", 1), _finite(spec, "p1_m", 1),
                                 None if tool is None else float(tool), str(spec["ik_branch"]))
    if kind == "spline":
        return SplinePath(_finite(spec, "sigma", 1), _finite(spec, "q_rad", 2))
    raise ValueError(f"unknown path kind {kind!r}")


def path_timing_from_file(spec: dict, scenario) -> PathTimingTrajectory:
    """A TOPP-RA-timed path from its `file_spec`."""
    grid, sd = _finite(spec, "grid", 1), _finite(spec, "sd", 1)
    if grid.size != sd.size or grid.size < 2 or not np.all(np.diff(grid) > 0):
        raise ValueError("grid must rise and match sd")
    return PathTimingTrajectory(path_from_file(spec["path"], scenario), grid, sd)


register_rebuild("path_timing", path_timing_from_file)
