"""The spatial kind of the one plan.Plan and its files: `SpatialPlan` builds the Plan of a spatial
scenario (its facts: pose times, hold scale, re-check, pose errors, clearance), and the spatial
plan.PlanKind registered here (`scenario_kind: spatial_transfer`) gives its summary, its file, written
atomically with what rebuilds the trajectory exactly and loaded back (plan_files.load_plan) only
against the scenario it was made for, and the trajectory as CSV.

A file is the plan's summary, the task-pose times and 1 kHz samples to plot, plus
what identifies its scenario (`scenario`, `scenario_kind` = plan.SPATIAL_PLAN_KIND, `n_dof`,
`joint_names`, `poses_m`, `face_normal`, `pose_normals`, `pose_rotations`), `info` and `rebuild`, the trajectory's own data:

    {"kind": "time_scaled", "k": k, "inner": {...}}             played k times slower (TimeScaled)
    {"kind": "piecewise_cubic", "breaks_s", "q_rad", "qd_rad_s"}  a C1 piecewise cubic (the via cubic):
                                                                  Drake's CubicHermite through its breaks
    {"kind": "bspline", "order", "knots_s", "control_points_rad"}  trajopt's BsplineTrajectory
    {"kind": "toppra", "path": {piecewise_cubic in s}, "grid", "sd"}  TOPP-RA's profile on its path
    {"kind": "sequence", "parts": [{...}, ...]}                trajectories one after another
    {"kind": "segments", "law", "T1_s", "T2_s", "paths": [{piecewise_cubic in u}]}  rest-to-rest
              segments of a family (planners/spatial_families.SegmentTrajectory)
    {"kind": "ruckig", "segments": [{q_start_rad, q_goal_rad, max_velocity_rad_s,
              max_acceleration_rad_s2, max_jerk_rad_s3}]}         Ruckig run again (deterministic)
    {"kind": "filtered_toppra", "base": {toppra}, "windows_s"}  TOPP-RA's timing box-filtered (jerk_filter.py)

Floats are written by repr (exact), so the rebuilt trajectory is the planned one to rounding;
`write_spatial_plan` proves it on every write (rebuilt vs planned at 1 kHz, REBUILD_TOL) and never
writes a file that does not reproduce its plan. `load_spatial_plan` refuses, in one line, a planar
plan file, a plan of another scenario (its content: plan_identity.py, whatever the names say; a file
written before that record, by its name: ur5-magnet-part has ur5-suction-bins's poses but another hand; joint count or names; task poses; or a start/end that Drake's forward kinematics puts
more than POSE_TOL away from the first/last task pose) and a file whose
rebuilt trajectory disagrees with its own samples; it re-checks the limits and the task poses
itself (nothing the file claims is trusted).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from pydrake.math import BsplineBasis
from pydrake.trajectories import BsplineTrajectory, PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.clearance import clearance
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.plan import SPATIAL_PLAN_KIND, Plan, check_plan_file_kind, ratio_report, register_plan_kind
from qmt_drake.plan_files import REBUILD_MODULES, read_plan_file, trajectory_from_rebuild
from qmt_drake.plan_identity import (
    IDENTITY_KEY,
    check_identity,
    differ_note,
    differing_sections,
    identity,
    spatial_sections,
)
from qmt_drake.planners.collision_free import MAX_TILT_RAD, collision_free_scenario
from qmt_drake.planners.spatial_families import SegmentTrajectory
from qmt_drake.planners.spatial_ruckig import ruckig_rest_to_rest, ruckig_segment_limits
from qmt_drake.planners.spatial_trajectory import (
    PolyTrajectory,
    RuckigTrajectory,
    SequenceTrajectory,
    TimeScaled,
    ToppraTrajectory,
    check,
    pose_errors,
    ratios_of,
    scale_to_hold,
)
from qmt_drake.spatial_task import SpatialScenario, load_spatial_scenario
from qmt_drake.trajectory import PolynomialTrajectory

REBUILD_TOL = 1e-9  # rad, rad/s, rad/s^2: rebuilt vs planned (only rounding may differ, ~1e-13)
POSE_TOL = 1e-6  # m and rad: the plan's first/last sample on the scenario's first/last task pose (Drake FK)


SPATIAL_FACTS = ("pose_times_s", "raw_duration_s", "hold_scale", "recheck", "pose_error", "clearance")


def SpatialPlan(*, scenario, method: str, trajectory, check, pose_times_s, raw_duration_s: float,  # noqa: N802
                hold_scale: float, recheck: dict, pose_error, clearance: dict, **plan_fields) -> Plan:
    """The one Plan of a spatial scenario (the name stays for callers; no subclass): `scenario` a
    SpatialScenario, `trajectory` a spatial_trajectory kind already scaled to hold; `check` the re-check
    at the re-check rate (10x the check rate) as a LimitReport of ratios (plan.ratio_report). Its facts:
    `recheck` the same as a dict ('max' the largest); pose_times_s when the hand is at each task pose,
    pose_error (K, 2) their Drake-FK errors (m, rad), raw_duration_s before scale_to_hold, hold_scale its
    k (1: none needed); `clearance` (a scenario with obstacles) the smallest signed distance of the arm
    and part from them along the plan (limits/clearance.py; < 0: a collision, and the plan is not
    feasible), {} without obstacles. `info` (= extra) holds the planner's facts."""
    facts = {"pose_times_s": np.asarray(pose_times_s, float), "raw_duration_s": float(raw_duration_s),
             "hold_scale": float(hold_scale), "recheck": recheck, "pose_error": np.asarray(pose_error, float),
             "clearance": dict(clearance)}
    return Plan(scenario=scenario, method=method, trajectory=trajectory, check=check,
                scenario_kind=SPATIAL_PLAN_KIND, facts=facts, **plan_fields)


