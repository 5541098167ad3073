"""Ruckig: jerk-limited time-optimal rest-to-rest profiles (community edition, offline).

Ruckig knows per-axis velocity, acceleration and jerk limits only, so the payload-moment norm bound
and the motor-torque limits enter as follows:

mode="cartesian_line" (default): the tip moves along the straight segment between consecutive task
  points. Two Cartesian axes with the per-axis limits scaled by the direction cosines of the
  segment (a_max,i = lam * A * |d_i|, j_max,i = J * |d_i|, A = moment limit / (m_o r_G),
  J = `jerk_limit` in m/s^3) and phase synchronization give a profile along the line whose
  acceleration vector has norm exactly lam * A: the norm bound is exact at lam = 1 (1 - 1e-9 is
  used: ruckig may reach a_max to the last bit). The joints follow by analytic IK (tool angle held
  for 3 joints) with exact derivatives. If the motor torques break their limits there, lam is
  reduced by bisection until the sampled trajectory keeps every limit.
mode="joint": straight joint-space segments between the IK solutions of the task points (phase
  synchronization keeps the straight joint line). Per-joint limits along the joint direction u:
  a_max,i = lam * A_s * |u_i|, j_max,i = J_s * |u_i|, with A_s = A / max|J_tip u| and
  J_s = J / max|J_tip u| over the segment (rad/s^2, rad/s^3 along the joint line: the tip
  acceleration without the centripetal term). lam is the largest scale (bisection, relative
  tolerance `bisection_rtol`) whose sampled trajectory keeps the moment and motor-torque
  limits; the jerk limit then bounds the tip jerk only approximately (J_tip-mapped, no Jdot terms).
  When doubling lam no longer shortens the motion the acceleration limit does not bind (the jerk
  limit does) and the search stops there.

The search samples at the scenario's planning rate (1 kHz); the plan is re-checked at the check
rate (10 kHz) and, if it breaks a limit there, played slower by the exact factor (which only
lowers the jerk) with the raw overshoot kept in extra["raw_check"] (toppra_plan.finish_plan).

Via points: the community edition computes intermediate waypoints only through a remote
(cloud) service, unusable offline, so the motion is chained segment by segment, each rest to rest:
it stops at every via point. `extra["notes"]` says so.

Profiles are evaluated by the one Ruckig evaluator (planners/ruckig_core.RuckigProfile: Ruckig's own
`Trajectory.at_time`, vectorised, bit for bit), which keeps Ruckig's inputs: a plan file stores them and
rebuilds the plan exactly (plan_files.py, `rebuild`).
"""

from __future__ import annotations

import time

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.plan import Plan
from qmt_drake.plan_files import register_rebuild
from qmt_drake.planners.baselines.finish import (
    finish_plan,
    infeasible_plan,
    no_path_plan,
    slowest_allowed_motion_s,
)
from qmt_drake.planners.baselines.paths import CartesianLinePath, task_joint_points
from qmt_drake.planners.ruckig_core import RuckigProfile, rest_to_rest_profile
from qmt_drake.sampling import piecewise_grid
from qmt_drake.timescale import Grow, search_scale
from qmt_drake.trajectory import ConcatenatedTrajectory, JointTrajectory

MODES = ("cartesian_line", "joint")
TINY_LIMIT = 1e-12  # limits of an axis the segment does not move along
VIA_NOTE = ("via points chained segment by segment, each rest to rest: the Ruckig community "
            "edition computes intermediate waypoints only through a remote service")


def ruckig_profile(start, goal, v_max, a_max, j_max, phase: bool = True) -> RuckigProfile:
    """Rest-to-rest time-optimal profile (planners/ruckig_core.rest_to_rest_profile; phase synchronisation
    by default), keeping its inputs; raises RuntimeError if ruckig fails."""
    return rest_to_rest_profile(start, goal, v_max, a_max, j_max, phase_synchronization=phase)


