"""Retime a joint path made elsewhere (MoveIt, a hand-written list) under a spatial scenario's limits.

    plan = retime_path(load_scenario("ur5-suction-bins"), "path.csv")            # or .yaml / .json / (K, n)
    plan.duration_s, plan.recheck["max"], plan.info["end_pose_error"]

A path is the task: its waypoints (radians) are read, mapped to the arm's joints BY NAME
(`joint_path_files.read_joint_path`), and joined by the C2 cubic in the joint-space chord length that the spatial
TOPP-RA uses for the IK'd path (planners/spatial_toppra.joint_path: zero slopes at the ends, the
arm starts and stops at rest). Inputs:

- CSV: a header row of joint names, one waypoint a row (an optional `time_s` / `time_from_start`
  column is ignored, as any timing, but must rise as YAML's times must);
- a ROS 2 `trajectory_msgs/JointTrajectory` as YAML or JSON (`joint_names`, `points[].positions`,
  optional `time_from_start` {sec, nanosec}; also inside a moveit_msgs/RobotTrajectory's
  `joint_trajectory`): only the geometric path is kept; times, if given, must rise.

Refused in one line, before any planning: an unknown or missing joint name, a row of another length,
a value that is no number (text, a boolean), a non-finite value, fewer than 2 waypoints, two neighbouring waypoints closer than SAME_RAD, a
waypoint or the spline between waypoints outside the URDF's joint range, falling time_from_start,
and, when the scenario has obstacles (`world.obstacles`), a path whose arm or carried part collides
with one (`path_clearance`: Drake's signed distance along the spline through the waypoints,
limits/clearance.py, at PATH_CLEARANCE_PER_RAD samples per radian of joint-space length, refined near
its minima, and at every waypoint exactly). The path is the user's and retime keeps its geometry, so
the refusal says where it collides (at waypoint k, or between waypoints k and k+1 and how far along),
the two shapes and the depth, and which waypoints themselves collide. A path that clears reports its
smallest clearance (info 'path_clearance').

Methods: `toppra` (the fastest timing of that very path: planners/spatial_toppra.plan_toppra with the
scenario's joint speed and acceleration limits, joint torques and the hand's contact rows, the same
rows the spatial TOPP-RA uses; on a dense path, e.g. a stream sampled from rest to rest, its grid holds
the path's knots and splits the short pieces where the samples crowd: spatial_toppra.path_grid, info
'grid_points'), `ga` (the spatial GA over the via-point cubic through the path's
waypoints, genes the segment times: it passes every waypoint, but between them its shape depends on
the segment times, so it follows the path only at the waypoints; at most GA_MAX_WAYPOINTS). Either
result goes through the spatial re-check (spatial_plan_io.finish_plan: sampled at 10x the check
rate, slowed by the smallest time scale that makes it hold). The hand's pose error at the path's
ends against the scenario's first/last task pose is reported as information only (info
'end_pose_error': [[m, rad] start, [m, rad] end]); plan.pose_times_s are the path's start and end.
A retimed plan's file (plan.write_json) loads back with `load_plan_file` (also any other plan file of
the scenario, through spatial_plan_io.load_spatial_plan): same scenario name and joints, the rebuilt
trajectory equal to the file's own samples, re-checked afresh.
"""

from __future__ import annotations

import difflib
import inspect
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from qmt_drake.api_checks import OPTION_RANGES, check_options, number, strict_call
from qmt_drake.budgets import check_budget, spatial_ga_estimate
from qmt_drake.config.fields import show
from qmt_drake.config.registry import ENERGY_TIME
from qmt_drake.config.resolve import SPATIAL, kind_of
from qmt_drake.errors import QmtInputError
from qmt_drake.joint_path_files import read_joint_path, source_name
from qmt_drake.limits.clearance import clearance, collision_model
from qmt_drake.plan_files import read_plan_file
from qmt_drake.planners.spatial_plan_io import (
    REBUILD_TOL,
    RETIMED_METHODS,
    SpatialPlan,
    finish_plan,
    load_spatial_plan,
    make_spatial_plan,
    trajectory_from_spec,
)
from qmt_drake.planners.spatial_search import plan_ga_spatial
from qmt_drake.planners.spatial_toppra import joint_path, plan_toppra
from qmt_drake.planners.spatial_trajectory import PolyTrajectory, ToppraTrajectory
from qmt_drake.spatial_task import SpatialScenario, load_spatial_scenario