def spatial_summary(plan: Plan) -> dict:
    """A spatial plan's CLI keys: the common ones, its re-check, task-pose errors, clearance and info."""
    c = plan.check
    return {"scenario": plan.scenario.name, "scenario_kind": plan.scenario_kind, "method": plan.method,
            "feasible": plan.feasible, "motion_time_s": plan.duration_s, "peak_ratios": dict(c.peak_ratios),
            "check_rate_hz": c.rate_hz, "planner_wall_s": plan.planner_wall_s, "n_dof": plan.n_dof,
            "duration_s": plan.duration_s, "planning_s": plan.planning_s,
            "raw_duration_s": plan.raw_duration_s, "hold_scale": plan.hold_scale,
            "recheck_max_ratio": plan.recheck["max"], "recheck": plan.recheck,
            "max_pose_position_error_m": float(plan.pose_error[:, 0].max()),
            "max_pose_angle_error_rad": float(plan.pose_error[:, 1].max()), **plan.clearance, **plan.info}


def _spatial_feasible(plan: Plan) -> bool:
    return bool(plan.check.feasible and plan.clearance.get("clearance_m", 0.0) >= 0.0)


def _spatial_n_dof(plan: Plan) -> int:
    return int(plan.scenario.n_dof)


def _spatial_pp(plan: Plan, rate_hz: float = 1000.0) -> PiecewisePolynomial:
    t, q, qd, _ = _samples(plan.trajectory, rate_hz)
    return PiecewisePolynomial.CubicHermite(t, q.T, qd.T)


def _spatial_file_dict(plan: Plan) -> dict:
    """The plan file's mapping (module docstring), JSON-ready, its rebuild proven (plan_file_dict)."""
    return jsonable(plan_file_dict(plan.scenario, plan))


def _spatial_csv(plan: Plan, path, rate_hz: float) -> None:
    write_spatial_csv(plan, path, rate_hz)


def make_spatial_plan(sc, method: str, traj, pose_times_s, *, planning_s: float, raw_duration_s: float,
                      hold_scale: float, info: dict) -> Plan:
    """A SpatialPlan of `traj` on sc, re-checked at sc's re-check rate and its task poses measured by
    Drake FK at pose_times_s (nothing the planner says is taken on trust)."""
    times = np.asarray(pose_times_s, float)
    rc = check(sc, traj, sc.recheck_rate_hz, refine=True)
    ratios = ratios_of(rc)
    seg = info.get("segment_times_s")
    genes = info.get("genes") or (None if seg is None else {f"T{i + 1}": v for i, v in enumerate(seg)})
    return SpatialPlan(scenario=sc, method=method, trajectory=traj,
                       check=ratio_report(sc.recheck_rate_hz, traj.duration_s, ratios),
                       genes=None if genes is None else {k: float(v) for k, v in genes.items()},
                       planner_wall_s=float(planning_s), evaluations=int(info.get("evaluations", 0)),
                       generations=int(info.get("generations", 0)), extra=dict(info), pose_times_s=times,
                       raw_duration_s=float(raw_duration_s), hold_scale=float(hold_scale), recheck=rc,
                       pose_error=pose_errors(sc, traj, times),
                       clearance=clearance(sc, traj, sc.recheck_rate_hz) if sc.obstacles else {})