class CartesianProfileTrajectory(JointTrajectory):
    """Joints following a Cartesian tip profile by analytic IK with exact derivatives."""

    def __init__(self, arm, profile: RuckigProfile, tool_angle_rad, branch) -> None:
        self.arm, self.profile = arm, profile
        self.tool, self.branch = tool_angle_rad, branch
        self.duration_s = profile.duration_s
        self.breakpoints_s = np.unique(np.concatenate([[0.0, self.duration_s],
                                                       profile.switch_times_s]))
        self.n_dof = arm.n_dof

    def evaluate(self, t_s, t_piece_s):
        p, v, a = self.profile.evaluate(t_s)
        q, qd, qdd = self.arm.joint_motion_on_tip_path(p, v, a, self.tool, self.branch)
        rest = np.broadcast_to(t_piece_s, np.shape(np.atleast_1d(t_s))) >= self.duration_s
        return q, np.where(rest[:, None], 0.0, qd), np.where(rest[:, None], 0.0, qdd)

    def file_spec(self) -> dict:
        """What rebuilds it exactly (plan_files.rebuild_spec): Ruckig's inputs, the tool angle and IK branch."""
        return {"kind": "ruckig", "path": "cartesian_line", "tool_angle_rad": self.tool,
                "ik_branch": self.branch, "ruckig_inputs": self.profile.inputs}


class JointProfileTrajectory(JointTrajectory):
    """Joints on a Ruckig profile in joint space."""

    def __init__(self, profile: RuckigProfile) -> None:
        self.profile = profile
        self.duration_s = profile.duration_s
        self.breakpoints_s = np.unique(np.concatenate([[0.0, self.duration_s],
                                                       profile.switch_times_s]))
        self.n_dof = profile.n

    def evaluate(self, t_s, t_piece_s):
        q, qd, qdd = self.profile.evaluate(t_s)
        rest = np.broadcast_to(t_piece_s, np.shape(np.atleast_1d(t_s))) >= self.duration_s
        return q, np.where(rest[:, None], 0.0, qd), np.where(rest[:, None], 0.0, qdd)

    def file_spec(self) -> dict:
        """What rebuilds it exactly (plan_files.rebuild_spec): Ruckig's inputs."""
        return {"kind": "ruckig", "path": "joint", "ruckig_inputs": self.profile.inputs}


def _number_or_none(x):
    """A tool angle as the task holds it: None (no tool angle held) or a float, rad."""
    return None if x is None else float(x)


RUCKIG_INPUTS = ("start", "goal", "max_velocity", "max_acceleration", "max_jerk")


def trajectory_from_file(spec: dict, scenario) -> JointTrajectory:
    """The trajectory a `file_spec` describes, Ruckig run again on the same inputs (deterministic, so the
    same profile bit for bit); ValueError/KeyError/TypeError if malformed."""
    inp = spec["ruckig_inputs"]
    args = [np.asarray(inp[k], dtype=float) for k in RUCKIG_INPUTS]
    if any(a.ndim != 1 or a.size != args[0].size or not np.all(np.isfinite(a)) for a in args):
        raise ValueError("ruckig_inputs must be finite lists of one length")
    prof = ruckig_profile(*args, phase=bool(inp["phase_synchronization"]))
    if spec["path"] == "cartesian_line":
        return CartesianProfileTrajectory(scenario.arm, prof, _number_or_none(spec["tool_angle_rad"]), str(spec["ik_branch"]))
    if spec["path"] == "joint":
        return JointProfileTrajectory(prof)
    raise ValueError(f"unknown ruckig path {spec['path']!r}")


register_rebuild("ruckig", trajectory_from_file)


def _worst(scenario, traj: JointTrajectory, rate_hz: float) -> float:
    """Worst limit ratio of a trajectory sampled at rate_hz (inf if a joint leaves its range)."""
    grid = piecewise_grid(traj.breakpoints_s[None, :], rate_hz)
    q, qd, qdd = traj.evaluate(grid.t_s, grid.t_piece_s)
    ls = scenario.limit_set
    peaks = ls.batch_peaks(np.array([traj.duration_s]), np.array([True]),
                           ls.columns(q, qd, qdd).max(axis=0)[None])
    return float(peaks.worst_ratio[0]) if peaks.joint_range_ok[0] else np.inf


