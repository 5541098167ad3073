"""Seed 001 behind the one CLI: `qmt-drake plan ohsaka-fig3 --method snopt|steepest|ipopt|collocation`
and `qmt-drake simulate ohsaka-fig3 --plan p.json` (apps/cli.py routes energy-time scenarios here).

energy/cli_options.add_energy_options(parser) adds the energy-time options to `plan` (a module of its own,
so that the parser loads no Drake); `plan_energy(args)` runs it:
SCENARIO is one of the built-in experiments (ohsaka-fig2, ohsaka-fig3, ohsaka-fig4) or a YAML file
of kind energy_time; `--coords X1 X2 X1 X2` replaces its coordinate vector, `--pattern` picks one
rotation-direction start like "-+-" (default: all 8, every local optimum reported). The work is
energy/energy_plan.plan_energy_time reached through the one planner registry (planners/registry.py),
whose EnergyPlan (a plan.Plan) is the result. Output: one line
per local optimum on stdout; `--json PATH` writes the plan file (every number, every optimum, the
best one's `plan` block and trajectory) that `simulate --plan` executes and plan.load_plan reads;
`--trajectory-csv PATH` writes the best optimum sampled at 1 kHz or finer: t [s], q [rad], qd
[rad/s], qdd [rad/s^2] and the joint torques tau [N m] (inverse dynamics with gravity). Exit codes
as qmt-drake: 2 bad input (one line), 3 no start converged (the file then holds the lowest-cost
optimum with "feasible": false).
"""

from __future__ import annotations

import json
import sys

from qmt_drake.apps import spatial_cli
from qmt_drake.budgets import check_energy_budget
from qmt_drake.energy.as_transfer import file_kind, load_transfer_plan, transfer_scenario_of
from qmt_drake.energy.energy_plan import METHODS as METHODS  # the CLI lists them
from qmt_drake.energy.execute import (
    check_time_step,
    execute,
    execute_plan,
    execute_transfer_plan,
    plot_execution,
)
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.errors import QmtInputError
from qmt_drake.margin import margin_text
from qmt_drake.margin_runs import with_margin
from qmt_drake.outputs import check_one_stdout, check_output_path, is_stdout, jsonable, write_text_atomic
from qmt_drake.plan import ENERGY_PLAN_KIND, SPATIAL_PLAN_KIND
from qmt_drake.plan_files import load_plan
from qmt_drake.planners import registry


def _stderr(line: str) -> None:
    print(line, file=sys.stderr)


def plan_energy(args, options: dict) -> int:
    """`qmt-drake plan ENERGY_SCENARIO ...` (module docstring); `options`: the planner's, from the flags
    (apps/plan_options.py, already checked against the registry's row)."""
    outputs = {flag: getattr(args, flag[2:].replace("-", "_")) for flag in ("--json", "--execute", "--recording",
                                                                            "--trajectory-csv")}
    check_one_stdout(outputs)
    for flag, path in outputs.items():  # probed before any work
        check_output_path(path, flag)
    talk = not (is_stdout(args.json) or is_stdout(args.trajectory_csv))  # else stdout is the JSON or the CSV
    E = get_experiment(args.scenario)
    if args.method not in METHODS:  # a transfer planner: the arm as a minimum-time transfer (energy/as_transfer.py)
        return _plan_transfer(args, E, options)
    check_energy_budget(options.get("m") or E.m, options.get("divisions") or E.divisions, allow_large=args.allow_large)

    def line(rec: dict) -> None:
        if talk:
            print(f"{rec['start']:>8s} -> {rec['end']}  z={rec['z']:.2f}  T={rec['T_s']:.4f} s  "
                  f"{'ok' if rec['success'] else 'NOT CONVERGED'}")

    plan = registry.plan(E, args.method, progress=None if args.quiet else _stderr, on_optimum=line, **options)
    result = plan.to_json_dict()
    if plan.feasible and args.trajectory_csv:
        plan.write_csv(args.trajectory_csv)
    if plan.feasible and args.execute:
        ex = execute(plan.problem.family, plan.x, recording_path=args.recording)
        plot_execution(ex, args.execute, f"{E.name} {plan.end} z={plan.cost_z:.0f}")
        result["execution"] = jsonable(ex.summary())
        if talk:
            print(f"executed {plan.end}: max tracking error {ex.max_tracking_error_rad:.2e} rad")
    if args.json:
        text = json.dumps(result, indent=1)
        if args.json == "-":
            print(text)
        else:
            write_text_atomic(args.json, text + "\n")
    return 0 if plan.feasible else 3


