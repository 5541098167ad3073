"""Seed 001's energy-time cost on the other arms (issue 27 item 6: "the energy-time cost (c1 tau'tau + c2) dt
needs only joint torques, which every arm has"): `qmt-drake plan thesis-ch4 | crane-tray | ur5-suction-bins |
ur5-magnet-part | panda-tray-cup --method snopt|ipopt|steepest [--c1 C1 --c2 C2 --max-iter N]`.

    minimise  z(x) = integral_0^T (c1 tau(t)'tau(t) + c2) dt     [N^2 m^2 s]
    over      x = the genes of a family every arm of the kind has: on a spatial arm the via cubic's segment
              times (planners/spatial_families.ViaCubicFamily: the joint-space cubic through the scenario's
              IK'd task poses, at rest at both ends); on a planar magnet or tray arm the scenario's own
              family (its YAML `family`, gene box and all: thesis-ch4's via cubic T1..T3, crane-tray's T1, T2)
    subject to every limit column of the kind's re-check <= 1 at CON_SAMPLES fixed fractions of the motion's
              time (spatial: limits/spatial_columns, joint range, speed, acceleration, torque and the hand's
              term; planar: the scenario's LimitSet columns, the magnet's moment or the tray's terms, motor
              torques, joint speed; a joint-range column, an excess in rad, <= 0), and the gene box.

tau are the joint torques the drives deliver, gravity, the carried part and the reflected rotor inertia
included (the kind's own model, the one its torque limit is checked on). z is the trapezoid rule on SAMPLES
points evenly spaced in time. Seed 001's weights are the defaults (c1 = 1, c2 = 1e5); --c1 / --c2 change them
(energy/objective.check_weights: both > 0).

One start: the family's tight timing (the smallest slow-down at which it holds: planners/spatial_tight on a
spatial arm, planners/optimum.tight_scale on a planar one) of a default shape (spatial: segment times as the
square roots of the joint moves; planar: the middle of the gene box), played START_SLOWDOWN times slower.
- snopt / ipopt: Drake's MathematicalProgram, cost and constraints as callbacks with central finite-difference
  gradients (relative step FD_STEP; the genes are a few seconds and every column is smooth in them; a single
  max-ratio constraint, kinked where the binding sample switches, took SNOPT 10 min), SNOPT or IPOPT.
- steepest: seed 001's steepest descent with a restoration step (as energy/steepest.py restores the end
  point): x <- x - a grad z, then, where the motion breaks a limit, the motion slowed by its tight scale; the
  step a halved until z decreases (Armijo, 1e-4), doubled after a success; stops when no step decreases z,
  when the relative decrease is below 1e-10, or after max_iter steps. The uniform slow-down moves along the
  time direction only, so on an active limit it stops short of the NLPs' optimum (a few per cent in z).
The result is re-checked as every plan of its kind: a spatial plan by spatial_search.finish_or_least_violating
(10x the check rate, slowed by the smallest factor that makes the fine re-check hold; none: the least-violating
plan, exit 3), a planar one by plan.family_plan (its check rate), slowed by the first of HOLD_STEPS that makes
it hold (none: not feasible, exit 3). Its info / extra has c1, c2, z, the energy integral, the start's z and
the solver's status. `collocation` on these kinds is energy/collocation_kinds.py (the same cost and limit rows on
a free joint path, started from this module's SNOPT optimum).
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.solvers import IpoptSolver, MathematicalProgram, SnoptSolver, SolverOptions

from qmt_drake.energy.nlp import _ad_wrap
from qmt_drake.energy.objective import check_weights, energy_time_cost, trapezoid_weights
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.spatial_columns import SpatialColumns
from qmt_drake.plan import family_plan
from qmt_drake.planners.optimum import tight_scale
from qmt_drake.planners.spatial_families import spatial_family
from qmt_drake.planners.spatial_search import finish_or_least_violating, tight_time
from qmt_drake.planners.spatial_tight import TIGHT_SAMPLES, tight_scales
from qmt_drake.problem import PlanningProblem

SAMPLES = 400  # cost quadrature points over the motion
WEIGHTS = trapezoid_weights(SAMPLES)  # the cost's quadrature on SAMPLES equally spaced times
CON_SAMPLES = 200  # constraint points of the NLPs (the result is then held at the re-check's 10x rate)
FD_STEP = 1e-6  # central differences: relative step on each segment time
START_SLOWDOWN = 1.5
PAPER_C1, PAPER_C2 = 1.0, 1e5  # seed 001's weights (models/scenarios/ohsaka-fig3.yaml)
SOLVERS = ("snopt", "ipopt", "steepest")
HOLD_STEPS = (1.0001, 1.001, 1.01, 1.1)  # the planar plan's slow-downs until its fine re-check holds


class EnergyTimeOnFamily:
    """z(x), the constraint rows and the restoration of one scenario's family (module docstring); a kind
    supplies its family's motion, its torques, its ratio columns and its tight scale."""

    lower: np.ndarray
    upper: np.ndarray

    def __init__(self, c1: float, c2: float) -> None:
        check_weights(c1, c2)
        self.c1, self.c2 = float(c1), float(c2)

    def motion(self, x, fractions) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """(T [s], q, qd, qdd) of member x at these fractions of its time."""
        raise NotImplementedError

    def joint_torques(self, q, qd, qdd) -> np.ndarray:
        raise NotImplementedError

    def column_ratios(self, q, qd, qdd) -> np.ndarray:
        """(S, M) the kind's limit columns, each <= 1 where it holds."""
        raise NotImplementedError

    def scale(self, x) -> float:
        """The smallest time scale (slow-down factor) at which x holds its limits; inf: none."""
        raise NotImplementedError

    def slowed(self, x, k: float) -> np.ndarray:
        """The genes of x played k times slower."""
        raise NotImplementedError

    def start(self) -> np.ndarray:
        raise NotImplementedError

    def torques(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(t [s], tau (S, n) [N m]) of the family member x on SAMPLES points."""
        T, q, qd, qdd = self.motion(x, np.linspace(0.0, 1.0, SAMPLES))
        return np.linspace(0.0, T, SAMPLES), self.joint_torques(q, qd, qdd)

    def energy(self, x) -> float:
        """integral tau'tau dt [N^2 m^2 s] (objective.energy_time_cost, trapezoid)."""
        t, tau = self.torques(x)
        return energy_time_cost(tau, t[-1], 1.0, 0.0, WEIGHTS)

    def z(self, x) -> float:
        t, tau = self.torques(x)
        return energy_time_cost(tau, t[-1], self.c1, self.c2, WEIGHTS)

    def ratios(self, x) -> np.ndarray:
        """(CON_SAMPLES * M,) every ratio column of the re-check at CON_SAMPLES fixed fractions of the
        motion's time: the NLP's constraints, each smooth in x."""
        _, q, qd, qdd = self.motion(x, np.linspace(0.0, 1.0, CON_SAMPLES))
        return self.column_ratios(q, qd, qdd).ravel()

    def gradient(self, f, x) -> np.ndarray:
        """d f / d x by central differences ((m,) for a scalar f, (K, m) for a vector f)."""
        x = np.asarray(x, float)
        cols = []
        for i in range(x.size):
            h = FD_STEP * max(abs(x[i]), 1e-3)
            e = np.zeros_like(x)
            e[i] = h
            cols.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h))
        return np.stack(cols, axis=-1)


