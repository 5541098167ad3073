"""Every planner on a spatial scenario (spatial_task.SpatialScenario), each result re-checked.

- `toppra`: TOPP-RA (planners/spatial_toppra.plan_toppra) along the IK'd geometric path (cubic in s
  through sc.q_path_rad), joint speed/acceleration limits, joint torque and suction-grip rows; its
  time-optimal duration on that path is the benchmark's bound.
- `ruckig`: Ruckig's time-optimal jerk-limited motion in joint space from task pose to task pose,
  stopping at each (the community Ruckig computes no intermediate waypoints); Ruckig knows only the
  joint speed/acceleration/jerk limits, so a segment whose torque/suction re-check fails is planned
  again by Ruckig with its acceleration and jerk limits times the largest factor c <= 1 (bisection)
  for which the re-check holds (speed limits kept).
- `via_cubic`: the joint-space via-point cubic family through the task poses (genes: the segment
  times T1..T_{K-1}; zero end velocities, continuous acceleration at the vias: Drake's
  CubicWithContinuousSecondDerivatives); `family_optimum` minimises T0 over the segment-time shape
  (Nelder-Mead on the simplex of shares, each shape played at its tightest time scale), `ga` runs
  planners/ga.run_ga on the same genes (SpatialViaProblem, fitness exp(-c T0) when every limit holds).

- `trajopt`: Drake's KinematicTrajectoryOptimization (a cubic B-spline, `control_points`), minimum
  duration under joint position/speed/acceleration/jerk bounds, zero velocity and acceleration at
  both ends, every point of the IK'd geometric path (task poses and transfer points, so the cup
  stays near face-down between them) an equality constraint at a fixed path parameter (given
  fractions, e.g. TOPP-RA's times at them over its duration, else joint chord-length shares), and
  the hand's face normal within `max_tilt_rad` (0.02 rad) of the task's at `tilt_samples` (40)
  evenly spaced path parameters (Drake's AngleBetweenVectorsConstraint: without it the spline tilts
  the hand between path points until gravity alone breaks the magnet's moment limit); SNOPT with a
  1e-10 feasibility tolerance. Torque and suction are not in its program (nonlinear in the spline's control points),
  so the result is time-scaled uniformly (scale_to_hold) until their re-check holds.

Every planner returns a SpatialPlan (planners/spatial_plan_io: a plan.Plan of the spatial kind).
Every method's result is passed through spatial_trajectory.scale_to_hold at the re-check rate (10x
the check rate), so a plan that only holds at its own grid is slowed by the smallest factor that
makes the fine check hold (the factor is reported: 1 when nothing was needed).
"""

from __future__ import annotations

import hashlib
import time

import numpy as np
from pydrake.multibody.inverse_kinematics import AngleBetweenVectorsConstraint
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import SnoptSolver, Solve, SolverOptions
from pydrake.trajectories import BsplineTrajectory, PiecewisePolynomial
from scipy.optimize import minimize

from qmt_drake.config.scenario import GaSettings
from qmt_drake.errors import QmtInputError
from qmt_drake.planners.ga import run_ga
from qmt_drake.planners.spatial_plan_io import SpatialPlan, make_spatial_plan
from qmt_drake.planners.spatial_ruckig import ruckig_rest_to_rest, ruckig_segment_limits
from qmt_drake.planners.spatial_tight import TIGHT_SAMPLES, tight_scales
from qmt_drake.planners.spatial_toppra import joint_path, plan_toppra
from qmt_drake.planners.spatial_trajectory import (
    PolyTrajectory,
    RuckigTrajectory,
    ToppraTrajectory,
    check,
    scale_to_hold,
)
from qmt_drake.problem import Evaluation, MinimumTime

METHODS = ("toppra", "ruckig", "family_optimum", "ga", "trajopt")
ALIASES = {"optimum": "family_optimum"}  # the planar scenarios' name of the family optimum


def _finish(sc, method, traj, pose_times, t0, info) -> SpatialPlan:
    raw = traj.duration_s
    held, k = scale_to_hold(sc, traj, sc.recheck_rate_hz)
    planning_s = time.perf_counter() - t0
    return make_spatial_plan(sc, method, held, np.asarray(pose_times, float) * k, planning_s=planning_s,
                             raw_duration_s=raw, hold_scale=k, info=info)


