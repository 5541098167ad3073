"""Free-path minimum time: Drake KinematicTrajectoryOptimization (B-spline path and duration, SNOPT).

The joint trajectory is a B-spline q(s), s = t/T in [0, 1], with the duration T a decision
variable; the cost is T. Constraints:
  - q(0), q(1) at the IK solutions of the start and goal, q'(0) = q'(1) = 0 (rest to rest);
  - the via points: q(s_k) = IK(via k) at fixed normalized times s_k (default: the fractions of
    the thesis's reported segment times; `via_times` overrides them);
  - joint ranges (AddPositionBounds);
  - payload moment at `constraint_samples` uniform normalized times plus every knot: a custom constraint
    |J q'' + Jdot q'| / (A T^2) <= 1 (A = moment limit / (m_o r_G); the tip acceleration is
    written with pydrake.math functions so SNOPT gets AutoDiff gradients), on the 4 active control
    points and T only;
  - motor torques at the same times: AddEffortBoundsAtNormalizedTimes with joint-side bounds
    N_i * motor limit_i (Drake's inverse dynamics includes the reflected rotor inertia).
  (`limit_rows="moment"`, the thesis arms' published variant; with `"limit_set"`, the tray, the two
  items above are instead every limit term's TOPP-RA rows F w(q, qd, qdd) <= g at the same times:
  the friction cone, the base circle and F_n >= 0 of the bottle, the servos' torques and speeds.)

The program is built and solved by the one trajopt, planners/trajopt_core.py; this is its planar
adapter (the spatial one is spatial_methods.plan_trajopt_spatial).

The constraints hold at the samples; the result is re-checked at 10 kHz like every plan and, if it
breaks a limit between samples, played slower by the exact factor with the raw overshoot kept in
extra["raw_check"] (toppra_plan.finish_plan). SNOPT finds a local optimum, so the duration is an
estimate of what any path could do (the free-path bound), not a certificate: extra["solver"]
holds the solver's status. A solve SNOPT stops unsolved (its iteration limit, its exit 41) on a point
that meets every constraint within trajopt_core.INFEASIBLE_TOL is a trajectory of the program
(trajopt_core.TrajoptResult.usable, the spatial trajopt's one rule): it is finished and re-checked like a
solved one, with extra["proven_optimal"] false and extra["solution_result"] saying why; any other unsolved
point is an infeasible plan naming the constraints it breaks.
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.math import BsplineBasis
from pydrake.trajectories import BsplineTrajectory

from qmt_drake.errors import QmtInputError
from qmt_drake.plan import Plan
from qmt_drake.plan_files import register_rebuild
from qmt_drake.planners import trajopt_core
from qmt_drake.planners.baselines.finish import (
    finish_plan,
    infeasible_plan,
    no_path_plan,
    slowest_allowed_motion_s,
)
from qmt_drake.planners.baselines.paths import reported_family_plan, task_joint_points
from qmt_drake.planners.trajopt_core import (
    LimitRows,
    RatioRows,
    TrajoptProblem,
    basis_weights,
    samples_with_knots,
)
from qmt_drake.trajectory import JointTrajectory

LIMIT_ROWS = ("auto", "moment", "limit_set")
__all__ = ["basis_weights", "plan_trajopt", "default_via_times", "BsplineJointTrajectory", "LIMIT_ROWS"]


class BsplineJointTrajectory(JointTrajectory):
    """A Drake BsplineTrajectory of q in time (from ReconstructTrajectory)."""

    def __init__(self, bspline) -> None:
        self.b = bspline
        self.b1 = bspline.MakeDerivative()
        self.b2 = self.b1.MakeDerivative()
        self.t0 = bspline.start_time()
        self.duration_s = float(bspline.end_time() - self.t0)
        knots = np.asarray(bspline.basis().knots()) - self.t0
        self.breakpoints_s = np.unique(np.clip(knots, 0.0, self.duration_s))
        self.n_dof = bspline.rows()

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        rest = np.broadcast_to(t_piece_s, t.shape) >= self.duration_s
        te = np.clip(t, 0.0, self.duration_s) + self.t0
        q = self.b.vector_values(te).T
        qd = np.where(rest[:, None], 0.0, self.b1.vector_values(te).T)
        qdd = np.where(rest[:, None], 0.0, self.b2.vector_values(te).T)
        return q, qd, qdd

    def file_spec(self) -> dict:
        """What rebuilds it exactly (plan_files.rebuild_spec): the B-spline's order, knots and control points."""
        return {"kind": "bspline", "order": self.b.basis().order(), "knots_s": np.asarray(self.b.basis().knots()),
                "control_points_rad": np.hstack(self.b.control_points()).T}