class SpatialEnergyTime(EnergyTimeOnFamily):
    """A spatial scenario's via-cubic family (segment times)."""

    def __init__(self, sc, c1: float, c2: float) -> None:
        super().__init__(c1, c2)
        self.sc = sc
        self.family = spatial_family(sc, "via_cubic")
        self.lower, self.upper = self.family.lower, self.family.upper
        self.columns = SpatialColumns(sc)

    def motion(self, x, fractions):
        traj = self.family.trajectory(np.asarray(x, float))
        return (traj.duration_s, *traj.sample(np.asarray(fractions) * traj.duration_s))

    def joint_torques(self, q, qd, qdd):
        return self.sc.chain.evaluate(q, qd, qdd).joint_torque_Nm

    def column_ratios(self, q, qd, qdd):
        return self.columns.columns(q, qd, qdd)

    def scale(self, x) -> float:
        return float(tight_scales(self.sc, [self.family.trajectory(np.asarray(x, float))], TIGHT_SAMPLES)[0])

    def slowed(self, x, k: float) -> np.ndarray:
        return np.asarray(x, float) * k

    def start(self) -> np.ndarray:
        d = np.linalg.norm(np.diff(self.sc.q_poses_rad, axis=0), ord=np.inf, axis=1)
        return np.clip(tight_time(self.sc, np.sqrt(d))[1] * START_SLOWDOWN, self.lower, self.upper)