def finish_plan(sc, method: str, traj, pose_times, t0: float, info: dict) -> Plan:
    """The planner's trajectory held at the re-check rate (spatial_trajectory.scale_to_hold) as a
    SpatialPlan; t0 the planner's start (time.perf_counter) for its planning time."""
    raw = traj.duration_s
    held, k = scale_to_hold(sc, traj, sc.recheck_rate_hz, refine=True)
    planning_s = time.perf_counter() - t0
    return make_spatial_plan(sc, method, held, np.asarray(pose_times, float) * k, planning_s=planning_s,
                             raw_duration_s=raw, hold_scale=k, info=info)


def _cubic_spec(pp) -> dict:
    if any(pp.getSegmentPolynomialDegree(i) > 3 for i in range(pp.get_number_of_segments())):
        raise ValueError("only piecewise cubics are stored as breaks, positions and velocities")
    b = np.asarray(pp.get_segment_times())
    return {"kind": "piecewise_cubic", "breaks_s": b, "q_rad": pp.vector_values(b).T,
            "qd_rad_s": pp.MakeDerivative(1).vector_values(b).T}


def trajectory_spec(traj, ruckig_segments=None) -> dict:
    """The `rebuild` data of a spatial trajectory (module docstring); ruckig_segments: the inputs of a
    RuckigTrajectory's segments (Ruckig's result does not carry them)."""
    if isinstance(traj, TimeScaled):
        return {"kind": "time_scaled", "k": traj.k, "inner": trajectory_spec(traj.inner, ruckig_segments)}
    if isinstance(traj, ToppraTrajectory):
        return {"kind": "toppra", "path": _cubic_spec(traj.path.pp), "grid": traj.grid, "sd": traj.sd}
    if isinstance(traj, RuckigTrajectory):  # before SequenceTrajectory, its base
        if ruckig_segments is None or len(ruckig_segments) != len(traj.segments):
            raise ValueError("a Ruckig trajectory needs the inputs of each of its segments")
        return {"kind": "ruckig", "segments": ruckig_segments}
    if isinstance(traj, SequenceTrajectory):
        return {"kind": "sequence", "parts": [trajectory_spec(p) for p in traj.parts]}
    if isinstance(traj, SegmentTrajectory):
        return {"kind": "segments", "law": traj.law, "T1_s": traj.T1_s, "T2_s": traj.T2_s,
                "paths": [_cubic_spec(p.pp) for p in traj.paths]}
    if isinstance(traj, PolynomialTrajectory) and isinstance(traj.pp, BsplineTrajectory):
        bs = traj.pp
        return {"kind": "bspline", "order": bs.basis().order(), "knots_s": np.asarray(bs.basis().knots()),
                "control_points_rad": np.hstack(bs.control_points()).T}
    if isinstance(traj, PolynomialTrajectory):
        return _cubic_spec(traj.pp)
    if callable(getattr(traj, "file_spec", None)):  # a kind registered in plan_files (jerk_filter.FilteredTiming)
        return traj.file_spec()
    raise ValueError(f"no plan-file form for a {type(traj).__name__}")


def _arr(spec: dict, key: str, ndim: int) -> np.ndarray:
    a = np.asarray(spec[key], dtype=float)
    if a.ndim != ndim or a.size == 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"'{key}' must be a finite {ndim}-D array")
    return a


