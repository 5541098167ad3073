"""What the time-optimal baselines (TOPP-RA, Ruckig, trajopt) share: the time budget, the
re-check with the exact slow-down, and infeasible results that never raise.

Every limit here is inertial (no gravity in the plane, no velocity limit), so playing a motion lam
times slower divides every peak ratio by lam^2: `finish_plan` slows an output that breaks a limit
on the 10 kHz re-check by the exact factor sqrt(peak ratio) and keeps the raw overshoot in
extra["raw_check"]. `infeasible_plan` gives feasible=False with the reason in extra["infeasible"].
The time budget is the slowest motion the scenario's family allows (all genes at their upper
bounds): every limit can be met by going slowly enough, so "too tight" means "not within that".
"""

from __future__ import annotations

import time

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.families import make_family
from qmt_drake.plan import Plan, make_plan, recheck
from qmt_drake.planners.baselines.paths import task_joint_points
from qmt_drake.timescale import Grow, search_scale
from qmt_drake.trajectory import JointTrajectory, RestTrajectory, TimeScaledTrajectory


def slowest_allowed_motion_s(scenario) -> float:
    """The slowest motion the scenario's family allows (all genes at their upper bounds), s:
    the time budget every planner here must meet (a longer motion is an infeasible result)."""
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
    return check.worst_ratio


def slow_to_limits_factor(scenario, trajectory, check, tries: int = 40, *,
                          max_motion_time_s: float = float("inf"), rel_tol: float = 1e-4):
    """(factor, slowed trajectory, its check): the motion played `factor` times slower until every
    limit holds on the refined re-check. Exact (factor = sqrt(worst ratio), repeated for the refined
    peaks) when the limit set allows the time-scaling shortcut; with gravity, a growth by 1.5 then a
    geometric bisection on the factor to `rel_tol` (`slowdown_search`, each step a re-check). The growth stops once the motion
    would exceed `max_motion_time_s` (a re-check of a very slow motion takes millions of samples):
    then the slowest factor within the budget is returned with its failing check."""
    if scenario.limit_set.time_scaling_is_exact:
        factor, traj = 1.0, trajectory
        for _ in range(4):
            factor *= np.sqrt(worst_ratio(check)) * (1 + 1e-9)
            traj = TimeScaledTrajectory(trajectory, factor)
            check = recheck(scenario, traj)
            if worst_ratio(check) <= 1.0:
                break
        return factor, traj, check
    checks = {1.0: check}

    def holds(k: float) -> bool:
        checks[k] = recheck(scenario, TimeScaledTrajectory(trajectory, k))
        return worst_ratio(checks[k]) <= 1.0

    found = slowdown_search(holds, max_motion_time_s / trajectory.duration_s, tries, rel_tol)
    k = found.hi  # the fastest that holds, or (growth out of budget or tries) the slowest tried
    if found.status == "capped":  # the slowest factor within the budget, with its failing check
        return k, TimeScaledTrajectory(trajectory, k), checks[k]
    traj = TimeScaledTrajectory(trajectory, k)
    return k, traj, recheck(scenario, traj)


def slowdown_search(holds, factor_cap: float, tries: int, rel_tol: float):
    """The planar baselines' variant of the one search (timescale.search_scale): from 1 (failing),
    growth by 1.5 up to factor_cap in at most `tries` probes, then geometric bisection to rel_tol."""
    return search_scale(holds, safe="above", midpoint="geometric", rel_tol=rel_tol,
                        grow=Grow(start=1.0, factor=1.5, limit=factor_cap, tries=tries))


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
        factor, traj, _ = slow_to_limits_factor(scenario, trajectory, raw,
                                                 max_motion_time_s=limit_T)
        extra["slowdown_factor"] = factor
        extra["note_slowdown"] = (f"the planner's own output broke a limit on the re-check (peak "
                                  f"moment ratio {raw.peak_moment_ratio:.5f}, motor "
                                  f"{raw.peak_motor_torque_ratio:.5f}); played {factor:.6f} "
                                  "times slower (exact when every limit is inertial, else searched)")
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


def no_path_plan(scenario, method: str, exc: Exception, t_start: float, extra: dict) -> Plan:
    """The infeasible result for a path that cannot be built (a point out of reach, a segment
    that leaves a joint range); `t_start` is the planner's perf_counter() at its start."""
    return infeasible_plan(scenario, method, f"no path: {exc}",
                           planner_wall_s=time.perf_counter() - t_start, extra=extra)
