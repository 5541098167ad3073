"""`qmt-drake plan` on transfer and energy-time scenarios (spatial ones go to apps/spatial_cli.py):
the checks of every argument before any work, the planner, --carried / --success and the outputs."""

from __future__ import annotations

import tempfile
from pathlib import Path

from qmt_drake.api import check_plan_options
from qmt_drake.apps import spatial_cli
from qmt_drake.apps.arg_checks import (
    check_int,
    check_outputs,
    check_positive_finite,
    emit_json,
    given,
    parse_options,
    progress,
)
from qmt_drake.budgets import check_plan_budget, check_replay_budget
from qmt_drake.config.scenario import load_scenario
from qmt_drake.energy.cli import ENERGY_ONLY_OPTIONS, plan_energy
from qmt_drake.energy.cli import METHODS as ENERGY_METHODS
from qmt_drake.energy.scenario import is_energy_scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import hand_plugin
from qmt_drake.margin_runs import search_half_step
from qmt_drake.outputs import check_output_path, is_stdout
from qmt_drake.planners import METHODS, plan_with
from qmt_drake.planners.ga import check_checkpoint
from qmt_drake.sweep.robust import plan_fastest_carried, plan_for_success

EXIT_INPUT, EXIT_INFEASIBLE, EXIT_SIMULATION, EXIT_INTERRUPTED = 2, 3, 4, 130


def _check_checkpoint(path, scenario, seed) -> None:
    """The output path is writable and an existing file is a checkpoint of this very run
    (planners/ga.py: same scenario data, GA settings and seed)."""
    check_output_path(path, "--checkpoint")
    try:
        check_checkpoint(path, scenario.fingerprint(), scenario.ga, seed)
    except QmtInputError as exc:
        raise QmtInputError(f"--checkpoint: {exc}") from None


TRANSFER_ONLY_OPTIONS = ("generations", "stall", "checkpoint", "option")


SPATIAL_ONLY_METHODS = tuple(m for m in spatial_cli.SPATIAL_METHODS if m not in METHODS)


def refuse_spatial_method(args) -> None:
    if args.method in SPATIAL_ONLY_METHODS:
        raise QmtInputError(f"--method {args.method} plans spatial scenarios; {args.scenario} is a transfer scenario: "
                            "use --method ga|optimum|thesis|toppra|ruckig|trajopt")