def _largest_scale(make, worst, lam_max: float | None, rtol: float, max_duration_s: float,
                   max_steps: int = 80):
    """Largest lam (<= lam_max if given) with worst(make(lam)) <= 1; (lam, traj, steps) or
    (None, the slowest trajectory tried, steps) if none before the motion gets longer than max_duration_s.
    The one search (timescale.search_scale) on a limit scale (small lam holds): from lam_max (or 1), doubling
    while it holds (until the motion no longer gets shorter: jerk binds), else halving until it holds (until
    the motion is longer than max_duration_s), then geometric bisection to rtol; max_steps calls in all."""
    trajs = {}

    def holds(lam: float) -> bool:
        trajs[lam] = trajs["last"] = make(lam)
        return worst(trajs[lam]) <= 1.0

    lam = 1.0 if lam_max is None else lam_max
    ok = holds(lam)
    if ok and lam_max is not None:
        return lam, trajs[lam], 1

    def stop(x: float, held: bool, kept: float) -> bool:
        if held:  # the acceleration limit no longer binds (jerk does): keep the last holding scale
            return trajs[x].duration_s >= trajs[kept].duration_s * (1 - 1e-9)
        return trajs[x].duration_s > max_duration_s  # slower still would only be longer

    grow = Grow(start=lam, factor=2.0, start_holds=True) if ok else \
        Grow(start=lam, factor=0.5, limit=1e-12, clip=False, follow=False)
    found = search_scale(holds, safe="below", midpoint="geometric", rel_tol=rtol, max_probes=max_steps, grow=grow,
                         stop=stop, probes=1)
    if found.holding is None:
        return None, trajs["last"], found.probes
    return found.holding, trajs[found.holding], found.probes


def _binding_clause(scenario, slowest, rate_hz: float) -> str:
    """'; <limit column> is still at r of its limit at t on the slowest motion tried': the limit that binds,
    the joint or hand row named (the scenario's LimitSet columns sampled at rate_hz)."""
    if slowest is None:
        return ""
    ls = scenario.limit_set
    grid = piecewise_grid(slowest.breakpoints_s[None, :], rate_hz)
    cols = np.where(np.asarray(ls.ratio_mask)[None, :], ls.columns(*slowest.evaluate(grid.t_s, grid.t_piece_s)),
                    -np.inf)
    k, j = np.unravel_index(int(np.argmax(cols)), cols.shape)
    return (f"; {ls.column_names[j]} is still at {cols[k, j]:.4g} of its limit at t = {grid.t_s[k]:.4g} s of the "
            f"slowest motion tried ({slowest.duration_s:.4g} s)")