def bspline_from_file(spec: dict, scenario) -> BsplineJointTrajectory:
    """The trajectory a `file_spec` describes (the same B-spline, so the same values bit for bit)."""
    cp = np.asarray(spec["control_points_rad"], dtype=float)
    if cp.ndim != 2 or cp.shape[1] != scenario.arm.n_dof or not np.all(np.isfinite(cp)):
        raise ValueError("control_points_rad must be finite rows of one joint vector each")
    basis = BsplineBasis(int(spec["order"]), [float(k) for k in spec["knots_s"]])
    return BsplineJointTrajectory(BsplineTrajectory(basis, [c.reshape(-1, 1) for c in cp]))


register_rebuild("bspline", bspline_from_file)


def default_via_times(scenario, n_points: int) -> np.ndarray:
    """Normalized times of the via points: the thesis's reported segment-time fractions for a
    via_cubic family, else proportional to the joint-space chord lengths."""
    if n_points <= 2:
        return np.array([])
    genes = scenario.reported.get("genes") or {}
    if scenario.family.kind == "via_cubic" and len(genes) == n_points - 1:
        T = np.array([float(genes[k]) for k in scenario.family.gene_names])
        return np.cumsum(T)[:-1] / T.sum()
    qk = task_joint_points(scenario)
    d = np.linalg.norm(np.diff(qk, axis=0), axis=1)
    return np.cumsum(d)[:-1] / d.sum()