def _plan_transfer(args, E, options: dict) -> int:
    """`qmt-drake plan ohsaka-fig3 --method toppra|ruckig|...`: the spatial planner on the arm's transfer
    (energy/as_transfer.py) with the spatial CLI's outputs; exit 3 with the least-violating plan."""
    for flag in ("--execute", "--recording"):
        if getattr(args, flag[2:]):
            raise QmtInputError(f"{flag}: the energy-time execution of a {args.method} plan is `qmt-drake simulate "
                                f"{args.scenario} --plan P.json`; drop {flag}")
    sc = transfer_scenario_of(E)
    return 0 if spatial_cli.plan(args, registry.find(registry.SPATIAL, args.method), options, scenario=sc) else 3


_NO_MOTOR = ("seed 001's arm is driven by ideal torque sources (the paper models no motor, gear or torque "
             "limit)")


def refused_options(args) -> tuple[tuple[str, str | None], ...]:
    """The simulate options that have no meaning on seed 001's arm, each with its physics reason (None: not
    given)."""
    return (
        ("--time-scale", None if args.time_scale == 1.0 else
         "the energy-time execution runs the plan at the timing its optimiser chose (c2 weighs the motion "
         "time against the energy); plan with another c2 for another timing"),
        ("--feedforward", None if args.feedforward == "none" else
         f"{_NO_MOTOR}: there is no motor voltage and no back-EMF to feed forward; its inverse-dynamics "
         "controller already has the plan's full torque as feedforward"),
        ("--explicit", None if not args.explicit else
         f"{_NO_MOTOR}: there is no motor-voltage loop to step explicitly"),
        ("--actuator", None if getattr(args, "actuator", None) is None else
         f"{_NO_MOTOR}: there is no DC motor or gear data to drive it with"),
    )


def simulate_energy(args) -> int:
    """`qmt-drake simulate ENERGY_SCENARIO [--plan P.json]`: the plan (or a fresh SNOPT plan)
    executed in Drake (energy/execute.py: the vertical arm, inverse-dynamics control); prints the
    tracking error, --json writes the execution summary. A plan file of another experiment (other
    start posture or goal) or of another scenario kind is refused in one line (plan.load_plan)."""
    for flag in ("--json", "--record"):
        check_output_path(getattr(args, flag[2:]), flag)
    for name, given in refused_options(args):
        if given:
            raise QmtInputError(f"{name}: {given}: drop {name}")
    step_s = check_time_step(None if args.time_step_ms is None else args.time_step_ms * 1e-3, "--time-step-ms", 1e3)
    E = get_experiment(args.scenario)
    if args.plan and file_kind(args.plan) == SPATIAL_PLAN_KIND:  # a transfer planner's plan of this arm
        plan = load_transfer_plan(args.plan, E)
    elif args.plan:
        plan = load_plan(args.plan, E)
        if not plan.feasible:
            raise QmtInputError(f"--plan {args.plan}: no start converged when it was planned; nothing to simulate")
    else:
        if not args.quiet:
            print(f"qmt-drake: no --plan given: planning {E.name} with --method snopt first; give --plan "
                  "FILE to simulate a saved plan", file=sys.stderr)
        plan = registry.plan(E, "snopt")
        if not plan.feasible:
            raise QmtInputError(f"{args.scenario}: no start converged; nothing to simulate")
    summary = execute_plan(plan, record_path=args.record, time_step_s=step_s) if plan.scenario_kind == ENERGY_PLAN_KIND \
        else execute_transfer_plan(plan, record_path=args.record, time_step_s=step_s)
    if getattr(args, "margin", False):  # its margin: the final error against the arrival tolerance
        summary = with_margin(E, plan, summary, expensive=True)
    text = json.dumps(jsonable(summary), indent=1)
    if args.json == "-":
        print(text)
    else:
        if args.json:
            write_text_atomic(args.json, text + "\n")
        print(f"{E.name}: executed T = {summary['motion_time_s']:.4f} s, max tracking error "
              f"{summary['max_tracking_error_rad']:.2e} rad, final error {summary['final_error_rad']:.2e} rad")
        if "margin" in summary:
            print(margin_text(summary["margin"]))
    return 0

