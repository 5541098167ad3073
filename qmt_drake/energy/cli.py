"""CLI adapter for seed 001's energy-time planner.

`add_parser(subparsers)` adds the sub-command `plan-energy` (the lead wires it, or its options,
into `qmt-drake plan SCENARIO --method steepest|snopt|ipopt|collocation`); `cmd_plan_energy(args)`
runs it: `qmt-drake plan-energy ohsaka-fig3 --method snopt` (or `qmt-drake plan ohsaka-fig3 ...`).

SCENARIO is one of the built-in experiments (ohsaka-fig2, ohsaka-fig3, ohsaka-fig4; see
experiments.py); `--coords X1 X2 X1 X2` replaces its coordinate vector. `--pattern` picks one
rotation-direction start like "-+-" (default: all 8, every local optimum reported).
Output: one line per local optimum on stdout; `--json PATH` writes every number (atomic).
Exit codes as qmt-drake: 2 bad input (one line), 3 no start converged.
"""

from __future__ import annotations

import argparse
import json

from qmt_drake.budgets import check_energy_budget
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import check_output_path

METHODS = ("snopt", "ipopt", "steepest", "collocation")


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("plan-energy", help="seed 001: energy-time optimal Fourier trajectory "
                              "of the vertical 3-link arm")
    p.add_argument("scenario", help="ohsaka-fig2 | ohsaka-fig3 | ohsaka-fig4, or a YAML file of kind energy_time")
    p.add_argument("--method", choices=METHODS, default="snopt")
    p.add_argument("--c1", type=float, default=None, help="weight of tau'tau (default: the experiment's)")
    p.add_argument("--c2", type=float, default=None, help="weight of time, > 0 (default: the experiment's)")
    p.add_argument("--m", type=int, default=None, help="Fourier terms per joint, >= 1 (default 5)")
    p.add_argument("--divisions", type=int, default=None, help="time divisions of the integral (default 40)")
    p.add_argument("--coords", type=float, nargs=4, default=None, metavar="X",
                   help="coordinate vector X1(0) X2(0) X1(T) X2(T) in m (X2 up)")
    p.add_argument("--pattern", default="all",
                   help='rotation-direction start: "--pattern=-+-" or "npn" (p = +, n = -), or "all"')
    p.add_argument("--max-iter", type=int, default=20000, help="steepest descent iteration cap")
    p.add_argument("--json", default=None, help="write the results as JSON to this path ('-': stdout)")
    p.add_argument("--execute", default=None, metavar="PNG",
                   help="run the best optimum in the Drake co-simulation and plot tracking to PNG")
    p.add_argument("--recording", default=None, metavar="HTML", help="Meshcat recording of the execution")
    p.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    p.set_defaults(func=cmd_plan_energy)
    return p


def _pattern(s: str):
    if s == "all":
        return None
    if len(s) != 3 or set(s) - {"+", "-", "p", "n"}:
        raise QmtInputError(f'--pattern "{s}" must be three signs like "--pattern=-+-" or "npn", or "all"')
    return tuple(1 if c in "+p" else -1 for c in s)


def cmd_plan_energy(args) -> int:
    import numpy as np

    from qmt_drake.energy.experiments import get_experiment
    from qmt_drake.energy.multistart import (PATTERNS, initial_end_posture, initial_reduced_genes,
                                             pattern_str, travel_pattern)
    from qmt_drake.outputs import jsonable, write_text_atomic

    for flag in ("--json", "--execute", "--recording"):  # probed before any work
        check_output_path(getattr(args, flag[2:]), flag)
    E = get_experiment(args.scenario)
    check_energy_budget(args.m if args.m is not None else E.m, args.divisions if args.divisions is not None
                        else E.divisions, allow_large=args.allow_large)
    over = {k: v for k, v in (("c1", args.c1), ("c2", args.c2), ("m", args.m),
                              ("divisions", args.divisions)) if v is not None}
    if args.coords is not None:
        over["X0"], over["XT"] = args.coords[:2], args.coords[2:]
    if args.max_iter < 1:
        raise QmtInputError(f"--max-iter {args.max_iter} must be >= 1")
    pats = _pattern(args.pattern)
    P = E.problem(**over)  # validates every input before any solve
    starts = PATTERNS if pats is None else (pats,)
    if E.moving_joints is not None or E.fixed_T_s is not None:
        starts = (None,)  # Fig. 2: one start, the paper's (a, b = 0, then step III)
    out = []
    for p in starts:
        if p is None:
            from qmt_drake.energy.experiments import paper_initial_x
            from qmt_drake.energy.steepest import restore_endpoint
            x0 = restore_endpoint(P, paper_initial_x(P, E.paper_initial_a, E.fixed_T_s or E.T_init_s))
            y0 = P.family.full_to_reduced(x0)
        else:
            y0 = initial_reduced_genes(P, initial_end_posture(P, p), E.T_init_s)
            x0 = P.family.reduced_to_full(y0)[0]
        rec = {"start": pattern_str(p) if p else "paper"}
        if args.method == "steepest":
            from qmt_drake.energy.steepest import steepest_descent
            r = steepest_descent(P, x0, max_iter=args.max_iter)
            x, z, ok = r.x, r.z, r.converged
            rec.update(iterations=r.iterations, stop=r.stop_reason, wall_s=r.wall_s)
        else:
            from qmt_drake.energy.nlp import solve_nlp
            r = solve_nlp(P, y0, "snopt" if args.method == "collocation" else args.method)
            x, z, ok = r.x, r.z, r.success
            rec.update(evaluations=r.evaluations, wall_s=r.wall_s, status=r.status)
            if args.method == "collocation":
                from qmt_drake.energy.collocation import solve_collocation
                c = solve_collocation(P, x)
                rec.update(fourier_z=z, collocation_z=c.z, collocation_z_resampled=c.z_resampled,
                           collocation_T_s=c.T_s, collocation_status=c.status, collocation_wall_s=c.wall_s)
                ok = ok and c.success
        rec.update(z=z, T_s=float(x[-1]), success=ok,
                   end=pattern_str(travel_pattern(P.theta0, P.family.end_posture(x))),
                   thetaT_deg=np.degrees(P.family.end_posture(x)), genes=dict(zip(P.family.gene_names(), x)),
                   energy=P.objective.energy_integral(x), x=x)
        out.append(rec)
        print(f"{rec['start']:>8s} -> {rec['end']}  z={z:.2f}  T={x[-1]:.4f} s  "
              f"{'ok' if ok else 'NOT CONVERGED'}")
    good = [r for r in out if r["success"]]
    result = {"scenario": E.name, "method": args.method, "c1": P.c1, "c2": P.c2, "m": P.m,
              "divisions": P.divisions, "theta0_deg": np.degrees(P.theta0), "X0": P.X0, "XT": P.XT,
              "optima": out}
    if good and args.execute:
        from qmt_drake.energy.execute import execute, plot_execution
        best = min(good, key=lambda r: r["z"])
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
