"""Seed 001 behind the one CLI: `qmt-drake plan ohsaka-fig3 --method snopt|steepest|ipopt|collocation`
and `qmt-drake simulate ohsaka-fig3 --plan p.json` (apps/cli.py routes energy-time scenarios here).

`add_energy_options(parser)` adds the energy-time options to `plan`; `plan_energy(args)` runs it:
SCENARIO is one of the built-in experiments (ohsaka-fig2, ohsaka-fig3, ohsaka-fig4) or a YAML file
of kind energy_time; `--coords X1 X2 X1 X2` replaces its coordinate vector, `--pattern` picks one
rotation-direction start like "-+-" (default: all 8, every local optimum reported). Output: one line
per local optimum on stdout; `--json PATH` writes every number and the best optimum as the plan
(`plan` block: family, start, genes) that `simulate --plan` executes; `--trajectory-csv PATH`
writes the best optimum sampled at 1 kHz or finer: t [s], q [rad], qd [rad/s], qdd [rad/s^2] and
the joint torques tau [N m] (inverse dynamics with gravity). Exit codes as qmt-drake: 2 bad input
(one line), 3 no start converged.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from qmt_drake.budgets import check_energy_budget
from qmt_drake.energy.collocation import solve_collocation
from qmt_drake.energy.dynamics import inverse_dynamics_with_gravity
from qmt_drake.energy.execute import execute, plot_execution
from qmt_drake.energy.experiments import paper_initial_x
from qmt_drake.energy.fourier import FourierVelocityFamily
from qmt_drake.energy.multistart import (
    PATTERNS,
    initial_end_posture,
    initial_reduced_genes,
    pattern_str,
    travel_pattern,
)
from qmt_drake.energy.nlp import solve_nlp
from qmt_drake.energy.objective import FINE_DIVISIONS
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.energy.steepest import restore_endpoint, steepest_descent
from qmt_drake.errors import QmtInputError
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD
from qmt_drake.outputs import check_output_path, jsonable, write_text_atomic

METHODS = ("snopt", "ipopt", "steepest", "collocation")


ENERGY_ONLY_OPTIONS = ("c1", "c2", "m", "divisions", "coords", "pattern", "max_iter", "execute", "recording")


def add_energy_options(p: argparse.ArgumentParser) -> None:
    """The options of `plan` that only energy-time scenarios take (--method snopt|steepest|ipopt|collocation)."""
    g = p.add_argument_group("energy-time scenarios (seed 001: --method snopt, steepest, ipopt, collocation)")
    g.add_argument("--c1", type=float, default=None, help="weight of tau'tau (default: the experiment's)")
    g.add_argument("--c2", type=float, default=None, help="weight of time, > 0 (default: the experiment's)")
    g.add_argument("--m", type=int, default=None, help="Fourier terms per joint, >= 1 (default 5)")
    g.add_argument("--divisions", type=int, default=None, help="time divisions of the integral (default 40)")
    g.add_argument("--coords", type=float, nargs=4, default=None, metavar="X",
                   help="coordinate vector X1(0) X2(0) X1(T) X2(T) in m (X2 up)")
    g.add_argument("--pattern", default=None,
                   help='rotation-direction start: "--pattern=-+-" or "npn" (p = +, n = -), or "all" (default)')
    g.add_argument("--max-iter", type=int, default=None, help="steepest: iteration cap (default 20000)")
    g.add_argument("--execute", default=None, metavar="PNG",
                   help="run the best optimum in the Drake co-simulation and plot tracking to PNG")
    g.add_argument("--recording", default=None, metavar="HTML", help="Meshcat recording of that execution")


def _pattern(s: str | None):
    if s is None or s == "all":
        return None
    if len(s) != 3 or set(s) - {"+", "-", "p", "n"}:
        raise QmtInputError(f'--pattern "{s}" must be three signs like "--pattern=-+-" or "npn", or "all"')
    return tuple(1 if c in "+p" else -1 for c in s)


def plan_energy(args) -> int:
    """`qmt-drake plan ENERGY_SCENARIO ...` (module docstring)."""


    for flag in ("--json", "--execute", "--recording", "--trajectory-csv"):  # probed before any work
        check_output_path(getattr(args, flag[2:].replace("-", "_")), flag)
    E = get_experiment(args.scenario)
    check_energy_budget(args.m if args.m is not None else E.m, args.divisions if args.divisions is not None
                        else E.divisions, allow_large=args.allow_large)
    over = {k: v for k, v in (("c1", args.c1), ("c2", args.c2), ("m", args.m),
                              ("divisions", args.divisions)) if v is not None}
    if args.coords is not None:
        over["X0"], over["XT"] = args.coords[:2], args.coords[2:]
    max_iter = 20000 if args.max_iter is None else args.max_iter
    if max_iter < 1:
        raise QmtInputError(f"--max-iter {max_iter} must be >= 1")
    pats = _pattern(args.pattern)
    P = E.problem(**over)  # validates every input before any solve
    starts = PATTERNS if pats is None else (pats,)
    if E.moving_joints is not None or E.fixed_T_s is not None:
        starts = (None,)  # Fig. 2: one start, the paper's (a, b = 0, then step III)
    out = []
    for k, p in enumerate(starts):
        if not args.quiet:
            print(f"qmt-drake: {E.name} {args.method}: start {k + 1} of {len(starts)}", file=sys.stderr)
        if p is None:
            x0 = restore_endpoint(P, paper_initial_x(P, E.paper_initial_a, E.fixed_T_s or E.T_init_s))
            y0 = P.family.full_to_reduced(x0)
        else:
            y0 = initial_reduced_genes(P, initial_end_posture(P, p), E.T_init_s)
            x0 = P.family.reduced_to_full(y0)[0]
        rec = {"start": pattern_str(p) if p else "paper"}
        if args.method == "steepest":
            r = steepest_descent(P, x0, max_iter=max_iter)
            x, z, ok = r.x, r.z, r.converged
            rec.update(iterations=r.iterations, stop=r.stop_reason, wall_s=r.wall_s)
        else:
            r = solve_nlp(P, y0, "snopt" if args.method == "collocation" else args.method)
            x, z, ok = r.x, r.z, r.success
            rec.update(evaluations=r.evaluations, wall_s=r.wall_s, status=r.status)
            if args.method == "collocation":
                c = solve_collocation(P, x)
                rec.update(fourier_z=z, collocation_z=c.z, collocation_z_resampled=c.z_resampled,
                           collocation_T_s=c.T_s, collocation_status=c.status, collocation_wall_s=c.wall_s)
                ok = ok and c.success
        rec.update(z=z, T_s=float(x[-1]), success=ok,
                   end=pattern_str(travel_pattern(P.theta0, P.family.end_posture(x))),
                   thetaT_deg=np.degrees(P.family.end_posture(x)), genes=dict(zip(P.family.gene_names(), x)),
                   energy=P.objective.energy_integral(x), x=x)
        out.append(rec)
        if args.json != "-":  # stdout is the JSON then
            print(f"{rec['start']:>8s} -> {rec['end']}  z={z:.2f}  T={x[-1]:.4f} s  "
                  f"{'ok' if ok else 'NOT CONVERGED'}")
    good = [r for r in out if r["success"]]
    result = {"kind": "energy_time", "scenario": E.name, "method": args.method, "c1": P.c1, "c2": P.c2,
              "m": P.m, "divisions": P.divisions, "theta0_deg": np.degrees(P.theta0), "X0": P.X0, "XT": P.XT,
              "optima": out}
    if good:
        best = min(good, key=lambda r: r["z"])
        fine = P.with_divisions(FINE_DIVISIONS)
        result["plan"] = {"family": "fourier_velocity", "theta0_rad": P.theta0, "m": P.m, "x": best["x"],
                          "motion_time_s": float(best["x"][-1]), "z": best["z"],
                          "z_fine": fine.value(best["x"]), "fine_divisions": FINE_DIVISIONS,
                          "end": best["end"]}
        if args.trajectory_csv:
            write_energy_csv(args.trajectory_csv, P, best["x"])
    if good and args.execute:
        ex = execute(P.family, best["x"], recording_path=args.recording)
        plot_execution(ex, args.execute, f"{E.name} {best['end']} z={best['z']:.0f}")
        result["execution"] = ex.summary()
        print(f"executed {best['end']}: max tracking error {ex.max_tracking_error_rad:.2e} rad")
    if args.json:
        text = json.dumps(jsonable(result), indent=1)
        if args.json == "-":
            print(text)
        else:
            write_text_atomic(args.json, text + "\n")
    return 0 if good else 3


def write_energy_csv(path, problem, x, rate_hz: float = 1000.0) -> None:
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


def simulate_energy(args) -> int:
    """`qmt-drake simulate ENERGY_SCENARIO [--plan P.json]`: the plan's best optimum (or a fresh
    SNOPT plan) executed in Drake (energy/execute.py: the vertical arm, inverse-dynamics control);
    prints the tracking error, --json writes the execution summary. A plan made for another
    experiment (other start, goal or weights) is refused in one line."""
    for flag in ("--json", "--record"):
        check_output_path(getattr(args, flag[2:]), flag)
    for name, given in (("--time-scale", args.time_scale != 1.0), ("--feedforward", args.feedforward != "none"),
                        ("--explicit", args.explicit), ("--time-step-ms", args.time_step_ms is not None)):
        if given:
            raise QmtInputError(f"{name} is an option of the transfer co-simulation; the energy-time "
                                f"execution runs the plan as planned: drop {name}")
    E = get_experiment(args.scenario)
    P = E.problem()
    if args.plan:
        plan = read_energy_plan(args.plan, E.name, P.theta0)
    else:
        if not args.quiet:
            print(f"qmt-drake: no --plan given: planning {E.name} with --method snopt first; give --plan "
                  "FILE to simulate a saved plan", file=sys.stderr)
        ns = argparse.Namespace(scenario=args.scenario, method="snopt", c1=None, c2=None, m=None,
                                divisions=None, coords=None, pattern=None, max_iter=None, execute=None,
                                recording=None, json=None, trajectory_csv=None, quiet=True, allow_large=False)
        plan = _best_plan(ns)
    family = FourierVelocityFamily(plan["theta0_rad"], plan["m"])
    ex = execute(family, np.asarray(plan["x"], float), recording_path=args.record)
    summary = ex.summary()
    # no payload in seed 001: the outcome is only whether the arm reached the goal (qmt_drake/outcome.py's tolerance)
    summary.update(scenario=E.name, motion_time_s=float(plan["x"][-1]),
                   reached_goal=bool(summary["final_error_rad"] <= ARRIVAL_TOLERANCE_DC_MOTOR_RAD),
                   arrival_tolerance_rad=ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
    text = json.dumps(jsonable(summary), indent=1)
    if args.json == "-":
        print(text)
    else:
        if args.json:
            write_text_atomic(args.json, text + "\n")
        print(f"{E.name}: executed T = {summary['motion_time_s']:.4f} s, max tracking error "
              f"{summary['max_tracking_error_rad']:.2e} rad, final error {summary['final_error_rad']:.2e} rad")
    return 0


def _best_plan(args) -> dict:
    """Plan quietly (plan_energy) and return its best optimum's plan block."""
    import contextlib
    import io
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as d:
        args.json = str(Path(d) / "plan.json")
        with contextlib.redirect_stdout(io.StringIO()):
            rc = plan_energy(args)
        if rc != 0:
            raise QmtInputError(f"{args.scenario}: no start converged; nothing to simulate")
        return json.loads(Path(args.json).read_text())["plan"]


def read_energy_plan(path, scenario_name: str, theta0) -> dict:
    """The plan block of an energy-time plan file, refused in one line unless it was made for this
    experiment (same name and start posture to 1e-9 rad)."""
    from pathlib import Path
    try:
        d = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise QmtInputError(f"--plan {path}: not a readable plan file ({type(exc).__name__})") from None
    if not isinstance(d, dict) or d.get("kind") != "energy_time" or not isinstance(d.get("plan"), dict):
        raise QmtInputError(f"--plan {path}: not an energy-time plan (write one with `qmt-drake plan "
                            f"{scenario_name} --json FILE`)")
    if d.get("scenario") != scenario_name or not np.allclose(d["plan"].get("theta0_rad", []), theta0,
                                                             atol=1e-9, rtol=0):
        raise QmtInputError(f"--plan {path} was made for {d.get('scenario')!r}, not {scenario_name!r} (other "
                            "start posture); plan this scenario first")
    return d["plan"]
