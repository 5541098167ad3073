"""`qmt-drake plan` on every scenario kind: the method and its options checked against the one planner
registry (apps/plan_options.py, planners/registry.py) before any work; transfer scenarios are planned
here (--carried / --success and the outputs), spatial ones in apps/spatial_cli.py, energy-time ones in
energy/cli.py, all through registry.plan."""

from __future__ import annotations

import tempfile
from pathlib import Path

from qmt_drake.api import check_plan_options
from qmt_drake.apps import spatial_cli
from qmt_drake.apps.arg_checks import (
    carried_cells_arg,
    check_int,
    check_outputs,
    check_positive_finite,
    emit_json,
    given,
    progress,
)
from qmt_drake.apps.plan_options import FLAGS, checked_method, scenario_kind
from qmt_drake.budgets import check_replay_budget
from qmt_drake.carried_cells import (
    carried_transfer_plan_every_cell,
    check_transfer_cells,
    every_cell_lines,
    every_cell_text,
    resolve_cells,
    transfer_default_cell,
)
from qmt_drake.energy.cli import plan_energy
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import hand_plugin
from qmt_drake.margin_runs import search_half_step
from qmt_drake.outputs import check_output_path, is_stdout
from qmt_drake.plan import a_kind
from qmt_drake.planners import registry
from qmt_drake.planners.ga import check_checkpoint
from qmt_drake.sweep.robust import plan_fastest_carried, plan_for_success
from qmt_drake.transfer_scenario import load_scenario

EXIT_INPUT, EXIT_INFEASIBLE, EXIT_SIMULATION, EXIT_INTERRUPTED = 2, 3, 4, 130


def _check_checkpoint(path, scenario, seed) -> None:
    """The output path is writable and an existing file is a checkpoint of this very run
    (planners/ga.py: same scenario data, GA settings and seed)."""
    check_output_path(path, "--checkpoint")
    try:
        check_checkpoint(path, scenario.fingerprint(), scenario.ga, seed)
    except QmtInputError as exc:
        raise QmtInputError(f"--checkpoint: {exc}") from None


def _refuse_for_kind(args, kind: str) -> None:
    """The flags that are not planner options and that a kind cannot use, each with its reason."""
    if kind != registry.ENERGY:
        wrong = given(args, ("execute", "recording"))
        if wrong:
            raise QmtInputError(f"{' '.join(wrong)}: execute an energy-time plan; {args.scenario} is "
                                f"{a_kind(kind)} scenario: `qmt-drake simulate {args.scenario} --plan P.json` runs its plan")
    elif args.carried or args.success is not None:
        raise QmtInputError(f"{'--carried' if args.carried else '--success'}: the energy-time arm (seed 001) carries no "
                            "payload it could lose, so there is nothing to slow down for; drop it")
    if not getattr(args, "avoid", None) and (getattr(args, "avoid_margin", 0.005) != 0.005
                                              or getattr(args, "avoid_tries", 1) != 1
                                              or getattr(args, "avoid_seed", 0) != 0):
        raise QmtInputError("--avoid-margin / --avoid-seed / --avoid-tries: options of --avoid (the collision-free "
                            "path); add --avoid or drop them")
    if getattr(args, "avoid", None) and kind != registry.SPATIAL:
        raise QmtInputError(f"--avoid plans a collision-free path among a spatial scenario's world.obstacles; "
                            f"{args.scenario} is {a_kind(kind)} scenario: drop it")
    if getattr(args, "jerk_limited", False) and not (kind == registry.SPATIAL and args.method == "toppra"):
        raise QmtInputError(f"--jerk-limited slows a spatial TOPP-RA plan to the jerk limits: use --method toppra on a "
                            f"spatial scenario ({args.method} on {args.scenario} does not take it; ruckig plans "
                            "jerk-limited motions itself)")