def plan_toppra_spatial(sc, *, n_grid: int = 1000) -> SpatialPlan:
    t0 = time.perf_counter()
    pp = joint_path(sc.q_path_rad)
    r = plan_toppra(pp, sc.chain, velocity_limit=sc.velocity_limit_rad_s,
                    acceleration_limit=sc.acceleration_limit_rad_s2, terms=sc.terms(), n_grid=n_grid)
    traj = ToppraTrajectory(pp, r["grid"], r["sd"])
    s_poses = np.asarray(pp.get_segment_times())[sc.path_pose_index]
    return _finish(sc, "toppra", traj, traj.time_at(s_poses), t0,
                   {"n_grid": n_grid, "toppra_solve_s": r["planning_s"]})


def _ruckig(sc, qa, qb, factor: float):
    """Ruckig's time-optimal rest-to-rest motion qa -> qb, acceleration and jerk limits times factor."""
    return ruckig_rest_to_rest(qa, qb, *ruckig_segment_limits(sc, factor))


def ruckig_segments(sc, *, rate_hz: float | None = None, iterations: int = 14):
    """Segment by segment (rest to rest between task poses): Ruckig with the joint limits, and where
    the torque/suction check fails, Ruckig again with acceleration and jerk limits times the largest
    factor c in (0, 1] (bisection, `iterations` halvings) whose check holds; (trajectory, factors)."""
    rate = rate_hz or sc.recheck_rate_hz
    segs, factors = [], []
    for qa, qb in zip(sc.q_poses_rad[:-1], sc.q_poses_rad[1:]):
        seg, c = _ruckig(sc, qa, qb, 1.0), 1.0
        if check(sc, RuckigTrajectory([seg]), rate)["max"] > 1.0:
            lo, hi = 0.0, 1.0
            for _ in range(iterations):
                mid = 0.5 * (lo + hi)
                ok = check(sc, RuckigTrajectory([_ruckig(sc, qa, qb, mid)]), rate)["max"] <= 1.0
                lo, hi = (mid, hi) if ok else (lo, mid)
            if lo == 0.0:
                raise QmtInputError("Ruckig: no reduction of the acceleration and jerk limits makes a segment hold "
                                    "its torque and suction limits; relax a limit")
            seg, c = _ruckig(sc, qa, qb, lo), lo
        segs.append(seg)
        factors.append(c)
    return RuckigTrajectory(segs), factors


def plan_ruckig_spatial(sc) -> SpatialPlan:
    t0 = time.perf_counter()
    traj, factors = ruckig_segments(sc)
    return _finish(sc, "ruckig", traj, traj.t_start, t0, {"segments": len(traj.segments),
                                                          "acceleration_jerk_factors": factors})


def via_cubic(sc, T) -> PolyTrajectory:
    T = np.asarray(T, float)
    breaks = np.r_[0.0, np.cumsum(T)]
    zero = np.zeros(sc.n_dof)
    return PolyTrajectory(PiecewisePolynomial.CubicWithContinuousSecondDerivatives(breaks, sc.q_poses_rad.T,
                                                                                   zero, zero))


def tight_time(sc, shares, samples: int = TIGHT_SAMPLES) -> tuple[float, np.ndarray]:
    """(T0, segment times) of the via cubic with these relative segment times at its tight time scale
    (planners/spatial_tight.py: in closed form on `samples` points, as the GA's candidates);
    QmtInputError naming the limit when no time scale makes it hold."""
    w = np.abs(np.asarray(shares, float)) + 1e-6
    T = w / w.sum()
    traj = via_cubic(sc, T)
    k = float(tight_scales(sc, [traj], samples)[0])
    if not np.isfinite(k):
        scale_to_hold(sc, traj, sc.check_rate_hz, k_max=12.0)  # raises naming the limit broken at rest
        raise QmtInputError("no time scale makes the via cubic hold its limits; relax a limit")
    return k, T * k