def trajectory_from_spec(spec: dict):
    """The trajectory a `rebuild` dict describes; ValueError/KeyError/TypeError/RuntimeError if malformed."""
    kind = spec["kind"]
    if kind == "time_scaled":
        return TimeScaled(trajectory_from_spec(spec["inner"]), float(spec["k"]))
    if kind == "piecewise_cubic":
        b, q, qd = _arr(spec, "breaks_s", 1), _arr(spec, "q_rad", 2), _arr(spec, "qd_rad_s", 2)
        if not (q.shape == qd.shape and q.shape[0] == b.size >= 2 and np.all(np.diff(b) > 0)):
            raise ValueError("breaks_s must rise and match q_rad and qd_rad_s row for row")
        return PolyTrajectory(PiecewisePolynomial.CubicHermite(b, q.T, qd.T))
    if kind == "bspline":
        cp = _arr(spec, "control_points_rad", 2)
        basis = BsplineBasis(int(spec["order"]), _arr(spec, "knots_s", 1).tolist())
        return PolyTrajectory(BsplineTrajectory(basis, [c.reshape(-1, 1) for c in cp]))
    if kind == "toppra":
        path = trajectory_from_spec(spec["path"]).pp
        return ToppraTrajectory(path, _arr(spec, "grid", 1), _arr(spec, "sd", 1))
    if kind == "sequence":
        return SequenceTrajectory([trajectory_from_spec(p) for p in spec["parts"]])
    if kind == "segments":
        paths = [trajectory_from_spec(p).pp for p in spec["paths"]]
        return SegmentTrajectory(paths, str(spec["law"]), _arr(spec, "T1_s", 1), _arr(spec, "T2_s", 1))
    if kind == "ruckig":
        keys = ("q_start_rad", "q_goal_rad", "max_velocity_rad_s", "max_acceleration_rad_s2", "max_jerk_rad_s3")
        return RuckigTrajectory([ruckig_rest_to_rest(*(_arr(s, k, 1) for k in keys)) for s in spec["segments"]])
    if kind in REBUILD_MODULES:  # plan_files' registry (imported by name on first use)
        return trajectory_from_rebuild(spec, None)
    raise ValueError(f"unknown trajectory kind {kind!r}")


def _ruckig_inputs(sc, plan: Plan):
    factors = plan.info.get("acceleration_jerk_factors")
    if factors is None:
        return None
    out = []
    for qa, qb, c in zip(sc.q_poses_rad[:-1], sc.q_poses_rad[1:], factors):
        v, a, j = ruckig_segment_limits(sc, c)
        out.append({"q_start_rad": qa, "q_goal_rad": qb, "max_velocity_rad_s": v, "max_acceleration_rad_s2": a,
                    "max_jerk_rad_s3": j})
    return out


def _samples(traj, rate_hz: float = 1000.0):
    t = np.union1d(np.arange(0.0, traj.duration_s, 1.0 / rate_hz), [traj.duration_s])
    return (t, *traj.sample(t))


def _max_difference(a, b) -> float:
    return max(float(np.max(np.abs(x - y))) for x, y in zip(a, b))


def plan_file_dict(sc, plan: Plan) -> dict:
    """What write_spatial_plan writes, after proving that `rebuild` reproduces the plan (REBUILD_TOL)."""
    spec = jsonable(trajectory_spec(plan.trajectory, _ruckig_inputs(sc, plan)))
    rebuilt = trajectory_from_spec(json.loads(json.dumps(spec)))
    t, *planned = _samples(plan.trajectory)
    err = _max_difference(planned, rebuilt.sample(t))
    if not (abs(rebuilt.duration_s - plan.duration_s) <= REBUILD_TOL and err <= REBUILD_TOL):
        raise RuntimeError(f"the {plan.method} plan's file form does not rebuild it (difference {err:.3g}); a bug")
    t, q, qd, qdd = _samples(plan.trajectory)  # 1 kHz and the end time, to plot
    samples = {"kind": "samples", "t_s": t, "q_rad": q, "qd_rad_s": qd, "qdd_rad_s2": qdd}
    return {**plan.summary(), "pose_times_s": plan.pose_times_s, "trajectory": samples,
            "scenario": sc.name, "scenario_kind": SPATIAL_PLAN_KIND,
            "scenario_path": str(sc.path), "n_dof": sc.n_dof, "joint_names": list(sc.joint_names),
            "poses_m": sc.poses_m, "face_normal": sc.face_normal, "pose_normals": sc.pose_normals,
            "pose_rotations": sc.pose_rotations,
            "info": plan.info, "rebuild": spec, IDENTITY_KEY: identity(spatial_sections(sc))}


