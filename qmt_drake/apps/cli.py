"""The `qmt-drake` command line. Argument parsing only; the work is in plain functions.

Exit codes: 0 done, 2 bad input (one line on stderr naming it), 3 no plan meets the limits
(the least-violating plan is still written; where none exists, one line naming the binding limit), 4 a simulation failed, 130 interrupted (Ctrl-C; a GA
run with --checkpoint leaves its checkpoint to resume from).

Every argument is checked before any long computation: output paths first (`check_output_path`),
then numbers (seeds, generations, time scale and step), the checkpoint file and the plan file.

This module is light: it loads no Drake, so `qmt-drake --help` and `qmt-drake CMD --help` answer at
once. Each command is one line of COMMANDS; the module that runs it (and, for a command whose
module adds its own subparser, that module too) is imported by name only when the command is the
one given (`_resolve`). The choices below are copies of the registries' names, kept here for that
reason; tests/test_import.py checks that they agree. Adding a command: write its
`add_parser(subparsers)` (which sets `func`) or its arguments and run function, and add one line.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable
from dataclasses import dataclass

from qmt_drake import malloc_tuning
from qmt_drake.apps.one_line_parser import OneLineParser
from qmt_drake.energy.cli_options import add_energy_options
from qmt_drake.errors import QmtInputError, QmtNoPlanError, QmtSimulationError

EXIT_INPUT, EXIT_INFEASIBLE, EXIT_SIMULATION, EXIT_INTERRUPTED = 2, 3, 4, 130  # apps/plan_command's (a test checks)

# Copies of the registries' names (tests/test_import.py checks they agree): the planner registry's
# methods of each kind (planners/registry.names), spatial_families (spatial_cli.SPATIAL_FAMILIES),
# sim.spatial_actuation.ACTUATORS, sim.FEEDFORWARD_OPTIONS. --method takes every name; the registry
# refuses a method the scenario's kind does not plan, in one line naming the ones it does.
METHODS = ("ga", "optimum", "thesis", "toppra", "toppra-drake", "ruckig", "trajopt", "snopt", "ipopt", "steepest",
           "collocation")
ENERGY_METHODS = ("snopt", "ipopt", "steepest", "collocation", "toppra", "toppra-drake", "ruckig", "trajopt",
                  "family_optimum", "ga")
SPATIAL_METHODS = ("toppra", "ruckig", "family_optimum", "ga", "trajopt", "toppra-drake", "snopt", "ipopt", "steepest",
                   "collocation")
ALL_METHODS = tuple(dict.fromkeys(METHODS + ENERGY_METHODS + SPATIAL_METHODS))
SPATIAL_FAMILIES = ("via_cubic", "line_cubic_velocity", "trapezoid_ptp")
SPATIAL_ACTUATORS = ("ideal", "dc_motor")
FEEDFORWARD_CHOICES = ("none", "back-emf", "full")

EXPLICIT_MAX_TIME_STEP_MS = 1.0  # sim.actuation.EXPLICIT_MAX_TIME_STEP_S (a test checks they agree)


def plan_arguments(s: argparse.ArgumentParser) -> None:
    s.description = ("Methods: transfer scenarios (thesis-*, via5-ch4, crane-tray, your YAML): "
                     f"{', '.join(METHODS)} (GA options: --generations --stall --checkpoint; any planner: "
                     "--option KEY=VALUE). Energy-time scenarios (ohsaka-fig2/3/4): "
                     f"{', '.join(ENERGY_METHODS)} (their options below). Spatial (3-D) scenarios "
                     f"(ur5-suction-bins, ur5-magnet-part, kind: spatial_transfer): {', '.join(SPATIAL_METHODS)} "
                     "(optimum: family_optimum; GA: --seed --generations --stall --checkpoint; --carried, --carried-max-scale, --carried-cells, "
                     "--option KEY=VALUE of the planner's int/float keywords). Default: ga, or snopt for an "
                     "energy-time scenario.")
    s.add_argument("scenario", help="built-in name (see `qmt-drake scenarios`) or a YAML path")
    s.add_argument("--method", default=None, choices=ALL_METHODS)
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--json", metavar="PATH|-", help="write the plan as JSON (- for stdout)")
    s.add_argument("--trajectory-csv", metavar="PATH", help="t, q, qd, qdd at 1 kHz")
    s.add_argument("--generations", type=int, help="GA: maximum generations (default: scenario)")
    s.add_argument("--stall", type=int, help="GA: stop after this many generations without "
                   "improvement")
    s.add_argument("--checkpoint", metavar="PATH", help="GA: resumable checkpoint file")
    s.add_argument("--family", choices=SPATIAL_FAMILIES, default=None,
                   help="spatial scenarios, methods toppra, family_optimum, ga: the trajectory family (default "
                        "via_cubic; line_cubic_velocity: the hand on straight lines; trapezoid_ptp: joint PTP)")
    s.add_argument("--option", action="append", metavar="KEY=VALUE",
                   help="planner option (e.g. path=joint_line, jerk_limit=10)")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    s.add_argument("--jerk-limited", action="store_true", help="spatial --method toppra: its path timing box-filtered "
                   "and slowed until its jerk is within the scenario's jerk limits (qmt_drake/jerk.py)")
    s.add_argument("--avoid", nargs="?", const="poses", choices=("poses", "ends"), default=None,
                   help="spatial scenarios with world.obstacles: plan along a collision-free path "
                        "(planners/collision_free.py: RRT-Connect, shortcut, certified spline) through every task "
                        "pose (--avoid, --avoid poses) or from the first to the last only (--avoid ends)")
    s.add_argument("--avoid-margin", type=float, default=0.005, metavar="M",
                   help="with --avoid: the path planner's clearance in m (default 0.005)")
    s.add_argument("--avoid-seed", type=int, default=0, metavar="N", help="with --avoid: the path planner's seed")
    s.add_argument("--avoid-tries", type=int, default=1, metavar="N",
                   help="with --avoid: plan N seeded paths (seeds N0, N0 + 1, ...) and keep the one TOPP-RA times fastest")
    s.add_argument("--carried", action="store_true",
                   help="then slow the plan to the fastest time scale the nominal co-simulation carries "
                        "(bisection; every try's verdict and the margin kept go to the plan file)")
    s.add_argument("--carried-feedforward", choices=FEEDFORWARD_CHOICES, default=None,
                   help="with --carried: the DC-motor controller's feedforward (default full; tray scenarios: their "
                        "servos; spatial scenarios: given, the search co-simulates the scenario's DC motors with it "
                        "instead of Drake's inverse-dynamics controller)")
    s.add_argument("--carried-max-scale", type=float, default=3.0,
                   help="with --carried: the slowest time scale tried (default 3)")
    s.add_argument("--carried-cells", default=None, metavar="CELLS",
                   help="with --carried: also run the chosen scale at these plant steps and contact approximations "
                        "and raise it until every cell carries the part: 'all' (the search's step h, h/2, h/4 x "
                        "tamsi, sap, similar, lagged; a cell Drake cannot build is n/a) or MS:APPROX pairs, e.g. "
                        "1:sap,0.25:lagged (docs/cosimulation.md)")
    s.add_argument("--success", type=float, default=None, metavar="P",
                   help="then slow the plan to the fastest time scale whose success probability under the "
                        "scenario's uncertainty section has its 95%% Wilson lower bound >= P (Dask sweeps, "
                        "resumable under --success-out), and check it on a fresh sweep")
    s.add_argument("--success-out", default="out/success", help="with --success: the sweep store (default out/success)")
    s.add_argument("--success-check-cases", type=int, default=200, help="with --success: cases of the fresh check")
    s.add_argument("--success-max-scale", type=float, default=2.0, help="with --success: the slowest time scale tried")
    add_energy_options(s)


def simulate_arguments(s: argparse.ArgumentParser) -> None:
    s.add_argument("scenario")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--method", default=None, choices=tuple(dict.fromkeys(METHODS + SPATIAL_METHODS)),
                   help="plan first with this method (default ga; energy-time scenarios: snopt; spatial "
                        f"scenarios: {', '.join(SPATIAL_METHODS)})")
    g.add_argument("--plan", metavar="PLAN.json", help="a plan file written by `plan --json`")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--time-scale", type=float, default=1.0,
                   help="replay with time stretched by S (S < 1 is faster)")
    s.add_argument("--record", metavar="PATH.html", help="save a Meshcat recording")
    s.add_argument("--time-step-ms", type=float, default=None,
                   help="plant step in ms (default 2 with implicit loop damping, 1 with --explicit)")
    s.add_argument("--feedforward", choices=FEEDFORWARD_CHOICES + ("shaped",), default=None,
                   help="controller feedforward: none (the thesis's PID; the default), back-emf (Ke N qd_des), "
                        "full (back-emf plus Drake inverse dynamics of the reference; the default of a spatial "
                        "scenario's dc_motor actuator), shaped (spatial scenarios: full on a reference slowed "
                        "where the motors cannot follow it and smoothed over 42 ms so its acceleration steps do "
                        "not ring the part; docs/spatial_drives.md)")
    s.add_argument("--actuator", choices=SPATIAL_ACTUATORS, default=None,
                   help="spatial scenarios: ideal (Drake's inverse-dynamics controller, the default) or dc_motor "
                        "(PD/PID voltage law, DC motors with gears: the scenario's actuators.motor); planar "
                        "scenarios: only the YAML's own actuator (dc_motor for actuator.kind dc_motor_gear)")
    s.add_argument("--explicit", action="store_true",
                   help="motors drive the plant directly (no implicit loop damping; needs <= 1 ms)")
    s.add_argument("--json", metavar="PATH|-")
    s.add_argument("--quiet", action="store_true")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    s.add_argument("--margin", action="store_true",
                   help="also find the time scale at which the verdict flips (to 0.5 %%, at most 12 more runs) "
                        "and the verdict at half the plant step (qmt_drake/margin.py)")


def bench_arguments(s: argparse.ArgumentParser) -> None:
    s.add_argument("--scenario", default="thesis-ch4")
    s.add_argument("--seeds", type=int, default=5)
    s.add_argument("--out", default="out")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")


def benchmark_arguments(s: argparse.ArgumentParser) -> None:
    s.add_argument("--scenarios", nargs="+", default=["thesis-ch2", "thesis-ch3", "thesis-ch4"])
    s.add_argument("--out", default="out")
    s.add_argument("--jerk-limits", nargs="+", type=float, default=[1.0, 10.0, 100.0],
                   help="Ruckig jerk limits to sweep, m/s^3")
    s.add_argument("--ga-seeds", nargs="+", type=int, default=[0])
    s.add_argument("--quick", action="store_true", help="short GA, small trajopt, one jerk limit")
    s.add_argument("--no-cosim", action="store_true", help="skip the closed-loop column")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")


def reproduce_arguments(s: argparse.ArgumentParser) -> None:
    s.add_argument("--out", default="out")


@dataclass(frozen=True)
class Command:
    """help: the line `qmt-drake --help` shows; arguments: adds the command's arguments to its
    subparser; run: 'module:function' (or a function) called with the parsed arguments. A command
    whose module adds its own subparser (and sets `func`) gives add_parser='module:add_parser' instead."""
    help: str
    arguments: Callable[[argparse.ArgumentParser], None] | None = None
    run: str | Callable | None = None
    add_parser: str | None = None


# The commands, in the order --help lists them: one line each.
COMMANDS: dict[str, Command] = {
    "scenarios": Command("list the built-in scenarios", None, "qmt_drake.apps.commands:cmd_scenarios"),
    "plan": Command("plan a motion (every method of every scenario kind)", plan_arguments,
                    "qmt_drake.apps.plan_command:cmd_plan"),
    "simulate": Command("execute a plan through motors, PID and the held payload", simulate_arguments,
                        "qmt_drake.apps.commands:cmd_simulate"),
    "bench": Command("planner speed benchmark (JSON)", bench_arguments, "qmt_drake.apps.commands:cmd_bench"),
    "benchmark": Command("GA vs TOPP-RA, Ruckig and trajopt (JSON, Markdown, PNG)", benchmark_arguments,
                         "qmt_drake.apps.commands:cmd_benchmark"),
    "sweep": Command("run a grid / Monte Carlo sweep of co-simulated transfers on Dask", add_parser="qmt_drake.sweep.cli:add_parser"),
    "design": Command("choose arm type and link lengths for a task by operability (seed 003)",
                      add_parser="qmt_drake.design.cli:add_parser"),
    "retime": Command("fastest timing of your own joint path (CSV or a ROS 2 JointTrajectory)",
                      add_parser="qmt_drake.apps.retime_command:add_parser"),
    "export": Command("write a plan as a controller's stream (ROS 2 or CSV) and re-check it",
                      add_parser="qmt_drake.apps.export_command:add_parser"),
    "reproduce": Command("the main job (make run): every seed, the benchmark and out/report.html",
                         reproduce_arguments, "qmt_drake.apps.commands:cmd_reproduce"),
}


def _resolve(target: str | Callable) -> Callable:
    """'package.module:function' -> the function (its module imported now), a function -> itself."""
    if callable(target):
        return target
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


def _command_of(argv: list[str]) -> str | None:
    """The command named in argv (the first word that is not an option), if it is one of COMMANDS."""
    words = [w for w in argv if not w.startswith("-")]
    return words[0] if words and words[0] in COMMANDS else None


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser; only `command`'s subparser has its arguments (the others: their name and help)."""
    p = OneLineParser(prog="qmt-drake", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    for name, c in COMMANDS.items():
        if name != command:
            sub.add_parser(name, help=c.help)
        elif c.add_parser is not None:
            _resolve(c.add_parser)(sub)
        else:
            s = sub.add_parser(name, help=c.help)
            if c.arguments is not None:
                c.arguments(s)
            s.set_defaults(func=c.run)
    return p


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser(_command_of(argv)).parse_args(argv)
        # The command line's allocator settings (malloc_tuning.py), before the command's modules load, as
        # they were when `import qmt_drake` made them; the library leaves the allocator alone.
        malloc_tuning.tune()
        return _resolve(args.func)(args)
    except QmtNoPlanError as exc:  # no plan meets the limits and none least-violating exists: exit 3, one line
        print(f"qmt-drake: no plan: {exc}", file=sys.stderr)
        return EXIT_INFEASIBLE
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