def cmd_plan(args) -> int:
    if spatial_cli.is_spatial_scenario(args.scenario):
        return 0 if spatial_cli.plan(args, ENERGY_ONLY_OPTIONS) else EXIT_INFEASIBLE
    if getattr(args, "jerk_limited", False):
        raise QmtInputError(f"--jerk-limited: for spatial scenarios' --method toppra; {args.scenario} is not one: drop it")
    if args.family is not None:
        raise QmtInputError(f"--family: for spatial scenarios; {args.scenario} sets its family in its file "
                            "(family.kind); drop --family")
    if is_energy_scenario(args.scenario):
        args.method = args.method or "snopt"
        if args.method not in ENERGY_METHODS:
            raise QmtInputError(f"--method {args.method} plans transfer scenarios; {args.scenario} is an "
                                f"energy-time scenario: use --method {'|'.join(ENERGY_METHODS)}")
        wrong = (given(args, TRANSFER_ONLY_OPTIONS) + (["--seed"] if args.seed != 0 else [])
                 + (["--carried"] if args.carried else []))
        if wrong:
            raise QmtInputError(f"{' '.join(wrong)}: options of transfer planners; {args.scenario} is an "
                                f"energy-time scenario (--method {args.method}): drop them")
        return plan_energy(args)
    args.method = args.method or "ga"
    if args.method in ENERGY_METHODS:
        raise QmtInputError(f"--method {args.method} plans energy-time scenarios (ohsaka-fig2/3/4, or a YAML "
                            f"with kind: energy_time); {args.scenario} is a transfer scenario: use --method "
                            "ga|optimum|thesis|toppra|ruckig|trajopt")
    refuse_spatial_method(args)
    wrong = given(args, ENERGY_ONLY_OPTIONS)
    if wrong:
        raise QmtInputError(f"{' '.join(wrong)}: options of the energy-time planners; {args.scenario} is a "
                            "transfer scenario: drop them")
    check_outputs(args, "--json", "--trajectory-csv")
    check_int(args.seed, "--seed", 0, "seeds are non-negative integers")
    check_positive_finite(args.carried_max_scale, "--carried-max-scale", "e.g. 3: try up to 3x slower")
    if args.success is not None:  # the options and the uncertainty section, checked before any planning
        spatial_cli.check_success_options(args, load_scenario(args.scenario))
    if args.carried_max_scale <= 1:
        raise QmtInputError(f"--carried-max-scale {args.carried_max_scale:g} must exceed 1 (1 is the plan as planned)")
    check_int(args.generations, "--generations", 1, "run at least one generation")
    check_int(args.stall, "--stall", 0, "0 never stops early")
    sc = load_scenario(args.scenario)
    check_tray_method(sc, args.method)
    check_plan_budget(sc, args.method, args.generations, allow_large=args.allow_large)
    if args.carried:  # the slowest replay the search may run (at the scenario's motion-time bound)
        try:
            check_replay_budget(sc, args.carried_max_scale, allow_large=args.allow_large)
        except QmtInputError as exc:
            raise QmtInputError(f"--carried-max-scale {args.carried_max_scale:g}: {exc}") from None
    if args.checkpoint is not None:
        if args.method != "ga":
            raise QmtInputError(f"--checkpoint is for --method ga, not {args.method}; drop it")
        _check_checkpoint(args.checkpoint, sc, args.seed)
    options = {}
    if args.method == "ga":
        if args.generations is not None:
            options["max_generations"] = args.generations
        if args.stall is not None:
            options["stall_generations"] = args.stall
        if args.checkpoint:
            options["checkpoint_path"] = args.checkpoint
    given_options = parse_options(args.option)
    check_plan_options(args.method, sc, given_options, where="--option", allow_large=args.allow_large)
    options.update(given_options)
    try:
        plan = plan_with(args.method, sc, seed=args.seed,
                         progress=None if args.quiet else progress, **options)
    except TypeError as exc:
        if "unexpected keyword argument" in str(exc):
            raise QmtInputError(f"--option: {exc}; see the planner's docstring for its options") from None
        if args.option:  # a value of the wrong type reached the planner
            raise QmtInputError(f"--option {' '.join(args.option)}: a value has the wrong type "
                                f"({str(exc).splitlines()[0]}); see the planner's docstring") from None
        raise
    if args.carried:
        if not plan.feasible:
            raise QmtInputError(f"--carried: the {args.method} plan breaks a limit on the re-check; nothing to "
                                "time-scale (drop --carried to write the least-violating plan)")
        plan = plan_fastest_carried(sc, args.method, base_plan=plan, feedforward=args.carried_feedforward,
                                    s_max=args.carried_max_scale, progress=None if args.quiet else progress)
        search = plan.extra["carried_search"]
        lost = search.get("lost_below")
        search["margin"] = None if lost is None else search["chosen"] / lost - 1.0
        # the chosen plan at the next step size: reported (a flip too), not re-chosen
        search["half_step"] = search_half_step(sc, plan, feedforward=args.carried_feedforward)
        if not args.quiet:
            hs = search["half_step"]
            progress(f"{sc.name} {args.method} x{search['chosen']:.4f} at half the step "
                     f"({hs['half_step_s'] * 1e3:g} ms): {hs['verdict_at_half_step']}, slip "
                     f"{hs['slip_at_half_step'] * 1e3:.3f} mm" + (" (the verdict FLIPS)" if hs["flips_at_half_step"] else ""))
    if args.success is not None:
        if not plan.feasible:
            raise QmtInputError(f"--success: the {args.method} plan breaks a limit on the re-check; nothing to "
                                "time-scale")
        with tempfile.TemporaryDirectory() as d:
            base_file = Path(d) / "base_plan.json"
            plan.write_json(base_file)
            plan, _ = plan_for_success(plan, base_file, args.success_out, target=args.success,
                                       check_cases=args.success_check_cases, s_max=args.success_max_scale,
                                       progress=None if args.quiet else progress)
    if args.json and args.json != "-":
        plan.write_json(args.json)
    elif args.json == "-":
        emit_json(plan.to_json_dict(), "-")
    if args.trajectory_csv:
        plan.write_csv(args.trajectory_csv)
    if not (is_stdout(args.json) or is_stdout(args.trajectory_csv)):  # stdout is the JSON or the CSV then
        print(f"{sc.name} {args.method}: T0 = {plan.motion_time_s:.4f} s, {hand_plugin(sc).plan_ratios_text(plan)}, "
              f"{'feasible' if plan.feasible else 'INFEASIBLE (least-violating plan)'}, "
              f"{plan.planner_wall_s:.2f} s")
    return 0 if plan.feasible else EXIT_INFEASIBLE


def check_tray_method(sc, method: str) -> None:
    """One line when the scenario's hand plug-in refuses the method (hands.py)."""
    hand = hand_plugin(sc)
    if method in hand.refused_methods:
        usable = [m for m in METHODS if m not in hand.refused_methods]
        raise QmtInputError(f"--method {method} is not available for the {hand.kind} scenario '{sc.name}' "
                            f"({hand.refused_methods[method]}); use {', '.join(usable[:-1])} or {usable[-1]}")