def write_spatial_plan(sc, plan: Plan, path) -> None:
    write_text_atomic(path, json.dumps(jsonable(plan_file_dict(sc, plan))) + "\n")  # = plan.write_json(path)


def write_spatial_csv(plan: Plan, path, rate_hz: float = 1000.0) -> None:
    """t, q_i, qd_i, qdd_i at rate_hz and the end time, units in the header."""
    t, q, qd, qdd = _samples(plan.trajectory, rate_hz)
    n = q.shape[1]
    header = ",".join(["t_s"] + [f"q{i + 1}_rad" for i in range(n)] + [f"qd{i + 1}_rad_s" for i in range(n)]
                      + [f"qdd{i + 1}_rad_s2" for i in range(n)])
    rows = np.column_stack([t, q, qd, qdd])
    write_text_atomic(path, "\n".join([header] + [",".join(f"{v:.12g}" for v in r) for r in rows]) + "\n")


def _check_fits(d: dict, path, sc) -> None:
    """The file's scenario against sc (module docstring), before rebuilding anything."""
    check_plan_file_kind(d, path, SPATIAL_PLAN_KIND, sc.name)
    again = f"plan again with `qmt-drake plan {sc.name} --json PATH`"
    differ = differing_sections(d, spatial_sections(sc))  # content decides, whatever the names say
    if differ != [] and d.get("scenario") != sc.name:  # other content, or no record: by its name
        raise QmtInputError(f"plan file {path} was made for scenario {d.get('scenario')}, not {sc.name}"
                            f"{differ_note(differ)}; {again}")
    check_identity(d, path, spatial_sections(sc), sc.name)  # the same name, other content
    if d.get("joint_names") == list(sc.joint_names) and d.get("n_dof") != sc.n_dof:  # the names agree: say which
        raise QmtInputError(f"plan file {path} says n_dof {d.get('n_dof')} for its {sc.n_dof} joints "
                            f"{list(sc.joint_names)}: the file was edited or damaged; {again}")
    if d.get("n_dof") != sc.n_dof or d.get("joint_names") != list(sc.joint_names):
        raise QmtInputError(f"plan file {path} is for joints {d.get('joint_names')} (scenario {d.get('scenario')}) "
                            f"but scenario {sc.name} has {list(sc.joint_names)}; {again}")
    try:
        poses = np.asarray(d.get("poses_m"), dtype=float)
    except (TypeError, ValueError):
        raise QmtInputError(f"plan file {path}: poses_m is not a list of points") from None
    if poses.shape != sc.poses_m.shape or not np.allclose(poses, sc.poses_m, rtol=0.0, atol=1e-12):
        raise QmtInputError(f"plan file {path} was made for task poses {poses.tolist()} (scenario {d.get('scenario')}) "
                            f"but scenario {sc.name} has {sc.poses_m.tolist()}; {again}")
    try:
        normals = np.asarray(d.get("pose_normals", sc.pose_normals), dtype=float)
    except (TypeError, ValueError):
        raise QmtInputError(f"plan file {path}: pose_normals is not a list of vectors") from None
    if normals.shape != sc.pose_normals.shape or not np.allclose(normals, sc.pose_normals, rtol=0.0, atol=1e-12):
        raise QmtInputError(f"plan file {path} was made for face normals {np.round(normals, 6).tolist()} at the task "
                            f"poses but scenario {sc.name} has {np.round(sc.pose_normals, 6).tolist()}; {again}")
    file_R, own_R = d.get("pose_rotations"), sc.pose_rotations
    try:
        same = (file_R is None and own_R is None) or (
            file_R is not None and own_R is not None and np.shape(file_R) == own_R.shape
            and np.allclose(np.asarray(file_R, dtype=float), own_R, rtol=0.0, atol=1e-12))
    except (TypeError, ValueError):
        raise QmtInputError(f"plan file {path}: pose_rotations is not a list of matrices") from None
    if not same:
        raise QmtInputError(f"plan file {path} was made for other hand rotations at the task poses than scenario "
                            f"{sc.name}'s (task.hand_rpy_rad); {again}")


def load_spatial_plan(path, sc) -> Plan:
    """The plan of a file written by write_spatial_plan, rebuilt exactly and re-checked on sc
    (module docstring); one-line QmtInputError naming the file for any misfit."""
    return _load(Path(path), read_plan_file(path), sc)