def plan_ruckig(scenario, jerk_limit: float = 10.0, mode: str = "cartesian_line", *,
                bisection_rtol: float = 1e-4, velocity_limit_scale: float = 1e6,
                slow_to_limits: bool = True, max_motion_time_s: float | None = None) -> Plan:
    """Ruckig jerk-limited profiles ("ruckig"), re-checked. See the module docstring.

    jerk_limit: tip jerk limit J, m/s^3 (mode "joint": mapped to each joint line, approximate).
    mode: "cartesian_line" or "joint". bisection_rtol: relative tolerance of the limit scale lam.
    velocity_limit_scale: velocity limits are this times A (no velocity limit in the thesis;
    ruckig needs one). slow_to_limits / max_motion_time_s: as in toppra_plan.finish_plan.
    """
    if mode not in MODES:
        raise QmtInputError(f"unknown ruckig mode '{mode}'; use one of {', '.join(MODES)}")
    if not (np.isfinite(jerk_limit) and jerk_limit > 0):
        raise QmtInputError(f"jerk_limit must be a positive number (m/s^3), got {jerk_limit}")
    method = "ruckig"
    t_start = time.perf_counter()
    arm, task = scenario.arm, scenario.task
    A = scenario.limits.moment_limit_Nm / scenario.moment_per_accel_kgm
    rate = scenario.sampling.plan_rate_hz  # the search; make_plan re-checks at the check rate
    extra = {"mode": mode, "jerk_limit_m_s3": float(jerk_limit), "A_m_s2": A,
             "path": "cartesian_line" if mode == "cartesian_line" else "joint_line"}
    notes = []
    pts = task.points_m
    if len(pts) > 2:
        notes.append(VIA_NOTE)
    try:
        qk = task_joint_points(scenario)
    except QmtInputError as exc:
        return no_path_plan(scenario, method, exc, t_start, extra)
    T_max = slowest_allowed_motion_s(scenario) if max_motion_time_s is None else max_motion_time_s
    parts, scales, steps_total, solve_wall = [], [], 0, 0.0
    worst = lambda tr: _worst(scenario, tr, rate)  # noqa: E731
    for i in range(len(pts) - 1):
        if mode == "cartesian_line":
            d = pts[i + 1] - pts[i]
            cos = np.abs(d) / np.hypot(*d)
            lim = np.maximum(cos, TINY_LIMIT)
            # Whole segment reachable and in range (else: infeasible).
            try:
                CartesianLinePath(arm, pts[i], pts[i + 1], task.tool_angle_rad, task.ik_branch)
            except QmtInputError as exc:
                return infeasible_plan(scenario, method, f"no path: {exc}",
                                       planner_wall_s=time.perf_counter() - t_start, extra=extra)

            def make(lam, a=pts[i], b=pts[i + 1], lim=lim):
                prof = ruckig_profile(a, b, velocity_limit_scale * A * lim, lam * A * lim,
                                      jerk_limit * lim)
                return CartesianProfileTrajectory(arm, prof, task.tool_angle_rad, task.ik_branch)
            lam_max = 1.0 - 1e-9  # ruckig may reach a_max to the last bit
        else:
            dq = qk[i + 1] - qk[i]
            u = dq / np.linalg.norm(dq)
            s = np.linspace(0.0, 1.0, 201)[:, None]
            gain = float(np.max(np.linalg.norm(arm.jacobian(qk[i] + s * dq) @ u, axis=-1)))
            lim = np.maximum(np.abs(u), TINY_LIMIT)
            A_s, J_s = A / gain, jerk_limit / gain

            def make(lam, a=qk[i], b=qk[i + 1], lim=lim, A_s=A_s, J_s=J_s):
                prof = ruckig_profile(a, b, velocity_limit_scale * A_s * lim, lam * A_s * lim,
                                      J_s * lim)
                return JointProfileTrajectory(prof)
            lam_max = None
        t0 = time.perf_counter()
        lam, traj, steps = _largest_scale(make, worst, lam_max, bisection_rtol, T_max)
        solve_wall += time.perf_counter() - t0
        steps_total += steps
        if lam is None:
            return infeasible_plan(scenario, method, f"segment {i + 1}: no acceleration scale "
                                   "keeps the limits before the motion gets longer than the "
                                   f"slowest allowed motion {T_max:.4f} s: the limits are too "
                                   "tight" + _binding_clause(scenario, traj, rate),
                                   planner_wall_s=time.perf_counter() - t_start, extra=extra)
        parts.append(traj)
        scales.append(lam)
    traj = parts[0] if len(parts) == 1 else ConcatenatedTrajectory(parts)
    extra.update({"acceleration_scale": scales, "ruckig_calls": steps_total,
                  "search_wall_s": solve_wall, "notes": notes,
                  "synchronization": "phase"})
    if mode == "cartesian_line":
        notes.append("per-axis limits scaled by the segment's direction cosines with phase "
                     "synchronization: the tip acceleration norm is exactly scale * A")
    return finish_plan(scenario, method, traj, planner_wall_s=time.perf_counter() - t_start,
                       extra=extra, slow_to_limits=slow_to_limits,
                       max_motion_time_s=T_max, evaluations=steps_total)
