"""Every planner on a spatial scenario (spatial_task.SpatialScenario), each result re-checked.

- `toppra`: TOPP-RA (planners/spatial_toppra.plan_toppra) along a family's geometric path, joint
  speed/acceleration limits, joint torque and the hand's rows; its time-optimal duration on that path
  is the benchmark's bound for the path. `family` via_cubic (default): the IK'd path through the task
  poses and transfer points (a joint-space cubic in s through sc.q_path_rad, passing the inner poses
  without stopping); line_cubic_velocity / trapezoid_ptp: their segments (planners/spatial_families:
  the Cartesian straight lines, or the joint-space straight lines), each from rest to rest.
- `ruckig`: Ruckig's time-optimal jerk-limited motion in joint space from task pose to task pose,
  stopping at each (the community Ruckig computes no intermediate waypoints); Ruckig knows only the
  joint speed/acceleration/jerk limits, so a segment whose torque/suction re-check fails is planned
  again by Ruckig with its acceleration and jerk limits times the largest factor c <= 1 (bisection)
  for which the re-check holds (speed limits kept).
- `family_optimum`, `ga`: the fastest member of a family and the GA over its genes
  (planners/spatial_search.py; families in planners/spatial_families.py).
- `trajopt`: Drake's KinematicTrajectoryOptimization (a cubic B-spline, `control_points`), minimum
  duration under joint position/speed/acceleration/jerk bounds, zero velocity and acceleration at
  both ends, every point of the IK'd geometric path (task poses and transfer points, so the cup
  stays near face-down between them) an equality constraint at a fixed path parameter (given
  fractions, e.g. TOPP-RA's times at them over its duration, else joint chord-length shares, and where
  those find no trajectory the times a rest-to-rest move at constant acceleration covers the shares,
  `point_fractions_rule` in the plan: a spline at rest at an end reaches a point near it in share only
  through a small basis weight), and
  the hand's face normal within `max_tilt_rad` (0.02 rad) of the path's (slerped between path points)
  at `tilt_samples` (40) evenly spaced path parameters (Drake's AngleBetweenVectorsConstraint: without
  it the spline tilts the hand between path points until gravity alone breaks the magnet's moment
  limit); SNOPT with a 1e-10 feasibility tolerance (a point it stops on unsolved, e.g. its exit 41, that
  meets every constraint within 1e-6 is used, `proven_optimal: false`; else the refusal names what it
  breaks). Torque and suction are not in its program (nonlinear in the spline's control points), so the
  result is time-scaled uniformly (scale_to_hold)
  until their re-check holds. The program is the one trajopt's (planners/trajopt_core.py; this is its
  spatial adapter, the planar one planners/baselines/trajopt_plan.py). In a cell (sc.obstacles), where the
  result's certified clearance is below half of `clearance_m`, the program is solved again with Drake's
  MinimumDistanceLowerBoundConstraint (planners/trajopt_clearance.py).

Every planner returns a SpatialPlan (planners/spatial_plan_io: a plan.Plan of the spatial kind).
Every method's result is passed through spatial_trajectory.scale_to_hold at the re-check rate (10x
the check rate), so a plan that only holds at its own grid is slowed by the smallest factor that
makes the fine check hold (the factor is reported: 1 when nothing was needed).
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.multibody.inverse_kinematics import AngleBetweenVectorsConstraint

from qmt_drake.errors import QmtInputError, QmtNoPlanError
from qmt_drake.limits.spatial_columns import joint_range_by_name
from qmt_drake.model.spatial_ik import slerp_unit
from qmt_drake.planners import registry, trajopt_core
from qmt_drake.planners.collision_free import MARGIN_M
from qmt_drake.planners.registry import SPATIAL
from qmt_drake.planners.spatial_families import spatial_family, via_cubic
from qmt_drake.planners.spatial_plan_io import SpatialPlan
from qmt_drake.planners.spatial_ruckig import ruckig_refusal, ruckig_rest_to_rest, ruckig_segment_limits
from qmt_drake.planners.spatial_search import (
    SpatialTightViaProblem,
    SpatialViaProblem,
    finish_or_least_violating,
    plan_family_optimum,
    plan_ga_spatial,
    tight_time,
)
from qmt_drake.planners.spatial_toppra import joint_path, plan_toppra
from qmt_drake.planners.spatial_trajectory import (
    PolyTrajectory,
    RuckigTrajectory,
    SequenceTrajectory,
    ToppraTrajectory,
    check,
)
from qmt_drake.planners.trajopt_clearance import breaks, keep_clear
from qmt_drake.timescale import search_scale

METHODS = registry.names(SPATIAL)  # the registry's spatial rows: toppra, ruckig, family_optimum, ga, trajopt
FAMILY_METHODS = ("toppra", "family_optimum", "ga")  # the planners that take a `family` (spatial_families)
ALIASES = registry.aliases(SPATIAL)  # optimum: the planar scenarios' name of the family optimum


__all__ = ["METHODS", "FAMILY_METHODS", "ALIASES", "PLANNERS", "plan_all", "plan_toppra_spatial", "plan_ruckig_spatial",
           "plan_family_optimum", "plan_ga_spatial", "plan_trajopt_spatial", "ruckig_segments", "via_cubic",
           "tight_time", "SpatialViaProblem", "SpatialTightViaProblem"]


def _toppra(sc, pp, n_grid: int):
    try:
        r = plan_toppra(pp, sc.chain, velocity_limit=sc.velocity_limit_rad_s,
                        acceleration_limit=sc.acceleration_limit_rad_s2, terms=sc.terms(), n_grid=n_grid)
    except QmtInputError as exc:  # no parameterisation: no timing of this path exists (the message names the limit)
        raise QmtNoPlanError(str(exc)) from None
    return ToppraTrajectory(pp, r["grid"], r["sd"]), r["planning_s"]


def plan_toppra_spatial(sc, *, n_grid: int = 1000, family: str = "via_cubic") -> SpatialPlan:
    """TOPP-RA on the family's geometric path (module docstring); n_grid grid points per path (per
    segment for the rest-to-rest families)."""
    t0 = time.perf_counter()
    fam = spatial_family(sc, family)
    if family == "via_cubic":
        pp = joint_path(sc.q_path_rad, *joint_range_by_name(sc.plant, sc.joint_names))  # kept inside the ranges
        traj, solve_s = _toppra(sc, pp, n_grid)
        s_poses = np.asarray(pp.get_segment_times())[sc.path_pose_index]
        return finish_or_least_violating(sc, "toppra", traj, traj.time_at(s_poses), t0,
                           {"n_grid": n_grid, "toppra_solve_s": solve_s})
    parts = [_toppra(sc, path, n_grid) for path in fam.paths]
    traj = SequenceTrajectory([p[0] for p in parts])
    return finish_or_least_violating(sc, "toppra", traj, traj.t_start, t0,
                       {"family": family, **fam.facts, "n_grid": n_grid,
                        "toppra_solve_s": float(sum(p[1] for p in parts))})


def _ruckig(sc, qa, qb, factor: float):
    """Ruckig's time-optimal rest-to-rest motion qa -> qb, acceleration and jerk limits times factor."""
    return ruckig_rest_to_rest(qa, qb, *ruckig_segment_limits(sc, factor))