def cmd_plan(args) -> int:
    """`qmt-drake plan` on every scenario kind: the method and its options checked against the one
    registry (apps/plan_options.py) before any work, then the kind's planning and outputs."""
    kind = scenario_kind(args.scenario)
    row, options = checked_method(args, kind)
    _refuse_for_kind(args, kind)
    if kind == registry.SPATIAL:
        return 0 if spatial_cli.plan(args, row, options) else EXIT_INFEASIBLE
    if kind == registry.ENERGY:
        return plan_energy(args, options)
    check_outputs(args, "--json", "--trajectory-csv")
    check_int(args.seed, "--seed", 0, "seeds are non-negative integers")
    check_positive_finite(args.carried_max_scale, "--carried-max-scale", "e.g. 3: try up to 3x slower")
    cells = carried_cells_arg(args)
    if args.success is not None:  # the options and the uncertainty section, checked before any planning
        spatial_cli.check_success_options(args, load_scenario(args.scenario))
    if args.carried_max_scale <= 1:
        raise QmtInputError(f"--carried-max-scale {args.carried_max_scale:g} must exceed 1 (1 is the plan as planned)")
    sc = load_scenario(args.scenario)
    check_tray_method(sc, args.method)
    if args.carried:  # the slowest replay the search may run (at the scenario's motion-time bound)
        try:
            check_replay_budget(sc, args.carried_max_scale, allow_large=args.allow_large)
        except QmtInputError as exc:
            raise QmtInputError(f"--carried-max-scale {args.carried_max_scale:g}: {exc}") from None
        if cells is not None:  # each cell's step checked by the hand before any planning
            check_transfer_cells(sc, resolve_cells(cells, transfer_default_cell(sc)[0]), "--carried-cells")
    if args.checkpoint is not None:
        _check_checkpoint(args.checkpoint, sc, args.seed)
    options = check_plan_options(args.method, sc, options, where=FLAGS, allow_large=args.allow_large)
    plan = registry.plan(sc, args.method, seed=args.seed, progress=None if args.quiet else progress, **options)
    if args.carried:
        if not plan.feasible:
            raise QmtInputError(f"--carried: the {args.method} plan breaks a limit on the re-check; nothing to "
                                "time-scale (drop --carried to write the least-violating plan)")
        base = plan
        plan = plan_fastest_carried(sc, args.method, base_plan=plan, feedforward=args.carried_feedforward or "full",
                                    s_max=args.carried_max_scale, progress=None if args.quiet else progress)
        if cells is not None:  # raised until carried at every cell (carried_cells.py)
            plan = carried_transfer_plan_every_cell(sc, base, plan, cells, feedforward=args.carried_feedforward or "full",
                                                    s_max=args.carried_max_scale, progress=None if args.quiet else progress)
            if not args.quiet:
                every = plan.extra["carried_search"]["every_cell"]
                for line in every_cell_lines(every):
                    progress(line)
                progress(f"{sc.name} {args.method} x{every['time_scale']:.5f}{every_cell_text(every)}")
        search = plan.extra["carried_search"]
        lost = search.get("lost_below")
        search["margin"] = None if lost is None else search["chosen"] / lost - 1.0
        # the chosen plan at the next step size: reported (a flip too), not re-chosen
        search["half_step"] = search_half_step(sc, plan, feedforward=args.carried_feedforward or "full")
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
            plan, success = plan_for_success(plan, base_file, args.success_out, target=args.success,
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
              f"{'feasible' if plan.feasible else infeasible_text(plan)}, "
              f"{plan.planner_wall_s:.2f} s" + ("" if args.success is None else spatial_cli.success_text(
                  success["fresh_check"], success["search"]["time_scale"], args.success)))
    return 0 if plan.feasible else EXIT_INFEASIBLE


def infeasible_text(plan) -> str:
    """An infeasible plan's words: the planner's reason when it gave one (a method that found no timing writes
    the arm at rest, T0 = 0: that is no least-violating plan, and its 0.0000 ratios say nothing)."""
    reason = getattr(plan, "extra", {}).get("infeasible")
    if reason and plan.motion_time_s == 0.0:
        return f"INFEASIBLE, no timing found: {reason} (the file holds the arm at rest)"
    return "INFEASIBLE (least-violating plan" + (f": {reason})" if reason else ")")


def check_tray_method(sc, method: str) -> None:
    """One line when the scenario's hand plug-in refuses the method (hands.py)."""
    hand = hand_plugin(sc)
    if method in hand.refused_methods:
        usable = [m for m in registry.names(registry.TRANSFER) if m not in hand.refused_methods]
        raise QmtInputError(f"--method {method} is not available for the {hand.kind} scenario '{sc.name}' "
                            f"({hand.refused_methods[method]}); use {', '.join(usable[:-1])} or {usable[-1]}")