def plan_trajopt(scenario, *, num_control_points: int = 16, constraint_samples: int = 80,
                 via_times=None, initial_guess: str = "family", max_motion_time_s: float | None = None,
                 slow_to_limits: bool = True, major_iterations: int = 500, limit_rows: str = "auto") -> Plan:
    """Minimum-duration B-spline through the task points ("trajopt"); see the module docstring.

    num_control_points: B-spline control points (order 4). constraint_samples: normalized times at
    which the limit rows are imposed (uniform, ends included, plus every knot). via_times:
    normalized times of the via points (default `default_via_times`). initial_guess: "family"
    (least-squares fit to the thesis's reported plan) or "joint_line" (straight joint segments
    over the reported motion time). max_motion_time_s: the duration's upper bound and time budget
    (default: the family's slowest allowed motion). major_iterations: SNOPT's limit. limit_rows:
    "moment" (the payload moment's AutoDiff rows and Drake's effort bounds: the thesis arms'
    published variant), "limit_set" (every term's TOPP-RA rows: the tray's friction cone, base
    circle and lift, servo torques and speeds) or "auto" (moment when the scenario has a payload
    moment limit, else limit_set).
    """
    if initial_guess not in ("family", "joint_line"):
        raise QmtInputError("initial_guess must be 'family' or 'joint_line'")
    if num_control_points < 6 or constraint_samples < 3:
        raise QmtInputError("trajopt needs num_control_points >= 6 and constraint_samples >= 3")
    if limit_rows not in LIMIT_ROWS:
        raise QmtInputError(f"limit_rows {limit_rows!r}: use {' or '.join(LIMIT_ROWS)}")
    if limit_rows == "auto":
        limit_rows = "moment" if scenario.limit_set.term("payload_moment") is not None else "limit_set"
    method = "trajopt"
    t_start = time.perf_counter()
    arm = scenario.arm
    n = arm.n_dof
    extra = {"num_control_points": int(num_control_points),
             "constraint_samples": int(constraint_samples), "initial_guess": initial_guess,
             "path": "free (B-spline through the task points)", "limit_rows": limit_rows}
    try:
        qk = task_joint_points(scenario)
    except QmtInputError as exc:
        return no_path_plan(scenario, method, exc, t_start, extra)
    T_max = slowest_allowed_motion_s(scenario) if max_motion_time_s is None else max_motion_time_s
    sv = np.asarray(default_via_times(scenario, len(qk)) if via_times is None else via_times,
                    dtype=float)
    if sv.size != len(qk) - 2 or np.any(np.diff(np.concatenate([[0], sv, [1]])) <= 0):
        raise QmtInputError(f"via_times must be {len(qk) - 2} increasing numbers in (0, 1)")
    extra["via_normalized_times"] = sv.tolist()
    if sv.size:
        extra["notes"] = ["via points at fixed normalized times (not optimised)"]

    # Initial guess: a least-squares fit of the control points, at rest at both ends.
    ref = reported_family_plan(scenario)
    T0 = ref.motion_time_s
    sg = np.linspace(0.0, 1.0, 400)
    if initial_guess == "family":
        q_guess = ref.trajectory.sample(sg * T0)[0]
    else:
        knots = np.concatenate([[0], sv, [1]])
        q_guess = np.stack([np.interp(sg, knots, qk[:, j]) for j in range(n)], axis=1)

    def initial_points(basis):  # least squares on the program's own basis (its knots, to the bit)
        B = np.array([[basis.EvaluateBasisFunctionI(i, s) for i in range(num_control_points)] for s in sg])
        P0 = np.linalg.lstsq(B, q_guess, rcond=None)[0]  # (ncp, n)
        P0[0], P0[-1] = qk[0], qk[-1]
        P0[1], P0[-2] = qk[0], qk[-1]  # zero end velocity
        return P0

    def samples(b):
        return samples_with_knots(b, constraint_samples)

    problem = TrajoptProblem(np.asarray(qk, float), np.concatenate([[0.0], sv, [1.0]]), arm.joint_lower_rad,
                             arm.joint_upper_rad, num_control_points, (1e-3, T_max), initial_points, initial_duration_s=T0,
                             snopt_options={"Major iterations limit": int(major_iterations)})
    if limit_rows == "moment":
        A = scenario.limits.moment_limit_Nm / scenario.moment_per_accel_kgm

        def moment(q, q1, q2, T):
            a = arm.tip_acceleration(q, q1, q2)  # m per (normalized s)^2 (AutoDiffXd)
            return np.array([(a[0] * a[0] + a[1] * a[1]) / (A * A * T**4)])

        problem.ratio_rows.append(RatioRows(moment, samples, "moment"))
        tau_lim = arm.gear_ratio * scenario.limits.motor_torque_limit_Nm
        problem.effort = (arm.plant, samples, -tau_lim, tau_lim)
    else:
        ls = scenario.limit_set
        terms, F, g = ls.toppra_rows()
        problem.limit_rows.append(LimitRows(lambda q, qd, qdd: ls.toppra_w(terms, q, qd, qdd), F, g, samples,
                                            "limit set rows (" + ", ".join(t.name for t in terms) + ")"))
    res = trajopt_core.solve(problem)
    extra["constraint_samples_with_knots"] = int(samples(res.basis).size)
    extra["solver"] = {"name": "SNOPT", "success": res.success, "info": res.info,
                       "solution_result": res.solution_result,
                       "duration_s": res.duration_s, "solve_wall_s": res.solve_wall_s}
    extra["solution_result"] = res.solution_result
    extra["proven_optimal"] = bool(res.success)  # usable but unsolved: a trajectory of the program, not proven minimal
    traj = BsplineJointTrajectory(res.trajectory)
    wall = time.perf_counter() - t_start
    if not res.usable:  # trajopt_core.TrajoptResult.usable: solved, or stopped on a point meeting every constraint
        at_bound = traj.duration_s >= T_max * (1 - 1e-6)
        names = sorted(set(res.infeasible_constraints or []))
        return infeasible_plan(
            scenario, method, f"SNOPT did not converge ({res.solution_result}, info "
            f"{res.info})" + (f" with the duration at its upper bound {T_max:.4f} s (the slowest "
                              "allowed motion): the limits are likely too tight" if at_bound else "")
            + (f"; its point breaks {len(names)} constraints ({', '.join(names[:3])}"
               + (", ..." if len(names) > 3 else "") + ")" if names else "")
            + "; the last iterate is kept as the trajectory", planner_wall_s=wall,
            trajectory=traj, extra=extra)
    return finish_plan(scenario, method, traj, planner_wall_s=wall, extra=extra,
                       slow_to_limits=slow_to_limits, max_motion_time_s=T_max)
