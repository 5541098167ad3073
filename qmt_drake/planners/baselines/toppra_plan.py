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
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.multibody.optimization import Toppra
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError, QmtNoPlanError
from qmt_drake.limits.at_rest import describe_at_rest, worst_at_rest
from qmt_drake.limits.spatial_columns import joint_range_by_name
from qmt_drake.plan import Plan
from qmt_drake.plan_files import register_rebuild
from qmt_drake.planners.baselines.finish import finish_plan, infeasible_plan, no_path_plan
from qmt_drake.planners.baselines.paths import (
    PATHS,
    GeometricPath,
    PathTimingTrajectory,
    chord_angle_rad,
    path_segments,
)
from qmt_drake.planners.spatial_plan_io import SpatialPlan
from qmt_drake.planners.spatial_search import finish_or_least_violating
from qmt_drake.planners.spatial_toppra import joint_path, plan_drake_toppra
from qmt_drake.planners.spatial_trajectory import ToppraTrajectory
from qmt_drake.planners.toppra_core import parameterise, toppra_path
from qmt_drake.trajectory import (
    CallableTrajectory,
    ConcatenatedTrajectory,
    JointTrajectory,
    polynomial_from_spec,
    polynomial_spec,
)


def _constraint(scenario, angle0_rad: float, sides: int, inscribed: bool,
                vertex_on_chord: bool = True):
    """The scenario's limit terms as one toppra constraint (LimitSet.toppra_constraint): each
    term gives w (affine in qdd, quadratic in qd; gravity in its constant part) and rows F w <= g
    (limits/); the payload moment's rows are the polygon described in the module docstring.
    vertex_on_chord: a vertex (else an edge normal) points along angle0."""
    return scenario.limit_set.toppra_constraint(polygon_sides=sides, angle0_rad=angle0_rad,
                                                inscribed=inscribed, vertex_on_chord=vertex_on_chord)


def _toppra_path(path: GeometricPath):
    """A GeometricPath q(s) as toppra's geometric path (toppra_core.toppra_path)."""
    return toppra_path(path, path.n_dof, (0.0, path.length))


def toppra_segment(scenario, segment: GeometricPath, *, polygon_sides: int = 32,
                   grid_points: int | np.ndarray = 200, inscribed: bool = True,
                   parametrizer: str = "ParametrizeConstAccel", vertex_on_chord: bool = True):
    """Time one rest-to-rest segment; (trajectory or None, return code, solve wall s). The one TOPP-RA
    (planners/toppra_core.parameterise); `parametrizer` names the output: the exact constant-s-ddot
    profile (PathTimingTrajectory) or toppra's spline (ParametrizeSpline, for demonstration)."""
    t0 = time.perf_counter()
    c = _constraint(scenario, chord_angle_rad(scenario, segment), polygon_sides, inscribed,
                    vertex_on_chord)
    # grid_points: a count (evenly spaced) or the grid itself (retime_planar: spatial_toppra.path_grid)
    grid = np.linspace(0.0, segment.length, int(grid_points)) if np.ndim(grid_points) == 0 else grid_points
    sol = parameterise(_toppra_path(segment), [c], grid)
    wall = time.perf_counter() - t0
    if not sol.ok:
        return None, sol.return_code, wall
    if parametrizer == "ParametrizeConstAccel":
        traj = PathTimingTrajectory(segment, grid, sol.sd)
        # Same formulas as toppra's ParametrizeConstAccel: the durations must agree.
        assert abs(traj.duration_s - sol.duration_s) <= 1e-9 * max(1.0, traj.duration_s)
    else:
        traj_out = sol.toppra_trajectory(parametrizer)
        ts = traj_out.waypoints[0] if traj_out.waypoints is not None else []
        traj = CallableTrajectory(lambda t, k: np.atleast_2d(traj_out(t, k)), traj_out.duration,
                                  ts, segment.n_dof)
    return traj, sol.return_code, wall


def _segments_into(extra: dict, scenario, path: str, reference_plan):
    """The path's segments (notes go into `extra`), or the QmtInputError saying why the path
    cannot be built; an unknown path name is a user error and raises."""
    if path not in PATHS:
        raise QmtInputError(f"unknown path '{path}'; use one of {', '.join(PATHS)}")
    try:
        segs, notes = path_segments(scenario, path, reference_plan)
    except QmtInputError as exc:
        return exc
    extra["notes"] = notes
    return segs


