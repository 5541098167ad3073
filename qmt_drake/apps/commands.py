"""What the `qmt-drake` commands scenarios, simulate, bench, benchmark and reproduce run (apps/cli.py parses their
arguments and calls these by name, so that the parser itself loads no Drake). Exit codes and
the order of checks: apps/cli.py's docstring."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from qmt_drake.actuators import check_own_actuator
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
from qmt_drake.apps.cli import EXPLICIT_MAX_TIME_STEP_MS
from qmt_drake.apps.plan_command import check_tray_method
from qmt_drake.budgets import check_ga_runs_budget, check_plan_budget, check_replay_budget
from qmt_drake.config.scenario import ENERGY_TIME_KIND, builtin_scenarios
from qmt_drake.energy.cli import simulate_energy
from qmt_drake.energy.scenario import get_experiment, is_energy_scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import hand_plugin, run_simulate
from qmt_drake.margin import margin_text
from qmt_drake.margin_runs import with_margin
from qmt_drake.outputs import check_output_dir, check_output_path
from qmt_drake.plan_files import load_plan
from qmt_drake.planners import plan_with, registry
from qmt_drake.sim.sim_settings import time_step_of
from qmt_drake.transfer_scenario import load_scenario


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
        if args.method not in (None, "snopt"):
            raise QmtInputError(f"--method {args.method} plans transfer scenarios; {args.scenario} is "
                                "energy-time: give --plan FILE or no --method (it plans with snopt)")
        return simulate_energy(args)
    args.feedforward = args.feedforward or "none"
    args.method = registry.find(registry.TRANSFER, args.method or "ga", "--method").name  # one line if not planar
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
    check_own_actuator(sc, args.actuator)
    check_plan_budget(sc, "thesis" if args.plan else args.method, allow_large=args.allow_large)
    time_step_s = None if args.time_step_ms is None else args.time_step_ms * 1e-3
    # priced at the step it runs at: --time-step-ms, else the scenario's simulation.plant.time_step
    check_replay_budget(sc, args.time_scale, time_step_of(time_step_s, sc, None), allow_large=args.allow_large)
    hand = hand_plugin(sc)
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
    if args.actuator is not None:  # it named the YAML's own actuator (check_own_actuator): say which was run
        result["actuator"] = args.actuator
        result["actuator_kind"] = sc.actuator.kind
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


def cmd_reproduce(args) -> int:
    """Runs studies/run_all.py of this checkout (the studies are scripts beside the package)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / "studies" / "run_all.py").is_file():
        raise QmtInputError("reproduce needs the qmt_drake source checkout (studies/ beside the package); "
                            "run it from a clone installed with `make run`")
    check_output_path(Path(args.out) / "report.html", "--out")
    return subprocess.call([sys.executable, "-m", "studies.run_all", "--out", str(args.out)], cwd=root)