METHODS = ("toppra", "ga")
SAME_RAD = 1e-9  # neighbouring waypoints closer than this (joint-space norm) are one waypoint given twice
RANGE_SAMPLES = 20  # spline points per waypoint interval checked against the joint range
GA_MAX_WAYPOINTS = 16  # the GA's genes are the segment times: one per interval
PATH_CLEARANCE_PER_RAD = 200  # clearance samples of the path per radian of joint-space length (then refined)


def check_waypoints(sc, Q: np.ndarray, where: str = "joint path") -> None:
    """The refusals of the module docstring on (K, n) waypoints in sc's joint order."""
    bad = np.argwhere(~np.isfinite(Q))
    if bad.size:
        k, j = bad[0]
        raise QmtInputError(f"{where}: waypoint {k} joint {sc.joint_names[j]} is {Q[k, j]} (not a finite number); "
                            "give radians")
    if len(Q) < 2:
        raise QmtInputError(f"{where}: {len(Q)} waypoint(s); a path needs at least 2 (start and end)")
    step = np.linalg.norm(np.diff(Q, axis=0), axis=1)
    if np.any(step < SAME_RAD):
        k = int(np.argmax(step < SAME_RAD))
        raise QmtInputError(f"{where}: waypoints {k} and {k + 1} are the same point (a duplicate); drop one")
    lo, hi = sc.plant.GetPositionLowerLimits(), sc.plant.GetPositionUpperLimits()
    pp = joint_path(Q)
    s = np.linspace(pp.start_time(), pp.end_time(), RANGE_SAMPLES * (len(Q) - 1) + 1)
    q = np.vstack([Q, pp.vector_values(s).T])
    out = np.maximum(lo - q, q - hi)
    if np.any(out > 1e-12):
        i, j = np.unravel_index(int(np.argmax(out)), out.shape)
        what = f"waypoint {i}" if i < len(Q) else "the spline between the waypoints"
        raise QmtInputError(f"{where}: {what} takes joint {sc.joint_names[j]} to {q[i, j]:.4f} rad, outside its "
                            f"range [{lo[j]:.4f}, {hi[j]:.4f}] rad; move the path inside the range")


def _where_on_path(s: float, s_waypoints: np.ndarray) -> str:
    """'waypoint k' or 'between waypoints k and k+1 (x % of the way)' for a path position s (rad)."""
    k = int(np.clip(np.searchsorted(s_waypoints, s, side="right") - 1, 0, len(s_waypoints) - 2))
    frac = (s - s_waypoints[k]) / (s_waypoints[k + 1] - s_waypoints[k])
    if frac <= 1e-6 or frac >= 1.0 - 1e-6:
        return f"waypoint {k if frac <= 1e-6 else k + 1}"
    return f"between waypoints {k} and {k + 1} ({100 * frac:.0f} % of the way)"


def path_clearance(sc, Q: np.ndarray, where: str = "joint path", *, refuse: bool = True) -> dict:
    """{} without obstacles; else the smallest clearance (m) of the arm and its part from the obstacles along
    the spline through the (K, n) waypoints and where it is (module docstring); a path that collides is
    refused in one line (refuse=False: reported, 'refusal' the line)."""
    if not sc.obstacles:
        return {}
    pp = joint_path(Q)
    s_w = np.asarray(pp.get_segment_times(), float)
    c = clearance(sc, PolyTrajectory(pp), PATH_CLEARANCE_PER_RAD)  # the path with its length s [rad] as time
    at_waypoints = [collision_model(sc).distance(q) for q in Q]
    k = int(np.argmin([d[0] for d in at_waypoints]))
    if at_waypoints[k][0] < c["clearance_m"]:  # a waypoint itself is the deepest point
        c = {**c, "clearance_m": at_waypoints[k][0], "clearance_pair": list(at_waypoints[k][1:]),
             "clearance_time_s": float(s_w[k])}
    spot = _where_on_path(c["clearance_time_s"], s_w)
    out = {"clearance_m": float(c["clearance_m"]), "clearance_pair": c["clearance_pair"], "at": spot,
           "path_position_rad": float(c["clearance_time_s"])}
    if c["clearance_m"] < 0.0:
        bad = [f"{j} ({-d[0] * 1e3:.1f} mm)" for j, d in enumerate(at_waypoints) if d[0] < 0.0]
        own = (f"; waypoint{'s' if len(bad) > 1 else ''} {', '.join(bad)} collide{'' if len(bad) > 1 else 's'} "
               "itself" if bad else "; every waypoint itself clears")
        a, b = c["clearance_pair"]
        line = (f"{where} collides {spot}: {a} overlaps {b} by {-c['clearance_m'] * 1e3:.1f} mm{own}; "
                "retime keeps your path's geometry: move the path clear of the obstacle")
        if refuse:
            raise QmtInputError(line)
        out["refusal"] = line
    return out