def _at_rest_clause(scenario, segment, grid_points: int) -> str:
    """The limit with the largest ratio at rest along the segment (limits/at_rest.py): it names the
    culprit when gravity alone breaks a limit somewhere on the path."""
    ls = scenario.limit_set
    s = np.linspace(0.0, segment.length, int(grid_points))
    q = segment.derivatives(s)[0]
    zero = np.zeros_like(q)
    motor = ls.term("motor_torque")
    lim = np.full(ls.n_columns, np.nan)
    if motor is not None:
        lim[ls.slices["motor_torque"]] = motor.joint_limit_Nm
    w = worst_at_rest(ls.columns(q, zero, zero), ls.column_names, ls.ratio_mask, lim)
    k = w["sample"]
    clause = describe_at_rest(w, f"path point s = {s[k]:.4g} ({100 * k / max(len(s) - 1, 1):.0f} % along)")
    return clause + ("; no timing holds it there" if w["ratio"] > 1.0 else "; every limit holds at rest on the path")


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
    segs = _segments_into(extra, scenario, path, reference_plan)
    if isinstance(segs, QmtInputError):
        return no_path_plan(scenario, method, segs, t_start, extra)
    extra["path_unit"] = segs[0].unit
    parts, solve_wall, codes, outer_T = [], 0.0, [], 0.0
    for seg in segs:
        traj, code, wall = toppra_segment(scenario, seg, polygon_sides=polygon_sides,
                                          grid_points=grid_points, parametrizer=parametrizer,
                                          vertex_on_chord=vertex_on_chord)
        solve_wall += wall
        codes.append(code)
        if traj is None:
            return infeasible_plan(scenario, method, f"toppra found no parameterization ({code}): "
                                   + _at_rest_clause(scenario, seg, grid_points),
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
    segs = _segments_into(extra, scenario, path, reference_plan)
    if isinstance(segs, QmtInputError):
        return no_path_plan(scenario, method, segs, t_start, extra)
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
            return infeasible_plan(scenario, method, "Drake Toppra found no parameterization: "
                                   + _at_rest_clause(scenario, seg, grid_points),
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
    traj = _OneSided(f, T, bp, pp.rows())
    traj.pp, traj.s_of_t = pp, s_of_t  # its file form (file_spec)
    return traj


def drake_timed_from_file(spec: dict, scenario) -> JointTrajectory:
    """Drake Toppra's q(s(t)) from its file form: the path q(s) and s(t), exactly."""
    return _drake_timed(polynomial_from_spec(spec["path"]), polynomial_from_spec(spec["s_of_t"]))


register_rebuild("drake_timed", drake_timed_from_file)


class _OneSided(CallableTrajectory):
    """CallableTrajectory whose pieces are evaluated 1e-9 s inside (one-sided at breakpoints)."""

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        tp = np.broadcast_to(t_piece_s, t.shape)
        bp = self.breakpoints_s
        j = np.clip(np.searchsorted(bp, tp, side="right") - 1, 0, len(bp) - 2)
        te = np.clip(t, bp[j] + 1e-9, bp[j + 1] - 1e-9)
        return super().evaluate(te, tp)

    def file_spec(self) -> dict:
        """What rebuilds it exactly (plan_files.rebuild_spec): Drake's path q(s) and its s(t), coefficients."""
        return {"kind": "drake_timed", "path": polynomial_spec(self.pp), "s_of_t": polynomial_spec(self.s_of_t)}


# ============================================================================ Drake's Toppra, spatial arms
def plan_toppra_drake_spatial(sc, *, n_grid: int = 1000) -> SpatialPlan:
    """Drake's Toppra ("toppra-drake") on a spatial scenario's IK'd path (the via-cubic path the spatial
    `toppra` times: spatial_toppra.joint_path through sc.q_path_rad, kept inside the joint ranges) with
    the limits Drake's Toppra takes by joint: speed and acceleration (spatial_toppra.plan_drake_toppra).
    The limits it cannot take (the motor torques with gear, rotor inertia and the carried part, and the
    hand's rows: suction, magnet moment, tray contact) are named in info['not_in_drake_toppra']; the
    project's full re-check (every term, refined between samples) then slows the plan by the smallest
    time scale that makes it hold (info 'hold_scale'), or gives the least-violating plan. Drake's s(t)
    is constant s-ddot between its grid points, so the plan is a ToppraTrajectory of its s-dot there
    (the same motion, and a plan file the spatial loader rebuilds)."""
    t0 = time.perf_counter()
    if not (isinstance(n_grid, int) and n_grid >= 10):
        raise QmtInputError(f"n_grid {n_grid!r} must be an integer >= 10 (Toppra's grid points; 1000 by default)")
    order = [sc.plant.GetJointByName(n).position_start() for n in sc.joint_names]
    if order != list(range(sc.plant.num_positions())):  # Drake's Toppra reads the path in the plant's order
        raise QmtInputError(f"toppra-drake: {sc.name}'s plant positions are not its joints "
                            f"{', '.join(sc.joint_names)} in order; use --method toppra")
    pp = joint_path(sc.q_path_rad, *joint_range_by_name(sc.plant, sc.joint_names))
    try:
        r = plan_drake_toppra(pp, sc.plant, velocity_limit=sc.velocity_limit_rad_s,
                              acceleration_limit=sc.acceleration_limit_rad_s2, n_grid=n_grid)
    except QmtInputError as exc:  # no parameterisation of this path under the joint limits
        raise QmtNoPlanError(str(exc)) from None
    s_of_t = r["s_of_t"]
    tb = np.asarray(s_of_t.get_segment_times())
    grid = s_of_t.vector_values(tb)[0]
    sd = np.maximum(s_of_t.derivative(1).vector_values(tb)[0], 0.0)
    traj = ToppraTrajectory(pp, grid, sd)
    s_poses = np.asarray(pp.get_segment_times())[sc.path_pose_index]
    skipped = [t.name for t in sc.terms()]
    return finish_or_least_violating(sc, "toppra-drake", traj, traj.time_at(s_poses), t0, {
        "n_grid": n_grid, "toppra_solve_s": r["planning_s"], "drake_duration_s": r["duration_s"],
        "in_drake_toppra": ["joint_speed", "joint_acceleration"], "not_in_drake_toppra": skipped,
        "note": "Drake's Toppra took the joint speed and acceleration limits; "
                f"{', '.join(skipped)} are held by the full re-check's slow-down (hold_scale)"})