class PlanarEnergyTime(EnergyTimeOnFamily):
    """A transfer (planar magnet, tray) scenario's family (its YAML family and gene bounds)."""

    def __init__(self, problem: PlanningProblem, c1: float, c2: float) -> None:
        super().__init__(c1, c2)
        self.problem, self.family = problem, problem.family
        self.lower, self.upper = problem.lower, problem.upper
        ls = problem.limit_set
        self.ub = np.where(ls.ratio_mask, 1.0, 0.0)  # a ratio column <= 1; joint-range excess [rad] <= 0

    def motion(self, x, fractions):
        T = float(self.family.motion_time_s(np.atleast_2d(x))[0])
        return (T, *self.family.sample(x, np.asarray(fractions) * T))

    def joint_torques(self, q, qd, qdd):
        return self.problem.arm.hand_state(q, qd, qdd).joint_torque_Nm

    def column_ratios(self, q, qd, qdd):
        c = self.problem.limit_set.columns(q, qd, qdd)
        return c + (1.0 - self.ub)  # the joint-range columns shifted so that every column holds at <= 1

    def scale(self, x) -> float:
        k = float(tight_scale(self.problem, np.atleast_2d(x))[0])
        return k if np.isfinite(k) else np.inf

    def slowed(self, x, k: float) -> np.ndarray:
        return self.family.time_scaled(x, k)[0]

    def start(self) -> np.ndarray:
        mid = 0.5 * (self.lower + self.upper)
        k = self.scale(mid)
        if not np.isfinite(k):
            raise QmtInputError(f"{self.problem.name}: the middle of the family's gene box holds no limit at any "
                                "speed; nothing to start the energy-time solvers from")
        return np.clip(self.slowed(mid, k * START_SLOWDOWN), self.lower, self.upper)


def _solve_program(P: EnergyTimeOnFamily, x0, solver: str, max_iter: int) -> tuple[np.ndarray, bool, str]:
    prog = MathematicalProgram()
    x = prog.NewContinuousVariables(len(x0), "T")
    s = 1.0 / P.c2  # z / c2: seconds plus (c1/c2) energy, near unit scale

    def cost(v):
        return P.z(v) * s, P.gradient(P.z, v) * s

    def limit(v):
        return P.ratios(v), P.gradient(P.ratios, v)

    prog.AddCost(_ad_wrap(cost), vars=x)
    n_rows = P.ratios(x0).size
    prog.AddConstraint(_ad_wrap(limit), lb=np.full(n_rows, -np.inf), ub=np.ones(n_rows), vars=x)
    prog.AddBoundingBoxConstraint(P.lower, P.upper, x)
    opts = SolverOptions()
    if solver == "snopt":
        sol = SnoptSolver()
        opts.SetOption(sol.solver_id(), "Major optimality tolerance", 1e-7)
        opts.SetOption(sol.solver_id(), "Major feasibility tolerance", 1e-9)
        opts.SetOption(sol.solver_id(), "Major iterations limit", int(max_iter))
    else:
        sol = IpoptSolver()
        opts.SetOption(sol.solver_id(), "tol", 1e-7)
        opts.SetOption(sol.solver_id(), "print_level", 0)
        opts.SetOption(sol.solver_id(), "max_iter", int(max_iter))
    if not sol.available():
        raise QmtInputError(f"{solver} is not available in this Drake build; use --method steepest")
    r = sol.Solve(prog, np.asarray(x0, float), opts)
    return np.asarray(r.GetSolution(x), float), bool(r.is_success()), str(r.get_solution_result())


def _restore(P: EnergyTimeOnFamily, x) -> np.ndarray:
    """x slowed until it holds (k <= 1)."""
    k = P.scale(x)
    return np.clip(P.slowed(x, k), P.lower, P.upper) if 1.0 < k < np.inf else x