def _planned_scenario(d: dict, path: Path, sc):
    """sc, checked to fit the file; for a plan made with `plan --avoid`, the scenario it was planned on:
    sc with its task replaced by the collision-free path, planned again from the file's facts (the chosen
    seed, margin and legs: the same path, planners/collision_free.py) when sc itself does not fit."""
    facts = d.get("collision_free_path")
    try:
        _check_fits(d, path, sc)
        return sc
    except QmtInputError:
        if not isinstance(facts, dict):
            raise
    try:
        avoided, _ = collision_free_scenario(sc, margin_m=float(facts["margin_m"]), seed=int(facts["seed"]),
                                             through=str(facts["through"]),
                                             max_tilt_rad=float(facts.get("tilt_limit_rad", MAX_TILT_RAD)))
    except (KeyError, TypeError, ValueError) as exc:
        raise QmtInputError(f"plan file {path}: its collision_free_path facts are incomplete ({exc}); plan again "
                            f"with `qmt-drake plan {sc.name} --avoid --json PATH`") from None
    _check_fits(d, path, avoided)
    return avoided


RETIMED_METHODS = ("retime_toppra", "retime_ga")  # retime.py's plans (retime.load_plan_file loads them)


def _load(path: Path, d: dict, sc) -> Plan:
    """plan.load_plan's loader of spatial files: sc None reloads the file's own scenario."""
    if d.get("method") in RETIMED_METHODS:  # its task is the user's path, not the scenario's poses
        raise QmtInputError(f"plan file {path} times a joint path from `qmt-drake retime`; load it with "
                            "qmt_drake.retime.load_plan_file(path, scenario) (`qmt-drake simulate` and `export` do)")
    if sc is None:
        src = d.get("scenario_path")
        sc = load_spatial_scenario(src if isinstance(src, str) and Path(src).is_file() else str(d["scenario"]))
    sc = _planned_scenario(d, path, sc)
    try:
        traj = trajectory_from_spec(d["rebuild"])
        stored = d["trajectory"]
        t = _arr(stored, "t_s", 1)
        err = _max_difference([_arr(stored, "q_rad", 2)], [traj.sample(t)[0]])
        times = _arr(d, "pose_times_s", 1)
        nums = {k: float(d[k]) for k in ("planning_s", "raw_duration_s", "hold_scale")}
        info = d.get("info") if isinstance(d.get("info"), dict) else {}
    except (KeyError, TypeError, ValueError, RuntimeError, AttributeError) as exc:
        raise QmtInputError(f"plan file {path}: cannot rebuild its trajectory ({str(exc).splitlines()[0]}); "
                            f"write it again with `qmt-drake plan {sc.name} --json PATH`") from None
    if err > REBUILD_TOL or abs(t[-1] - traj.duration_s) > REBUILD_TOL:
        raise QmtInputError(f"plan file {path}: its rebuilt trajectory differs from its own samples by {err:.3g} rad "
                            "(edited by hand?); write it again with `qmt-drake plan`")
    if times.size != len(sc.poses_m):
        raise QmtInputError(f"plan file {path} has {times.size} task-pose times; scenario {sc.name} has "
                            f"{len(sc.poses_m)} task poses")
    ends = np.array([sc.ik.errors(q, sc.poses_m[k], **sc.pose_target(k)) for q, k in
                     zip(traj.sample([0.0, traj.duration_s])[0], (0, len(sc.poses_m) - 1))])
    if np.any(ends > POSE_TOL):
        raise QmtInputError(f"plan file {path} starts/ends {ends[0, 0] * 1e3:.3g}/{ends[1, 0] * 1e3:.3g} mm "
                            f"away from scenario {sc.name}'s first/last task pose; plan again for this scenario")
    return make_spatial_plan(sc, str(d.get("method", "loaded")), traj, times, planning_s=nums["planning_s"],
                             raw_duration_s=nums["raw_duration_s"], hold_scale=nums["hold_scale"], info=info)


register_plan_kind(SPATIAL_PLAN_KIND, SpatialScenario, _load, summary=spatial_summary, file_dict=_spatial_file_dict,
                   write_csv=_spatial_csv, feasible=_spatial_feasible, n_dof=_spatial_n_dof,
                   to_piecewise_polynomial=_spatial_pp, json_indent=None)