def plan_family_optimum(sc, *, restarts: int = 1) -> SpatialPlan:
    """Nelder-Mead over the segment-time shares, each share vector at its tight time (`tight_time`),
    from `restarts` starts (shares ~ sqrt of the joint distance, equal shares); the best start's
    evaluations are reported."""
    t0 = time.perf_counter()
    m = len(sc.q_poses_rad) - 1
    d = np.linalg.norm(np.diff(sc.q_poses_rad, axis=0), ord=np.inf, axis=1)
    starts = [np.sqrt(d), np.ones(m)][:restarts]
    best = None
    for x0 in starts:
        r = minimize(lambda x: tight_time(sc, x)[0], x0 / x0.sum(), method="Nelder-Mead",
                     options={"xatol": 1e-5, "fatol": 1e-7, "maxiter": 600})
        if best is None or r.fun < best.fun:
            best = r
    _, T = tight_time(sc, best.x)
    traj = via_cubic(sc, T)
    return _finish(sc, "family_optimum", traj, np.r_[0.0, np.cumsum(T)], t0,
                   {"segment_times_s": T, "evaluations": int(best.nfev)})


TIGHT_BATCH = 50  # candidates per tight_scales call


class SpatialViaProblem:
    """The via-cubic family as a GA Problem (problem.py protocol): genes T1..T_m (s)."""

    def __init__(self, sc, *, upper_s: float = 3.0, fitness_c_per_s: float = 1.0) -> None:
        self.sc = sc
        m = len(sc.q_poses_rad) - 1
        self.name = f"{sc.name} via-cubic"
        self.gene_names = tuple(f"T{i + 1}" for i in range(m))
        self.lower, self.upper = np.full(m, 0.05), np.full(m, upper_s)
        self.objective = MinimumTime(fitness_c_per_s)

    def evaluate(self, genes, exact: bool = False) -> Evaluation:
        G = np.atleast_2d(np.asarray(genes, float))
        viol = np.array([max(check(self.sc, via_cubic(self.sc, g), self.sc.check_rate_hz)["max"] - 1.0, 0.0)
                         for g in G])
        return Evaluation(cost=G.sum(axis=1), violation=viol)

    def fitness(self, ev: Evaluation) -> np.ndarray:
        return self.objective.fitness(ev)

    def confirm(self, genes) -> bool:
        return check(self.sc, via_cubic(self.sc, genes), self.sc.recheck_rate_hz)["max"] <= 1.0

    def fingerprint(self) -> str:
        data = np.r_[self.sc.q_poses_rad.ravel(), self.lower, self.upper]
        return hashlib.sha256(data.tobytes() + self.sc.name.encode()).hexdigest()[:16]


class SpatialTightViaProblem(SpatialViaProblem):
    """The via-cubic family with every candidate played at its tight time scale (planners/spatial_tight.py,
    as the planar GA's ga.tight_timing): the genes T1..T_m give the shape (their shares), the cost is the
    tight duration k * sum(T), so the GA searches shapes and never the feasibility boundary."""

    def __init__(self, sc, *, samples: int = TIGHT_SAMPLES, **kwargs) -> None:
        super().__init__(sc, **kwargs)
        self.samples = samples
        self.name += " (tight timing)"

    def scales(self, G) -> np.ndarray:
        # in batches: each trajectory's scale is its own (the same to the bit in any batch), and one batch of
        # a whole population held ~4 MB a candidate (16 GiB at 4000); batches of 50 are also faster (cache)
        G = np.atleast_2d(G)
        return np.concatenate([tight_scales(self.sc, [via_cubic(self.sc, g) for g in G[i:i + TIGHT_BATCH]],
                                            self.samples) for i in range(0, len(G), TIGHT_BATCH)] or [np.zeros(0)])

    def evaluate(self, genes, exact: bool = False) -> Evaluation:
        G = np.atleast_2d(np.asarray(genes, float))
        k = self.scales(G)
        ok = np.isfinite(k)
        return Evaluation(cost=np.where(ok, k * G.sum(axis=1), np.inf), violation=np.where(ok, 0.0, np.inf))

    def realize(self, genes) -> np.ndarray:
        """The segment times (s) of the tight motion of `genes`."""
        g = np.asarray(genes, float)
        return g * self.scales(g)[0]

    def confirm(self, genes) -> bool:  # the plan is held at the re-check rate by _finish's scale_to_hold
        return bool(np.isfinite(self.scales(genes)[0]))

    def fingerprint(self) -> str:
        return super().fingerprint() + f":tight{self.samples}"