def _steepest(P: EnergyTimeOnFamily, x0, max_iter: int) -> tuple[np.ndarray, bool, str]:
    x, z = np.asarray(x0, float), P.z(x0)
    a = 1e-2 * float(np.mean(x)) / max(float(np.linalg.norm(P.gradient(P.z, x))), 1e-300)
    for it in range(max_iter):
        g = P.gradient(P.z, x)
        while a > 1e-16:
            y = _restore(P, np.clip(x - a * g, P.lower, P.upper))
            holds = P.scale(y) <= 1.0 + 1e-9  # a step no slow-down within the gene box restores is refused
            zy = P.z(y) if holds else np.inf
            if np.isfinite(zy) and zy <= z - 1e-4 * a * float(g @ g) or (zy < z and a < 1e-12):
                break
            a *= 0.5
        else:
            return x, False, f"stopped: no decreasing step (an active limit) after {it} iterations"
        if (z - zy) <= 1e-10 * abs(z):
            return y, True, f"converged: relative decrease below 1e-10 after {it + 1} iterations"
        x, z, a = y, zy, 2.0 * a
    return x, False, f"stopped at max_iter = {max_iter}"


def _solve(P: EnergyTimeOnFamily, method: str, max_iter: int, where: str) -> tuple[np.ndarray, dict]:
    """(genes that hold on the samples, info) of `method` on P from P.start()."""
    if method not in SOLVERS:
        raise QmtInputError(f"method {method!r}: the energy-time planners of this kind are {'|'.join(SOLVERS)}")
    x0 = P.start()
    if method == "steepest":
        x, ok, status = _steepest(P, x0, max_iter)
    else:
        x, ok, status = _solve_program(P, x0, method, max_iter)
    x = np.clip(x, P.lower, P.upper)
    if not np.isfinite(P.scale(x)):
        raise QmtInputError(f"{where}: {method} ended at genes {np.round(x, 4).tolist()} that no time scale makes "
                            "hold; a bug or a limit broken at rest")
    x = _restore(P, x)  # a solver's last iterate may sit a hair outside the limits
    return x, {"objective": "energy_time", "c1": P.c1, "c2": P.c2, "z": P.z(x),
               "energy_integral_N2m2s": P.energy(x), "start_z": P.z(x0), "solver_status": status, "converged": ok}


def plan_energy_time_spatial(sc, *, method: str, c1: float = PAPER_C1, c2: float = PAPER_C2,
                             max_iter: int = 200):
    """The energy-time optimum of spatial scenario sc (module docstring) by `method` (snopt | ipopt |
    steepest): its SpatialPlan, re-checked."""
    t0 = time.perf_counter()
    P = SpatialEnergyTime(sc, c1, c2)
    x, info = _solve(P, method, max_iter, sc.name)
    fam = P.family
    info.update(family="via_cubic", genes=dict(zip(fam.gene_names, x)), segment_times_s=fam.segment_times(x))
    return finish_or_least_violating(sc, method, fam.trajectory(x), fam.pose_times(x), t0, info)


def plan_energy_time_transfer(scenario, *, method: str, c1: float = PAPER_C1, c2: float = PAPER_C2,
                              max_iter: int = 200):
    """The energy-time optimum of a transfer scenario (planar magnet, tray) over its family's genes by
    `method`: its Plan, re-checked at the scenario's check rate; where that fine re-check fails, slowed by
    the smallest of HOLD_STEPS factors that makes it hold (none: the plan as solved, not feasible: exit 3)."""
    t0 = time.perf_counter()
    problem = PlanningProblem(scenario)
    P = PlanarEnergyTime(problem, c1, c2)
    x, info = _solve(P, method, max_iter, scenario.name)
    plan = family_plan(problem, x, method, planner_wall_s=time.perf_counter() - t0, extra=info)
    for k in HOLD_STEPS:
        if plan.feasible:
            break
        y = np.clip(P.slowed(x, k), P.lower, P.upper)
        plan = family_plan(problem, y, method, planner_wall_s=time.perf_counter() - t0,
                           extra={**info, "hold_scale": k, "z": P.z(y), "energy_integral_N2m2s": P.energy(y)})
    return plan