def end_pose_errors(sc, traj) -> np.ndarray:
    """(2, 2) Drake-FK (m, rad) errors of the hand at the trajectory's start/end to the first/last task pose."""
    q = traj.sample([0.0, traj.duration_s])[0]
    last = len(sc.poses_m) - 1
    return np.array([sc.ik.errors(q[0], sc.poses_m[0], **sc.pose_target(0)),
                     sc.ik.errors(q[1], sc.poses_m[last], **sc.pose_target(last))])


def _retime_toppra(sc, Q, n_grid: int, info: dict) -> SpatialPlan:
    t0 = time.perf_counter()
    pp = joint_path(Q)
    r = plan_toppra(pp, sc.chain, velocity_limit=sc.velocity_limit_rad_s,
                    acceleration_limit=sc.acceleration_limit_rad_s2, terms=sc.terms(), n_grid=n_grid)
    traj = ToppraTrajectory(pp, r["grid"], r["sd"])
    return finish_plan(sc, "retime_toppra", traj, [0.0, traj.duration_s], t0,
                       {**info, "n_grid": n_grid, "grid_points": len(r["grid"]), "toppra_solve_s": r["planning_s"]})


def _retime_ga(sc, Q, info: dict, **ga_options) -> SpatialPlan:
    if len(Q) > GA_MAX_WAYPOINTS:
        raise QmtInputError(f"--method ga: the path has {len(Q)} waypoints; the GA takes at most {GA_MAX_WAYPOINTS} "
                            "(one gene per interval): use --method toppra, or thin the path")
    # the via-cubic family through the path's waypoints instead of the task poses' IK
    p = plan_ga_spatial(replace(sc, q_poses_rad=Q), family="via_cubic", **ga_options)
    return p.replace(scenario=sc, method="retime_ga", extra={**info, **p.extra},
                     pose_times_s=np.array([0.0, p.duration_s]))


def _scenario_arg(scenario) -> SpatialScenario:
    """A spatial scenario; a built-in name or a YAML path of one is loaded; anything else refused."""
    if isinstance(scenario, SpatialScenario):
        return scenario
    kind = kind_of(scenario)
    if kind == SPATIAL or (not kind and isinstance(scenario, (str, Path))):  # no such file: the loader names it
        return load_spatial_scenario(scenario)
    if kind == ENERGY_TIME:
        raise QmtInputError(f"retime_path: {scenario} is an energy-time experiment; pass its arm as a spatial "
                            "scenario: qmt_drake.energy.as_transfer.transfer_scenario_of(load_scenario(NAME))")
    raise QmtInputError(f"retime_path: scenario {show(scenario)} is not a spatial scenario; retime a planar "
                        "scenario's path with qmt_drake.retime_planar.retime_planar_path")


GA_SKIP = ("sc", "family")  # retime's GA searches the via-cubic family through the path's waypoints
_GA_PLANNER = plan_ga_spatial  # its keywords, read once (a test's stand-in for the GA keeps them)
GA_DEFAULTS = {k: p.default for k, p in inspect.signature(plan_ga_spatial).parameters.items() if k not in GA_SKIP}


def _check_ga_options(method: str, ga_options: dict, allow_large) -> None:
    """ga_options against plan_ga_spatial's keywords (a misspelt one named with the closest known keyword),
    their values and the GA's price (budgets.spatial_ga_estimate), before any work."""
    known = ["method", "n_grid", "collisions", "allow_large", *GA_DEFAULTS]
    for key in ga_options:
        if key not in GA_DEFAULTS:
            near = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
            raise QmtInputError(f"retime_path: unknown keyword {key!r}; {f'did you mean {near[0]!r}? ' if near else ''}"
                                f"it takes {', '.join(known)}")
    if method == "toppra" and ga_options:
        raise QmtInputError(f"option {sorted(ga_options)[0]!r} is a GA option; drop it for method toppra")
    if not isinstance(allow_large, (bool, np.bool_)):
        raise QmtInputError(f"retime_path: allow_large {show(allow_large)} must be True or False")
    check_options(_GA_PLANNER, ga_options, "retime_path option", "the spatial GA", skip=GA_SKIP)
    if method == "ga":
        size = {k: ga_options.get(k, GA_DEFAULTS[k]) for k in ("population", "generations")}
        est = replace(spatial_ga_estimate(size["population"], size["generations"]),
                      fix="use fewer generations= (or a smaller stall=) or a smaller population=")
        try:
            check_budget(est, allow_large=bool(allow_large))
        except QmtInputError as exc:  # the API's keyword, not the CLI's flag
            raise QmtInputError(str(exc).replace("--allow-large", "allow_large=True")) from None