def ruckig_segments(sc, *, rate_hz: float | None = None, iterations: int = 14):
    """Segment by segment (rest to rest between task poses): Ruckig with the joint limits, and where
    the torque/suction check fails, Ruckig again with acceleration and jerk limits times the largest
    factor c in (0, 1] (bisection, `iterations` halvings) whose check holds; (trajectory, factors)."""
    rate = rate_hz or sc.recheck_rate_hz
    segs, factors = [], []
    for i, (qa, qb) in enumerate(zip(sc.q_poses_rad[:-1], sc.q_poses_rad[1:])):
        seg, c = _ruckig(sc, qa, qb, 1.0), 1.0
        if check(sc, RuckigTrajectory([seg]), rate)["max"] > 1.0:
            def holds(c, qa=qa, qb=qb):
                return check(sc, RuckigTrajectory([_ruckig(sc, qa, qb, c)]), rate)["max"] <= 1.0
            found = search_scale(holds, 0.0, 1.0, safe="below", steps=iterations)  # the one search, on c
            lo, hi = found.lo, found.hi
            if lo == 0.0:  # name the limit that binds at the slowest factor tried (hi)
                r = check(sc, RuckigTrajectory([slowest := _ruckig(sc, qa, qb, hi)]), rate)
                raise QmtNoPlanError(ruckig_refusal(sc, i, slowest, hi, r["binding"], r["max"]))
            seg, c = _ruckig(sc, qa, qb, lo), lo
        segs.append(seg)
        factors.append(c)
    return RuckigTrajectory(segs), factors


def plan_ruckig_spatial(sc) -> SpatialPlan:
    t0 = time.perf_counter()
    traj, factors = ruckig_segments(sc)
    return finish_or_least_violating(sc, "ruckig", traj, traj.t_start, t0, {"segments": len(traj.segments),
                                                          "acceleration_jerk_factors": factors})