def plan_ga_spatial(sc, *, seed: int = 0, generations: int = 150, population: int = 40, stall: int = 60,
                    tight_timing: bool = True, progress=None) -> SpatialPlan:
    """The binary GA (planners/ga.run_ga) on the via-cubic segment times; tight_timing plays every
    candidate at its tight time scale (SpatialTightViaProblem), else a candidate is feasible or not
    as its genes give it (the thesis's GA: it must find the feasibility boundary itself)."""
    t0 = time.perf_counter()
    problem = SpatialTightViaProblem(sc) if tight_timing else SpatialViaProblem(sc)
    settings = GaSettings(population=population, max_generations=generations, stall_generations=stall,
                          fitness_c_per_s=1.0, selection="tournament", encoding="gray", tight_timing=tight_timing)
    res = run_ga(problem, settings, seed=seed, progress=progress)
    if not res.feasible:
        raise QmtInputError(f"the GA found no via-cubic within the limits in {res.generations} generations; "
                            "give it more generations or relax a limit")
    T = problem.realize(res.genes) if tight_timing else np.asarray(res.genes, float)
    return _finish(sc, "ga", via_cubic(sc, T), np.r_[0.0, np.cumsum(T)], t0,
                   {"segment_times_s": T, "generations": res.generations, "evaluations": res.evaluations,
                    "seed": seed, "tight_timing": tight_timing})


def plan_trajopt_spatial(sc, *, control_points: int = 16, point_fractions=None, max_tilt_rad: float = 0.02,
                         tilt_samples: int = 40) -> SpatialPlan:
    t0 = time.perf_counter()
    Q, n = sc.q_path_rad, sc.n_dof
    if point_fractions is None:
        d = np.linalg.norm(np.diff(Q, axis=0), axis=1)
        point_fractions = np.r_[0.0, np.cumsum(d)] / d.sum()
    s = np.asarray(point_fractions, float)
    to = KinematicTrajectoryOptimization(n, control_points, 4)
    to.AddDurationCost(1.0)
    to.AddPositionBounds(sc.plant.GetPositionLowerLimits(), sc.plant.GetPositionUpperLimits())
    to.AddVelocityBounds(-sc.velocity_limit_rad_s, sc.velocity_limit_rad_s)
    to.AddAccelerationBounds(-sc.acceleration_limit_rad_s2, sc.acceleration_limit_rad_s2)
    to.AddJerkBounds(-sc.jerk_limit_rad_s3, sc.jerk_limit_rad_s3)
    to.AddDurationConstraint(0.05, 60.0)
    for sk, qk in zip(s, Q):
        to.AddPathPositionConstraint(qk, qk, sk)
    for sk in (0.0, 1.0):
        to.AddPathVelocityConstraint(np.zeros(n), np.zeros(n), sk)
        to.AddPathAccelerationConstraint(np.zeros(n), np.zeros(n), sk)
    if max_tilt_rad is not None:  # the face normal within max_tilt_rad of the task's at tilt_samples points
        ctx = sc.plant.CreateDefaultContext()
        tilt = AngleBetweenVectorsConstraint(sc.plant, sc.plant.world_frame(), sc.face_normal, sc.ik.hand,
                                             sc.ik.face_axis, 0.0, max_tilt_rad, ctx)
        for sk in np.linspace(0.0, 1.0, tilt_samples):
            to.AddPathPositionConstraint(tilt, sk)
    u = np.linspace(0.0, 1.0, control_points)
    guess = [np.array([np.interp(x, s, Q[:, j]) for j in range(n)]).reshape(n, 1) for x in u]
    to.SetInitialGuess(BsplineTrajectory(to.basis(), guess))
    opts = SolverOptions()
    opts.SetOption(SnoptSolver.id(), "Major feasibility tolerance", 1e-10)
    res = Solve(to.get_mutable_prog(), None, opts)
    if not res.is_success():
        raise QmtInputError(f"trajopt found no trajectory through the task poses ({res.get_solution_result()}); "
                            "give it more control points or relax a limit")
    bs = to.ReconstructTrajectory(res)
    traj = PolyTrajectory(bs)
    return _finish(sc, "trajopt", traj, s[sc.path_pose_index] * traj.duration_s, t0,
                   {"control_points": control_points, "solver": res.get_solver_id().name(),
                    "point_fractions": s})


PLANNERS = {"toppra": plan_toppra_spatial, "ruckig": plan_ruckig_spatial,
            "family_optimum": plan_family_optimum, "ga": plan_ga_spatial, "trajopt": plan_trajopt_spatial}


def plan_all(sc, methods=METHODS) -> dict:
    return {m: PLANNERS[m](sc) for m in methods}