@strict_call
def retime_path(scenario, joint_path_or_file, method: str = "toppra", *, n_grid: int = 1000,
                collisions: str = "refuse", allow_large: bool = False, **ga_options) -> SpatialPlan:
    """The fastest timing of a given joint path on a spatial scenario (module docstring): a SpatialPlan
    re-checked at the scenario's re-check rate. scenario: a SpatialScenario, or a spatial scenario's
    built-in name or YAML path (loaded). joint_path_or_file: a .csv / .yaml / .json file, a
    JointTrajectory mapping, or a (K, n) array in scenario.joint_names order (rad). method: "toppra"
    (n_grid grid points) or "ga" (ga_options: plan_ga_spatial's seed, generations, population, stall,
    progress, ...; priced by budgets.spatial_ga_estimate and refused over the budget unless allow_large).
    collisions: "refuse" a path that collides with the scenario's obstacles (one line, before
    any timing), or "report" it (timed anyway: info 'path_clearance' negative, the plan infeasible)."""
    if not isinstance(method, str) or method not in METHODS:
        raise QmtInputError(f"method {show(method)}: retime takes {'|'.join(METHODS)}")
    if not isinstance(collisions, str) or collisions not in ("refuse", "report"):
        raise QmtInputError(f"collisions {show(collisions)}: give 'refuse' or 'report'")
    lo, hi, fix = OPTION_RANGES["n_grid"]  # before any allocation: 10^9 points filled 23 GB
    n_grid = number(n_grid, "n_grid", minimum=lo, maximum=hi, integer=True, fix=fix)
    _check_ga_options(method, ga_options, allow_large)
    scenario = _scenario_arg(scenario)
    src = joint_path_or_file if isinstance(joint_path_or_file, (str, Path)) else None
    where = source_name(src)
    Q = read_joint_path(joint_path_or_file, scenario.joint_names)
    check_waypoints(scenario, Q, where)
    cleared = path_clearance(scenario, Q, where, refuse=collisions == "refuse")
    info = {"path_source": None if src is None else str(src), "path_waypoints": len(Q),
            "path_q_rad": Q, "path_length_rad": float(np.sum(np.linalg.norm(np.diff(Q, axis=0), axis=1)))}
    if cleared:
        info["path_clearance"] = cleared
    plan = _retime_toppra(scenario, Q, n_grid, info) if method == "toppra" else _retime_ga(scenario, Q, info, **ga_options)
    ends = end_pose_errors(scenario, plan.trajectory)
    plan = plan.replace(pose_error=ends, extra={**plan.extra, "end_pose_error": ends})
    return plan


def load_plan_file(path, sc) -> SpatialPlan:
    """A plan file of sc: a retimed path's (module docstring) or any other (load_spatial_plan)."""
    d = read_plan_file(path)
    method = d.get("method")
    if method not in RETIMED_METHODS:
        return load_spatial_plan(path, sc)
    if d.get("scenario") != sc.name or d.get("joint_names") != list(sc.joint_names):
        raise QmtInputError(f"plan file {path} retimes a path of scenario {d.get('scenario')} (joints "
                            f"{d.get('joint_names')}), not of {sc.name}; retime the path for {sc.name}")
    try:
        traj = trajectory_from_spec(d["rebuild"])
        stored = d["trajectory"]
        t = np.asarray(stored["t_s"], float)
        err = float(np.max(np.abs(np.asarray(stored["q_rad"], float) - traj.sample(t)[0])))
        nums = {k: float(d[k]) for k in ("planning_s", "raw_duration_s", "hold_scale")}
        info = dict(d["info"])
    except (KeyError, TypeError, ValueError, RuntimeError, AttributeError) as exc:
        raise QmtInputError(f"plan file {path}: cannot rebuild its trajectory ({str(exc).splitlines()[0]}); "
                            f"write it again with `qmt-drake retime {sc.name} --path FILE --json PATH`") from None
    if not err <= REBUILD_TOL:
        raise QmtInputError(f"plan file {path}: its rebuilt trajectory differs from its own samples by {err:.3g} rad "
                            "(edited by hand?); write it again with `qmt-drake retime`")
    plan = make_spatial_plan(sc, method, traj, [0.0, traj.duration_s], planning_s=nums["planning_s"],
                             raw_duration_s=nums["raw_duration_s"], hold_scale=nums["hold_scale"], info=info)
    ends = end_pose_errors(sc, traj)
    return plan.replace(pose_error=ends, extra={**info, "end_pose_error": ends})
