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

The constraints hold at the samples; the result is re-checked at 10 kHz like every plan and, if it
breaks a limit between samples, played slower by the exact factor with the raw overshoot kept in
extra["raw_check"] (toppra_plan.finish_plan). SNOPT finds a local optimum, so the duration is an
estimate of what any path could do (the free-path bound), not a certificate: extra["solver"]
holds the solver's status.
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import SnoptSolver, SolverOptions
from pydrake.trajectories import BsplineTrajectory

from qmt_drake.errors import QmtInputError
from qmt_drake.plan import Plan
from qmt_drake.planners.baselines.finish import (
    finish_plan,
    infeasible_plan,
    no_path_plan,
    slowest_allowed_motion_s,
)
from qmt_drake.planners.baselines.paths import reported_family_plan, task_joint_points
from qmt_drake.trajectory import JointTrajectory


def basis_weights(basis, s: float, order: int = 2):
    """(active indices, weights (order+1, len(active))): q^(k)(s) = P[:, idx] @ weights[k]."""
    m = basis.num_basis_functions()
    eye = [np.eye(m)[:, [i]] for i in range(m)]
    traj = BsplineTrajectory(basis, eye)
    idx = np.array(basis.ComputeActiveBasisFunctionIndices(s))
    W = [traj.value(s)[idx, 0]]
    d = traj
    for _ in range(order):
        d = d.MakeDerivative()
        W.append(d.value(s)[idx, 0])
    return idx, np.array(W)


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
                 slow_to_limits: bool = True, major_iterations: int = 500) -> Plan:
    """Minimum-duration B-spline through the task points ("trajopt"); see the module docstring.

    num_control_points: B-spline control points (order 4). constraint_samples: normalized times at
    which the moment and effort constraints are imposed (uniform, ends included). via_times:
    normalized times of the via points (default `default_via_times`). initial_guess: "family"
    (least-squares fit to the thesis's reported plan) or "joint_line" (straight joint segments
    over the reported motion time). max_motion_time_s: the duration's upper bound and time budget
    (default: the family's slowest allowed motion). major_iterations: SNOPT's limit.
    """
    if initial_guess not in ("family", "joint_line"):
        raise QmtInputError("initial_guess must be 'family' or 'joint_line'")
    if num_control_points < 6 or constraint_samples < 3:
        raise QmtInputError("trajopt needs num_control_points >= 6 and constraint_samples >= 3")
    method = "trajopt"
    t_start = time.perf_counter()
    arm = scenario.arm
    n = arm.n_dof
    A = scenario.limits.moment_limit_Nm / scenario.moment_per_accel_kgm
    extra = {"num_control_points": int(num_control_points),
             "constraint_samples": int(constraint_samples), "initial_guess": initial_guess,
             "path": "free (B-spline through the task points)"}
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

    # Initial guess.
    ref = reported_family_plan(scenario)
    T0 = ref.motion_time_s
    trajopt = KinematicTrajectoryOptimization(n, num_control_points, 4, T0)
    basis = trajopt.basis()
    sg = np.linspace(0.0, 1.0, 400)
    if initial_guess == "family":
        q_guess = ref.trajectory.sample(sg * T0)[0]
    else:
        knots = np.concatenate([[0], sv, [1]])
        q_guess = np.stack([np.interp(sg, knots, qk[:, j]) for j in range(n)], axis=1)
    B = np.array([[basis.EvaluateBasisFunctionI(i, s) for i in range(num_control_points)]
                  for s in sg])
    P0 = np.linalg.lstsq(B, q_guess, rcond=None)[0]  # (ncp, n)
    P0[0], P0[-1] = qk[0], qk[-1]
    P0[1], P0[-2] = qk[0], qk[-1]  # zero end velocity
    guess = BsplineTrajectory(basis, [P0[i][:, None] for i in range(num_control_points)])
    trajopt.SetInitialGuess(guess)
    prog = trajopt.get_mutable_prog()
    prog.SetInitialGuess(trajopt.duration(), T0)

    trajopt.AddDurationCost(1.0)
    trajopt.AddDurationConstraint(1e-3, T_max)
    trajopt.AddPositionBounds(arm.joint_lower_rad, arm.joint_upper_rad)
    trajopt.AddPathPositionConstraint(qk[0], qk[0], 0.0)
    trajopt.AddPathPositionConstraint(qk[-1], qk[-1], 1.0)
    trajopt.AddPathVelocityConstraint(np.zeros(n), np.zeros(n), 0.0)
    trajopt.AddPathVelocityConstraint(np.zeros(n), np.zeros(n), 1.0)
    for s, q in zip(sv, qk[1:-1]):
        trajopt.AddPathPositionConstraint(q, q, float(s))

    # Uniform samples plus every knot: the tip acceleration has a kink at a knot (the jerk of a
    # cubic B-spline jumps there) and an optimiser puts its peaks exactly there.
    knots = np.clip(np.asarray(basis.knots()), 0.0, 1.0)
    samples = np.unique(np.round(np.concatenate([np.linspace(0.0, 1.0, constraint_samples),
                                                 knots]), 12))
    extra["constraint_samples_with_knots"] = int(samples.size)
    P = trajopt.control_points()  # (n, ncp)
    Tvar = trajopt.duration()
    for s in samples:
        idx, W = basis_weights(basis, float(s))
        k = len(idx)

        def moment(x, W=W, k=k):
            Pa = x[:n * k].reshape(n, k)
            T = x[-1]
            q, q1, q2 = Pa @ W[0], Pa @ W[1], Pa @ W[2]
            a = arm.tip_acceleration(q, q1, q2)  # m per (normalized s)^2 (AutoDiffXd)
            r2 = (a[0] * a[0] + a[1] * a[1]) / (A * A * T**4)
            return np.array([r2])

        vars_ = np.concatenate([P[:, idx].reshape(-1), [Tvar]])
        prog.AddConstraint(moment, [-np.inf], [1.0], vars_, description=f"moment s={s:.3f}")
    tau_lim = arm.gear_ratio * scenario.limits.motor_torque_limit_Nm
    trajopt.AddEffortBoundsAtNormalizedTimes(arm.plant, samples, -tau_lim, tau_lim)

    solver = SnoptSolver()
    opts = SolverOptions()
    opts.SetOption(solver.solver_id(), "Major iterations limit", int(major_iterations))
    t0 = time.perf_counter()
    result = solver.Solve(prog, None, opts)
    solve_wall = time.perf_counter() - t0
    info = result.get_solver_details().info
    extra["solver"] = {"name": "SNOPT", "success": bool(result.is_success()), "info": int(info),
                       "solution_result": str(result.get_solution_result()),
                       "duration_s": float(result.GetSolution(Tvar)), "solve_wall_s": solve_wall}
    traj = BsplineJointTrajectory(trajopt.ReconstructTrajectory(result))
    wall = time.perf_counter() - t_start
    if not result.is_success():
        at_bound = traj.duration_s >= T_max * (1 - 1e-6)
        return infeasible_plan(
            scenario, method, f"SNOPT did not converge ({result.get_solution_result()}, info "
            f"{info})" + (f" with the duration at its upper bound {T_max:.4f} s (the slowest "
                          "allowed motion): the limits are likely too tight" if at_bound else "")
            + "; the last iterate is kept as the trajectory", planner_wall_s=wall,
            trajectory=traj, extra=extra)
    return finish_plan(scenario, method, traj, planner_wall_s=wall, extra=extra,
                       slow_to_limits=slow_to_limits, max_motion_time_s=T_max)