def plan_trajopt_spatial(sc, *, control_points: int = 16, point_fractions=None, max_tilt_rad: float = 0.02,
                         tilt_samples: int = 40, clearance_m: float = MARGIN_M) -> SpatialPlan:
    """trajopt (module docstring); in a cell (sc.obstacles) the result keeps clearance_m from the obstacles
    where the plain program does not clear (planners/trajopt_clearance.keep_clear; 0: the plain program only).
    point_fractions None: the path points at their joint chord shares, and where that finds no trajectory, at the
    times a rest-to-rest move at constant acceleration covers those shares (trajopt_core.rest_to_rest_fractions)."""
    t0 = time.perf_counter()
    if not (np.isfinite(clearance_m) and clearance_m >= 0.0):
        raise QmtInputError(f"trajopt clearance_m {clearance_m!r} must be a distance >= 0 in m (0: no clearance constraint)")
    Q = sc.q_path_rad
    if point_fractions is None:
        d = np.linalg.norm(np.diff(Q, axis=0), axis=1)
        c = np.r_[0.0, np.cumsum(d)]
        shares = c / c[-1]  # the last exactly 1 (Drake aborts on a path parameter above 1)
        tries = [("chord shares", shares), ("rest-to-rest times", trajopt_core.rest_to_rest_fractions(shares))]
    else:
        tries = [("given", np.asarray(point_fractions, float))]
    refusals: list[str] = []
    for rule, s in tries:
        if s.shape != (len(Q),) or s[0] != 0.0 or s[-1] != 1.0 or np.any(np.diff(s) <= 0.0):
            raise QmtInputError(f"trajopt point_fractions: give {len(Q)} rising fractions from 0 to 1, one per path point")
        res, info, refusal = _trajopt_at(sc, s, control_points, max_tilt_rad, tilt_samples, clearance_m)
        if refusal is None:
            break
        refusals.append(f"({rule}) {refusal}")
    else:
        raise QmtNoPlanError("trajopt found no trajectory through the task poses: " + "; ".join(refusals)
                             + "; give it more control points or relax a limit")
    if refusals:  # the chord shares found none: the plan is at the rest-to-rest times
        info["chord_shares_refused"] = refusals[0]
    traj = PolyTrajectory(res.trajectory)
    return finish_or_least_violating(sc, "trajopt", traj, s[sc.path_pose_index] * traj.duration_s, t0,
                   {"control_points": control_points, "solver": "SNOPT", "point_fractions": s,
                    "point_fractions_rule": rule, "solution_result": res.solution_result,
                    "proven_optimal": bool(res.success), **info})


def _trajopt_at(sc, s, control_points: int, max_tilt_rad, tilt_samples: int, clearance_m: float) -> tuple:
    """(result, facts, None) of the program with the path points at fractions s (and, in a cell, the clearance
    kept: trajopt_clearance.keep_clear), or (result, facts, what its point breaks) where it found no trajectory."""
    Q, n = sc.q_path_rad, sc.n_dof
    lower, upper = sc.plant.GetPositionLowerLimits(), sc.plant.GetPositionUpperLimits()
    tilt = []
    if max_tilt_rad is not None:  # the face normal within max_tilt_rad of the path's at tilt_samples points
        ctx = sc.plant.CreateDefaultContext()
        tilt = [(AngleBetweenVectorsConstraint(sc.plant, sc.plant.world_frame(), _normal_at(sc, s, sk), sc.ik.hand,
                                               sc.ik.face_axis, 0.0, max_tilt_rad, ctx), sk)
                for sk in np.linspace(0.0, 1.0, tilt_samples)]
    u = np.linspace(0.0, 1.0, control_points)
    guess = np.array([[np.interp(x, s, Q[:, j]) for j in range(n)] for x in u])
    problem = trajopt_core.TrajoptProblem(
        Q, s, lower, upper, control_points, (0.05, 60.0), guess, rest_derivatives=2,
        velocity_limit=sc.velocity_limit_rad_s, acceleration_limit=sc.acceleration_limit_rad_s2,
        jerk_limit=sc.jerk_limit_rad_s3, path_constraints=tilt, snopt_options={"Major feasibility tolerance": 1e-10})
    res, info = trajopt_core.solve(problem), {}
    if sc.obstacles and clearance_m > 0.0:  # the clearance as a constraint where the plain program does not keep it
        res, kept = keep_clear(sc, problem, res, clearance_m, max_tilt_rad, tilt_samples)
        info["trajopt_clearance"] = kept
    if res.usable or info.get("trajopt_clearance", {}).get("used"):  # usable: trajopt_core.TrajoptResult
        return res, info, None
    rounds = info.get("trajopt_clearance", {}).get("rounds")
    also = f"; nor with the clearance ({rounds[-1]['result']}: its point {rounds[-1]['breaks']})" if rounds else ""
    return res, info, f"{res.solution_result}: its point {breaks(res, problem, max_tilt_rad)}{also}"


def _normal_at(sc, fractions, x: float) -> np.ndarray:
    """The path's face normal at path fraction x: slerped between the path points around it."""
    i = int(np.clip(np.searchsorted(fractions, x, side="right") - 1, 0, len(fractions) - 2))
    u = (x - fractions[i]) / max(fractions[i + 1] - fractions[i], 1e-300)
    return slerp_unit(sc.path_normals[i], sc.path_normals[i + 1], np.clip(u, 0.0, 1.0))[0]


PLANNERS = registry.functions(SPATIAL)  # a read-only view of the registry's spatial rows


def plan_all(sc, methods=METHODS) -> dict:
    return {m: PLANNERS[m](sc) for m in methods}
