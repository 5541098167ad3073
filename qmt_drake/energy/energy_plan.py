"""Seed 001's result as a Plan: the best local optimum's Fourier trajectory (fourier.py) in the one
plan.Plan, of the energy-time kind (`EnergyPlan` builds it; its facts: problem, x, costs, optima,
end), and the energy-time plan.PlanKind registered here: its summary, file and CSV, and
plan_files.load_plan reading its file back.

`plan_energy_time(E, method)` runs the multi-start of `qmt-drake plan ohsaka-fig3 --method M`: one
solve per rotation-direction start (8, or the given pattern; Fig. 2: the paper's one start) with
snopt | ipopt | steepest | collocation, and returns the lowest cost z among the converged optima
(`feasible`: it converged; with none converged, the lowest z of all, not feasible). Every start's
record stays in `optima`.

The file keeps every key the energy-time file had (`kind: energy_time`, scenario, method, c1, c2,
m, divisions, theta0_deg, X0, XT, optima, and `plan` {family, theta0_rad, m, x, motion_time_s, z,
z_fine, fine_divisions, end} when an optimum converged) plus the Plan's (`scenario_kind`,
feasible, motion_time_s, cost_z, energy_integral_N2m2s, ...) and `trajectory` {kind:
fourier_velocity, theta0_rad, m, x}: the genes, written exactly (repr floats), which rebuild the
trajectory. Loading checks the file against the experiment: same name and start posture (1e-9
rad), and an end posture whose tip lies on the experiment's goal X(T) (END_TOL_M by the planar
forward kinematics); z and the energy are recomputed, not read. The CSV: t [s], q [rad], qd
[rad/s], qdd [rad/s^2] and tau [N m] (inverse dynamics with gravity, the cost's torques).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from qmt_drake.energy.collocation import solve_collocation
from qmt_drake.energy.dynamics import inverse_dynamics_with_gravity
from qmt_drake.energy.experiments import Experiment, paper_initial_x
from qmt_drake.energy.fourier import FourierTrajectory
from qmt_drake.energy.kinematics import tip_position
from qmt_drake.energy.multistart import (
    PATTERNS,
    initial_end_posture,
    initial_reduced_genes,
    pattern_str,
    travel_pattern,
)
from qmt_drake.energy.nlp import solve_nlp
from qmt_drake.energy.objective import FINE_DIVISIONS
from qmt_drake.energy.problem import EnergyProblem
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.energy.steepest import restore_endpoint, steepest_descent
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.plan import ENERGY_PLAN_KIND, Plan, ratio_report, register_plan_kind
from qmt_drake.plan_identity import (
    IDENTITY_KEY,
    check_identity,
    differ_note,
    differing_sections,
    energy_sections,
    identity,
)

METHODS = ("snopt", "ipopt", "steepest", "collocation")
END_TOL_M = 1e-6  # the plan's end tip on the experiment's X(T) [m]


def EnergyPlan(*, scenario: Experiment, method: str, trajectory: FourierTrajectory, check,  # noqa: N802
               problem: EnergyProblem, optima=(), cost_z: float, cost_z_fine: float, energy_integral_N2m2s: float, end: str,
               **plan_fields) -> Plan:
    """The one Plan of an energy-time scenario (the name stays for callers; no subclass): `scenario` the
    Experiment, `trajectory` the optimum's FourierTrajectory. Its facts: `problem` the EnergyProblem it
    was planned on (weights c1, c2, Fourier terms m, divisions), `x` the paper's trajectory vector
    (a_ij, b_ij, T), cost_z = integral (c1 tau'tau + c2) dt on the problem's grid, cost_z_fine on
    FINE_DIVISIONS, energy_integral_N2m2s = integral tau'tau dt [N^2 m^2 s], optima every start's
    record, end the travel pattern. `feasible`: the solver converged (the paper states no limit)."""
    facts = {"problem": problem, "x": np.asarray(trajectory.x, float), "optima": list(optima),
             "cost_z": float(cost_z), "cost_z_fine": float(cost_z_fine),
             "energy_integral_N2m2s": float(energy_integral_N2m2s), "end": str(end)}
    return Plan(scenario=scenario, method=method, trajectory=trajectory, check=check,
                scenario_kind=ENERGY_PLAN_KIND, facts=facts, **plan_fields)


def plan_block(plan: Plan) -> dict:
    """The `plan` block `simulate --plan` has always read (theta0_rad, m, x, ...)."""
    P = plan.problem
    return {"family": "fourier_velocity", "theta0_rad": P.theta0, "m": P.m, "x": plan.x,
            "motion_time_s": plan.motion_time_s, "z": plan.cost_z, "z_fine": plan.cost_z_fine,
            "fine_divisions": FINE_DIVISIONS, "end": plan.end}


def energy_summary(plan: Plan) -> dict:
    """An energy-time plan's CLI keys: the common ones, its costs, weights and every start's optimum."""
    P = plan.problem
    d = {"kind": ENERGY_PLAN_KIND, "scenario": plan.scenario.name, "scenario_kind": plan.scenario_kind,
         "method": plan.method, "feasible": plan.feasible, "motion_time_s": plan.motion_time_s,
         "cost_z": plan.cost_z, "cost_z_fine": plan.cost_z_fine,
         "energy_integral_N2m2s": plan.energy_integral_N2m2s, "end": plan.end,
         "planner_wall_s": plan.planner_wall_s, "c1": P.c1, "c2": P.c2, "m": P.m,
         "divisions": P.divisions, "theta0_deg": np.degrees(P.theta0), "X0": P.X0, "XT": P.XT,
         "optima": plan.optima}
    if plan.feasible:
        d["plan"] = plan_block(plan)
    return d


def _energy_file_dict(plan: Plan) -> dict:
    P = plan.problem
    src = plan.scenario.source_path
    return jsonable({**energy_summary(plan), "scenario_path": None if src is None else str(src), "n_dof": plan.n_dof,
                     "extra": plan.extra, "trajectory": {"kind": "fourier_velocity", "theta0_rad": P.theta0,
                                                         "m": P.m, "x": plan.x},
                     IDENTITY_KEY: identity(energy_sections(plan.scenario))})


def _energy_csv(plan: Plan, path, rate_hz: float) -> None:
    write_energy_csv(path, plan.problem, plan.x, rate_hz)


def make_energy_plan(E: Experiment, P: EnergyProblem, method: str, x, converged: bool, *, optima=(),
                     planner_wall_s: float = 0.0, extra: dict | None = None) -> Plan:
    """The EnergyPlan of trajectory vector x on P: z, its fine-grid value and the energy computed here."""
    x = np.asarray(x, float)
    T = float(x[-1])
    return EnergyPlan(scenario=E, method=method, trajectory=FourierTrajectory(P.family, x),
                      # no limit terms; the cost's fine grid is the sampling it was measured on
                      check=ratio_report(FINE_DIVISIONS / T, T, {}, feasible=converged),
                      planner_wall_s=float(planner_wall_s), extra=dict(extra or {}), problem=P,
                      optima=list(optima), cost_z=float(P.objective.value(x)),
                      cost_z_fine=float(P.with_divisions(FINE_DIVISIONS).value(x)),
                      energy_integral_N2m2s=float(P.objective.energy_integral(x)),
                      end=pattern_str(travel_pattern(P.theta0, P.family.end_posture(x))))


def plan_energy_time(E: Experiment, method: str = "snopt", *, c1: float | None = None, c2: float | None = None,
                     m: int | None = None, divisions: int | None = None, coords=None, pattern=None,
                     max_iter: int | None = None, progress: Callable[[str], None] | None = None,
                     on_optimum: Callable[[dict], None] | None = None) -> Plan:
    """Seed 001's multi-start on experiment E (module docstring). c1, c2, m, divisions: override the
    experiment's weights, Fourier terms and time divisions; coords: X1(0) X2(0) X1(T) X2(T) [m];
    pattern: one start as signs, e.g. (-1, 1, -1) (default all 8); max_iter: steepest's cap (20000);
    progress: a callable taking one line; on_optimum: called with each start's record as it ends."""
    if method not in METHODS:
        raise QmtInputError(f"method {method!r} does not plan energy-time scenarios; use {'|'.join(METHODS)}")
    over = {k: v for k, v in (("c1", c1), ("c2", c2), ("m", m), ("divisions", divisions)) if v is not None}
    if coords is not None:
        over["X0"], over["XT"] = list(coords)[:2], list(coords)[2:]
    max_iter = 20000 if max_iter is None else max_iter
    if max_iter < 1:
        raise QmtInputError(f"--max-iter {max_iter} must be >= 1")
    P = E.problem(**over)  # validates every input before any solve
    starts = PATTERNS if pattern is None else (tuple(pattern),)
    if E.moving_joints is not None or E.fixed_T_s is not None:
        starts = (None,)  # Fig. 2: one start, the paper's (a, b = 0, then step III)
    out, t0 = [], time.perf_counter()
    for k, p in enumerate(starts):
        if progress:
            progress(f"qmt-drake: {E.name} {method}: start {k + 1} of {len(starts)}")
        out.append(_solve_one(E, P, method, p, max_iter))
        if on_optimum:
            on_optimum(out[-1])
    good = [r for r in out if r["success"]]
    best = min(good or out, key=lambda r: r["z"] if np.isfinite(r["z"]) else np.inf)
    return make_energy_plan(E, P, method, best["x"], bool(good), optima=out,
                            planner_wall_s=time.perf_counter() - t0)


def _solve_one(E: Experiment, P: EnergyProblem, method: str, p, max_iter: int) -> dict:
    """One start (a sign pattern, or None: the paper's Fig. 2 start) solved by `method`: its record."""
    if p is None:
        x0 = restore_endpoint(P, paper_initial_x(P, E.paper_initial_a, E.fixed_T_s or E.T_init_s))
        y0 = P.family.full_to_reduced(x0)
    else:
        y0 = initial_reduced_genes(P, initial_end_posture(P, p), E.T_init_s)
        x0 = P.family.reduced_to_full(y0)[0]
    rec: dict = {"start": pattern_str(p) if p else "paper"}
    if method == "steepest":
        r = steepest_descent(P, x0, max_iter=max_iter)
        x, z, ok = r.x, r.z, r.converged
        rec.update(iterations=r.iterations, stop=r.stop_reason, wall_s=r.wall_s)
    else:
        s = solve_nlp(P, y0, "snopt" if method == "collocation" else method)
        x, z, ok = s.x, s.z, s.success
        rec.update(evaluations=s.evaluations, wall_s=s.wall_s, status=s.status)
        if method == "collocation":
            c = solve_collocation(P, x)
            rec.update(fourier_z=z, collocation_z=c.z, collocation_z_resampled=c.z_resampled,
                       collocation_T_s=c.T_s, collocation_status=c.status, collocation_wall_s=c.wall_s)
            ok = ok and c.success
    rec.update(z=z, T_s=float(x[-1]), success=ok, end=pattern_str(travel_pattern(P.theta0, P.family.end_posture(x))),
               thetaT_deg=np.degrees(P.family.end_posture(x)), genes=dict(zip(P.family.gene_names(), x)),
               energy=P.objective.energy_integral(x), x=x)
    return rec


def write_energy_csv(path, problem: EnergyProblem, x, rate_hz: float = 1000.0) -> None:
    """The plan x sampled at rate_hz (at least 2001 samples): t [s], q_i [rad], qd_i [rad/s],
    qdd_i [rad/s^2], tau_i [N m] (inverse dynamics with gravity, the cost's torques). Atomic."""
    T = float(x[-1])
    t = np.linspace(0.0, T, max(int(np.ceil(T * rate_hz)) + 1, 2001))
    q, qd, qdd = problem.family.sample(x, t)
    tau = inverse_dynamics_with_gravity(q, qd, qdd, problem.arm, derivatives=False)
    n = q.shape[1]
    head = ["t_s"] + [f"{k}{i + 1}{u}" for k, u in (("q", "_rad"), ("qd", "_rad_s"), ("qdd", "_rad_s2"),
                                                     ("tau", "_Nm")) for i in range(n)]
    rows = np.column_stack([t, q, qd, qdd, tau])
    write_text_atomic(path, ",".join(head) + "\n" + "\n".join(",".join(f"{v:.17g}" for v in r) for r in rows) + "\n")


def _load(path: Path, d: dict, E: Experiment | None) -> Plan:
    """plan.load_plan's loader of energy-time files (module docstring); E None: the file's experiment."""
    if E is None:
        src = d.get("scenario_path")
        E = get_experiment(src if isinstance(src, str) and Path(src).is_file() else str(d["scenario"]))
    again = f"plan this scenario first (`qmt-drake plan {E.name} --json PATH`)"
    traj = d.get("trajectory") if isinstance(d.get("trajectory"), dict) else d.get("plan")  # older files: `plan`
    if not isinstance(traj, dict):
        raise QmtInputError(f"plan file {path} holds no converged optimum of {d.get('scenario')}; {again}")
    P0 = E.problem()
    try:
        theta0 = np.asarray(traj["theta0_rad"], float)
        same_start = theta0.shape == P0.theta0.shape and np.allclose(theta0, P0.theta0, atol=1e-9, rtol=0)
    except (KeyError, TypeError, ValueError):
        raise QmtInputError(f"plan file {path}: its trajectory has no start posture theta0_rad; {again}") from None
    differ = differing_sections(d, energy_sections(E))  # content decides, whatever the names say
    if (differ != [] and d.get("scenario") != E.name) or not same_start:
        why = differ_note(differ) if d.get("scenario") != E.name else " (other start posture)"
        raise QmtInputError(f"plan file {path} was made for {d.get('scenario')!r}, not {E.name!r}{why}; {again}")
    check_identity(d, path, energy_sections(E), E.name)  # the same name, other content
    try:
        x = np.asarray(traj["x"], float)
        m = traj["m"]
        P = E.problem(**{k: d[k] for k in ("c1", "c2", "divisions") if k in d}, m=m)
        if x.shape != (P.family.n_genes,) or not np.all(np.isfinite(x)) or not x[-1] > 0:
            raise ValueError(f"x must be {P.family.n_genes} finite genes ending with a positive T")
    except QmtInputError as exc:
        raise QmtInputError(f"plan file {path}: {exc}") from None
    except (KeyError, TypeError, ValueError) as exc:
        raise QmtInputError(f"plan file {path}: cannot rebuild its trajectory ({exc}); {again}") from None
    miss = float(np.linalg.norm(tip_position(P.arm, P.family.end_posture(x)) - P.XT))
    if miss > END_TOL_M:
        raise QmtInputError(f"plan file {path} ends {miss * 1e3:.3g} mm away from {E.name}'s goal X(T); {again}")
    feasible = bool(d.get("feasible", "plan" in d))  # the solver's convergence, as the file reports it
    extra = d.get("extra") if isinstance(d.get("extra"), dict) else {}
    wall = d.get("planner_wall_s", 0.0)
    return make_energy_plan(E, P, str(d.get("method", "loaded")), x, feasible,
                            optima=d.get("optima") if isinstance(d.get("optima"), list) else [],
                            planner_wall_s=wall if isinstance(wall, (int, float)) else 0.0, extra=extra)


register_plan_kind(ENERGY_PLAN_KIND, Experiment, _load, summary=energy_summary, file_dict=_energy_file_dict,
                   write_csv=_energy_csv)
