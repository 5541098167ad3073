"""The `qmt-drake` command line. Argument parsing only; the work is in plain functions.

Exit codes: 0 done, 2 bad input (one line on stderr naming it), 3 no plan meets the limits
(the least-violating plan is still written), 4 a simulation failed, 130 interrupted (Ctrl-C; a GA
run with --checkpoint leaves its checkpoint to resume from).

Every argument is checked before any long computation: output paths first (`check_output_path`),
then numbers (seeds, generations, time scale and step), the checkpoint file and the plan file.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

from qmt_drake.apps import spatial_cli
from qmt_drake.apps.arg_checks import (
    check_int,
    check_outputs,
    check_positive_finite,
    emit_json,
    progress,
)
from qmt_drake.apps.bench import run_bench
from qmt_drake.apps.benchmark import run_benchmark
from qmt_drake.apps.export_command import add_parser as add_export_parser
from qmt_drake.apps.one_line_parser import OneLineParser
from qmt_drake.apps.plan_command import (
    EXIT_INPUT,
    EXIT_INTERRUPTED,
    EXIT_SIMULATION,
    SPATIAL_ONLY_METHODS,
    check_tray_method,
    cmd_plan,
    refuse_spatial_method,
)
from qmt_drake.apps.retime_command import add_parser as add_retime_parser
from qmt_drake.budgets import check_ga_runs_budget, check_plan_budget, check_replay_budget
from qmt_drake.config.scenario import ENERGY_TIME_KIND, builtin_scenarios, load_scenario
from qmt_drake.design.cli import add_parser as add_design_parser
from qmt_drake.energy.cli import METHODS as ENERGY_METHODS
from qmt_drake.energy.cli import add_energy_options, simulate_energy
from qmt_drake.energy.scenario import get_experiment, is_energy_scenario
from qmt_drake.errors import QmtInputError, QmtSimulationError
from qmt_drake.hands import hand_plugin, run_simulate
from qmt_drake.margin import margin_text
from qmt_drake.margin_runs import with_margin
from qmt_drake.outputs import check_output_dir, check_output_path
from qmt_drake.plan_files import load_plan
from qmt_drake.planners import METHODS, plan_with
from qmt_drake.sim.spatial_actuation import ACTUATORS as SPATIAL_ACTUATORS
from qmt_drake.sweep.cli import add_parser as add_sweep_parser

# sim.FEEDFORWARD_OPTIONS keys (kept here so `--help` does not import Drake; a test checks they agree).
FEEDFORWARD_CHOICES = ("none", "back-emf", "full")

EXPLICIT_MAX_TIME_STEP_MS = 1.0  # sim.actuation.EXPLICIT_MAX_TIME_STEP_S (a test checks they agree)


def cmd_scenarios(args) -> int:
    for name in builtin_scenarios():
        sc = load_scenario(name)
        print(f"{name:12s} {sc.family.kind:20s} genes {', '.join(sc.family.gene_names):22s} "
              f"{sc.arm.n_dof}-link arm, payload {sc.payload.mass_kg * 1e3:.0f} g")
    for name in builtin_scenarios(ENERGY_TIME_KIND):
        ex = get_experiment(name)
        print(f"{name:12s} {'fourier_velocity':20s} energy-time (seed 001), c2 = {ex.c2:g}, m = {ex.m}; "
              f"plan with --method snopt|steepest|ipopt|collocation")
    spatial_cli.list_scenarios()
    return 0


def cmd_simulate(args) -> int:
    if spatial_cli.is_spatial_scenario(args.scenario):
        return spatial_cli.simulate(args)
    if is_energy_scenario(args.scenario):
        args.feedforward = args.feedforward or "none"
        if args.actuator is not None:
            raise QmtInputError("--actuator is an option of the transfer co-simulation; the energy-time execution "
                                "runs the plan as planned: drop --actuator")
        if args.method not in (None, "snopt"):
            raise QmtInputError(f"--method {args.method} plans transfer scenarios; {args.scenario} is "
                                "energy-time: give --plan FILE or no --method (it plans with snopt)")
        if args.margin:
            raise QmtInputError("--margin: the energy-time execution takes no time scale or plant step to vary; "
                                "drop --margin (its result states its final error against the tolerance)")
        return simulate_energy(args)
    if args.actuator is not None:
        raise QmtInputError(f"--actuator: for spatial scenarios; {args.scenario}'s actuator is its YAML actuator "
                            "section: drop --actuator")
    args.feedforward = args.feedforward or "none"
    args.method = args.method or "ga"
    refuse_spatial_method(args)
    check_outputs(args, "--json", "--record")
    check_int(args.seed, "--seed", 0, "seeds are non-negative integers")
    check_positive_finite(args.time_scale, "--time-scale", "1 replays the plan as planned, 2 twice as slow")
    check_positive_finite(args.time_step_ms, "--time-step-ms", "the plant step in ms, e.g. 1 or 2")
    if args.explicit and args.time_step_ms is not None and args.time_step_ms > EXPLICIT_MAX_TIME_STEP_MS:
        raise QmtInputError(f"--explicit --time-step-ms {args.time_step_ms:g}: the explicit motor loop is "
                            f"known unstable above {EXPLICIT_MAX_TIME_STEP_MS:g} ms (a loss would be the "
                            f"loop's, not the physics'); use --time-step-ms {EXPLICIT_MAX_TIME_STEP_MS:g} "
                            "or less, or drop --explicit")
    sc = load_scenario(args.scenario)
    check_plan_budget(sc, "thesis" if args.plan else args.method, allow_large=args.allow_large)
    check_replay_budget(sc, args.time_scale, None if args.time_step_ms is None else args.time_step_ms * 1e-3,
                        allow_large=args.allow_large)
    hand = hand_plugin(sc)
    time_step_s = None if args.time_step_ms is None else args.time_step_ms * 1e-3
    # What the co-simulation needs from the scenario and the options, before planning.
    hand.check_simulation(sc, time_step_s=time_step_s, implicit_loop_damping=not args.explicit,
                          feedforward=args.feedforward)
    if args.plan:
        plan = load_plan(args.plan, scenario=sc)
    else:
        check_tray_method(sc, args.method)
        _say_planning_first(args)
        plan = plan_with(args.method, sc, seed=args.seed,
                         progress=None if args.quiet else progress)
    result = run_simulate(sc, plan, time_scale=args.time_scale, record_path=args.record, time_step_s=time_step_s,
                          implicit_loop_damping=not args.explicit, feedforward=args.feedforward)
    if args.margin:
        result = with_margin(sc, plan, result, expensive=True, time_scale=args.time_scale, time_step_s=time_step_s,
                             feedforward=args.feedforward, progress=None if args.quiet else progress)
    emit_json(result, args.json)
    if args.json != "-":
        print(f"{sc.name} {plan.method} x{args.time_scale}: {hand.simulate_text(result)}")
        print(margin_text(result["margin"]))
    return 0


def _say_planning_first(args) -> None:
    """simulate without --plan plans first: say so, since a GA takes tens of seconds."""
    if not args.quiet:
        print(f"qmt-drake: no --plan given: planning with --method {args.method} (seed {args.seed}) first; "
              "give --plan FILE to simulate a saved plan", file=sys.stderr)


def cmd_bench(args) -> int:
    check_output_dir(args.out, "--out")
    check_int(args.seeds, "--seeds", 1, "run at least one seed")
    check_ga_runs_budget(load_scenario(args.scenario), args.seeds, 3000, allow_large=args.allow_large)
    data = run_bench(scenario=args.scenario, out_dir=Path(args.out), progress=progress,
                     seeds=args.seeds)
    print(json.dumps(data, indent=1))
    return 0


def cmd_benchmark(args) -> int:
    check_output_dir(args.out, "--out")
    for seed in args.ga_seeds:
        check_int(seed, "--ga-seeds", 0, "seeds are non-negative integers")
    for j in args.jerk_limits:
        check_positive_finite(j, "--jerk-limits", "tip jerk limits in m/s^3, e.g. 1 10 100")
    for name in args.scenarios:
        check_ga_runs_budget(load_scenario(name), len(args.ga_seeds), 30 if args.quick else 1000,
                             allow_large=args.allow_large)
    run_benchmark(scenarios=tuple(args.scenarios), out_dir=Path(args.out), progress=progress,
                  jerk_limits=tuple(args.jerk_limits), ga_seeds=tuple(args.ga_seeds),
                  quick=args.quick, cosim=not args.no_cosim)
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="qmt-drake", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("scenarios", help="list the built-in scenarios")
    s.set_defaults(func=cmd_scenarios)

    s = sub.add_parser("plan", help="plan a motion (every method of every scenario kind)",
                       description="Methods: transfer scenarios (thesis-*, via5-ch4, crane-tray, your YAML): "
                       f"{', '.join(METHODS)} (GA options: --generations --stall --checkpoint; any planner: "
                       "--option KEY=VALUE). Energy-time scenarios (ohsaka-fig2/3/4): "
                       f"{', '.join(ENERGY_METHODS)} (their options below). Spatial (3-D) scenarios "
                       f"(ur5-suction-bins, ur5-magnet-part, kind: spatial_transfer): {', '.join(spatial_cli.SPATIAL_METHODS)} "
                       "(optimum: family_optimum; GA: --seed --generations --stall; --carried, --carried-max-scale, "
                       "--option KEY=VALUE of the planner's int/float keywords). Default: ga, or snopt for an "
                       "energy-time scenario.")
    s.add_argument("scenario", help="built-in name (see `qmt-drake scenarios`) or a YAML path")
    s.add_argument("--method", default=None, choices=METHODS + ENERGY_METHODS + SPATIAL_ONLY_METHODS)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--json", metavar="PATH|-", help="write the plan as JSON (- for stdout)")
    s.add_argument("--trajectory-csv", metavar="PATH", help="t, q, qd, qdd at 1 kHz")
    s.add_argument("--generations", type=int, help="GA: maximum generations (default: scenario)")
    s.add_argument("--stall", type=int, help="GA: stop after this many generations without "
                   "improvement")
    s.add_argument("--checkpoint", metavar="PATH", help="GA: resumable checkpoint file")
    s.add_argument("--family", choices=spatial_cli.SPATIAL_FAMILIES, default=None,
                   help="spatial scenarios, methods toppra, family_optimum, ga: the trajectory family (default "
                        "via_cubic; line_cubic_velocity: the hand on straight lines; trapezoid_ptp: joint PTP)")
    s.add_argument("--option", action="append", metavar="KEY=VALUE",
                   help="planner option (e.g. path=joint_line, jerk_limit=10)")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    s.add_argument("--jerk-limited", action="store_true", help="spatial --method toppra: slowed until its peak jerk "
                   "is within the scenario's jerk limits (qmt_drake/jerk.py)")
    s.add_argument("--carried", action="store_true",
                   help="then slow the plan to the fastest time scale the nominal co-simulation carries "
                        "(bisection; every try's verdict and the margin kept go to the plan file)")
    s.add_argument("--carried-feedforward", choices=FEEDFORWARD_CHOICES, default="full",
                   help="with --carried: the DC-motor controller's feedforward (tray scenarios: their servos)")
    s.add_argument("--carried-max-scale", type=float, default=3.0,
                   help="with --carried: the slowest time scale tried (default 3)")
    s.add_argument("--success", type=float, default=None, metavar="P",
                   help="then slow the plan to the fastest time scale whose success probability under the "
                        "scenario's uncertainty section has its 95%% Wilson lower bound >= P (Dask sweeps, "
                        "resumable under --success-out), and check it on a fresh sweep")
    s.add_argument("--success-out", default="out/success", help="with --success: the sweep store (default out/success)")
    s.add_argument("--success-check-cases", type=int, default=200, help="with --success: cases of the fresh check")
    s.add_argument("--success-max-scale", type=float, default=2.0, help="with --success: the slowest time scale tried")
    add_energy_options(s)
    s.set_defaults(func=cmd_plan)

    s = sub.add_parser("simulate", help="execute a plan through motors, PID and the held payload")
    s.add_argument("scenario")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--method", default=None, choices=METHODS + SPATIAL_ONLY_METHODS,
                   help="plan first with this method (default ga; energy-time scenarios: snopt; spatial "
                        f"scenarios: {', '.join(spatial_cli.SPATIAL_METHODS)})")
    g.add_argument("--plan", metavar="PLAN.json", help="a plan file written by `plan --json`")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--time-scale", type=float, default=1.0,
                   help="replay with time stretched by S (S < 1 is faster)")
    s.add_argument("--record", metavar="PATH.html", help="save a Meshcat recording")
    s.add_argument("--time-step-ms", type=float, default=None,
                   help="plant step in ms (default 2 with implicit loop damping, 1 with --explicit)")
    s.add_argument("--feedforward", choices=FEEDFORWARD_CHOICES, default=None,
                   help="controller feedforward: none (the thesis's PID; the default), back-emf (Ke N qd_des), "
                        "full (back-emf plus Drake inverse dynamics of the reference; the default of a spatial "
                        "scenario's dc_motor actuator)")
    s.add_argument("--actuator", choices=SPATIAL_ACTUATORS, default=None,
                   help="spatial scenarios: ideal (Drake's inverse-dynamics controller, the default) or dc_motor "
                        "(PD/PID voltage law, DC motors with gears: the scenario's actuators.motor)")
    s.add_argument("--explicit", action="store_true",
                   help="motors drive the plant directly (no implicit loop damping; needs <= 1 ms)")
    s.add_argument("--json", metavar="PATH|-")
    s.add_argument("--quiet", action="store_true")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    s.add_argument("--margin", action="store_true",
                   help="also find the time scale at which the verdict flips (to 0.5 %%, at most 12 more runs) "
                        "and the verdict at half the plant step (qmt_drake/margin.py)")
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("bench", help="planner speed benchmark (JSON)")
    s.add_argument("--scenario", default="thesis-ch4")
    s.add_argument("--seeds", type=int, default=5)
    s.add_argument("--out", default="out")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    s.set_defaults(func=cmd_bench)

    s = sub.add_parser("benchmark", help="GA vs TOPP-RA, Ruckig and trajopt (JSON, Markdown, PNG)")
    s.add_argument("--scenarios", nargs="+", default=["thesis-ch2", "thesis-ch3", "thesis-ch4"])
    s.add_argument("--out", default="out")
    s.add_argument("--jerk-limits", nargs="+", type=float, default=[1.0, 10.0, 100.0],
                   help="Ruckig jerk limits to sweep, m/s^3")
    s.add_argument("--ga-seeds", nargs="+", type=int, default=[0])
    s.add_argument("--quick", action="store_true", help="short GA, small trajopt, one jerk limit")
    s.add_argument("--no-cosim", action="store_true", help="skip the closed-loop column")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    s.set_defaults(func=cmd_benchmark)

    add_sweep_parser(sub)
    add_design_parser(sub)
    add_retime_parser(sub)
    add_export_parser(sub)

    s = sub.add_parser("reproduce", help="the main job (make run): every seed, the benchmark and out/report.html")
    s.add_argument("--out", default="out")
    s.set_defaults(func=cmd_reproduce)
    return p


def cmd_reproduce(args) -> int:
    """Runs studies/run_all.py of this checkout (the studies are scripts beside the package)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / "studies" / "run_all.py").is_file():
        raise QmtInputError("reproduce needs the qmt_drake source checkout (studies/ beside the package); "
                            "run it from a clone installed with `make run`")
    check_output_path(Path(args.out) / "report.html", "--out")
    return subprocess.call([sys.executable, "-m", "studies.run_all", "--out", str(args.out)], cwd=root)


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(list(sys.argv[1:] if argv is None else argv))
        return args.func(args)
    except QmtInputError as exc:
        print(f"qmt-drake: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except QmtSimulationError as exc:
        print(f"qmt-drake: simulation failed: {exc}", file=sys.stderr)
        return EXIT_SIMULATION
    except KeyboardInterrupt as exc:
        # The GA saves its checkpoint on the way out (planners/ga.py); nothing half-written stays.
        print(f"qmt-drake: interrupted {exc}".rstrip(), file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
