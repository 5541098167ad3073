"""`qmt-drake plan` and `simulate` on a spatial (3-D) scenario (`kind: spatial_transfer`, spatial_task.py).

    qmt-drake plan ur5-suction-bins --method toppra|ruckig|family_optimum|ga|trajopt --json p.json
        [--family via_cubic|line_cubic_velocity|trapezoid_ptp (toppra, family_optimum, ga)] [--trajectory-csv p.csv]
        [--carried [--carried-max-scale K] [--carried-feedforward none|back-emf|full] [--carried-cells all|MS:APPROX,...]]
        [--seed N --generations G --stall S --checkpoint PATH] [--option KEY=VALUE] [--quiet]
    qmt-drake simulate ur5-suction-bins --plan p.json [--time-scale S] [--json out.json]

`plan` runs the registry's spatial rows (planners/registry.py -> planners/spatial_methods, spatial_search;
every result re-checked at 10x the check rate and slowed by the
smallest time scale that makes that check hold), prints one summary line (motion time, its ratio to
TOPP-RA's time-optimal duration on the family's path (via_cubic: the IK'd path), the re-check's largest ratio, the time scale applied)
and writes the plan file (planners/spatial_plan_io: rebuilds the trajectory exactly) and the CSV.
`--carried` then slows the plan to the fastest time scale the co-simulation carries
(planners/spatial_carried; Drake's inverse-dynamics controller, or with --carried-feedforward the
scenario's DC motors with that feedforward). Limits that no plan meets: exit 3 with the
least-violating plan written (the GA's best, a plan slowed as far as slowing helps), or, where no
timing exists at all (a path broken at rest), exit 3 and one line naming the binding limit. `simulate` loads a plan file back (refused in one line when made for
another scenario, or planar), or plans first with --method, and co-simulates it
(sim/spatial_cosim) printing the outcome word (outcome.py). A method or option this kind does not take
is refused by the registry in one line naming it; `optimum` is accepted for `family_optimum`.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

from qmt_drake.apps.arg_checks import (
    carried_cells_arg,
    check_int,
    check_outputs,
    check_positive_finite,
    emit_json,
    given,
    progress,
)
from qmt_drake.apps.plan_options import checked_method
from qmt_drake.budgets import (
    SPATIAL_REPLAY,
    announce,
    check_budget,
    path_time_lower_bound_s,
    replay_estimate,
    spatial_ga_estimate,
)
from qmt_drake.carried_cells import (
    check_spatial_cells,
    every_cell_lines,
    every_cell_text,
    resolve_cells,
    spatial_default_cell,
)
from qmt_drake.config.resolve import builtin_scenarios, kind_of
from qmt_drake.errors import QmtInputError
from qmt_drake.jerk import jerk_limited_plan, peak_jerk
from qmt_drake.margin import apart, margin_text
from qmt_drake.margin_runs import with_margin
from qmt_drake.outcome import verdict_line
from qmt_drake.outputs import check_output_dir, check_output_path, is_stdout, jsonable
from qmt_drake.planners import registry
from qmt_drake.planners.collision_free import collision_free_scenario
from qmt_drake.planners.spatial_carried import carried_plan, carried_search
from qmt_drake.planners.spatial_families import FAMILIES
from qmt_drake.planners.spatial_methods import METHODS, plan_toppra_spatial
from qmt_drake.planners.spatial_search import check_ga_checkpoint
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.retime import load_plan_file
from qmt_drake.sim.spatial_actuation import check_drive
from qmt_drake.sim.spatial_cosim import TAIL_S, check_spatial_time_step, simulate_spatial, spatial_time_step
from qmt_drake.spatial_data import parse_spatial_data
from qmt_drake.spatial_task import SPATIAL_KIND, build_spatial_scenario, load_spatial_scenario
from qmt_drake.sweep.budget import estimate_spatial_sweep, estimate_sweep
from qmt_drake.sweep.parameters import MOTOR_PARAMETERS
from qmt_drake.sweep.robust import plan_for_success, success_spec
from qmt_drake.sweep.spec import load_spec
from qmt_drake.sweep.stats import cases_to_certify, wilson_interval

SPATIAL_METHODS = METHODS
SPATIAL_FAMILIES = FAMILIES
# --explicit (dc_motor only, sim/spatial_actuation.check_drive): the law applies the loop's damping (PD and back
# EMF) itself, nothing folded into the plant as joint damping, as the planar --explicit
SIMULATE_REFUSED = ()
NOT_FOR_SPATIAL: dict = {}


def is_spatial_scenario(name_or_path) -> bool:
    """A built-in name or a YAML file with `kind: spatial_transfer`; never raises (a probe)."""
    return kind_of(name_or_path) == SPATIAL_KIND


def list_scenarios() -> None:
    """One line per built-in spatial scenario (for `qmt-drake scenarios`)."""
    for name in builtin_scenarios(SPATIAL_KIND):
        sc = load_spatial_scenario(name)
        print(f"{name:12s} {SPATIAL_KIND:20s} {sc.n_dof}-joint {sc.urdf.stem}, {sc.hand_kind} hand, payload "
              f"{sc.body.mass_kg * 1e3:.0f} g, {len(sc.poses_m)} task poses; plan with --method {'|'.join(METHODS)}")


def _refuse_given(args, refused, energy_options) -> None:
    wrong = [(f"--{d.replace('_', '-')}", NOT_FOR_SPATIAL[d]) for d, default in refused
             if getattr(args, d, default) != default]
    if wrong:
        raise QmtInputError(f"{wrong[0][0]}: not for spatial scenario {args.scenario} ({wrong[0][1]}); drop it")
    energy = given(args, energy_options)
    if energy:
        raise QmtInputError(f"{' '.join(energy)}: options of the energy-time planners; {args.scenario} is a "
                            "spatial scenario: drop them")


def _plan(args, sc, row, opts: dict):
    """The registry's `row` on sc with its checked options; the GA (the one spatial planner whose run
    time the user sizes) priced and its checkpoint checked first."""
    if row.name == "ga":
        d = row.options()
        size = {k: opts.get(k, d[k]["default"]) for k in ("population", "generations")}
        est = check_budget(spatial_ga_estimate(size["population"], size["generations"]),
                           allow_large=getattr(args, "allow_large", False))
        if not args.quiet:
            announce(est)
        if opts.get("checkpoint_path") is not None:
            check_output_path(opts["checkpoint_path"], "--checkpoint")
            try:
                check_ga_checkpoint(sc, opts["checkpoint_path"], seed=args.seed,
                                    **{k: v for k, v in opts.items() if k != "checkpoint_path"})
            except QmtInputError as exc:
                raise QmtInputError(f"--checkpoint: {exc}") from None
    if not args.quiet:
        progress(f"qmt-drake: planning {sc.name} with {row.name}")
    return registry.plan(sc, row.name, seed=args.seed, progress=None if args.quiet else progress, **opts)


def plan(args, row, opts: dict, scenario=None) -> bool:
    """`qmt-drake plan` on a spatial scenario (module docstring), `row` and `opts` the registry's method
    and options (apps/plan_options.checked_method); True when the written plan holds every limit on
    the re-check (False: the least-violating plan is written, exit 3). scenario: a SpatialScenario built
    elsewhere (energy/as_transfer: seed 001's arm), else args.scenario's."""
    method = row.name
    check_outputs(args, "--json", "--trajectory-csv")
    check_positive_finite(args.carried_max_scale, "--carried-max-scale", "e.g. 3: try up to 3x slower")
    if args.carried_max_scale <= 1:
        raise QmtInputError(f"--carried-max-scale {args.carried_max_scale:g} must exceed 1 (1 is the plan as planned)")
    check_int(args.seed, "--seed", 0, "seeds are non-negative integers")
    cells = carried_cells_arg(args)
    drive = carried_drive(args) if args.carried else ("ideal", "full")
    success = getattr(args, "success", None) is not None
    sc = drive_scenario(args.scenario, *drive, success=success) if scenario is None else scenario
    avoided = None
    if getattr(args, "avoid", None):  # the task becomes the certified collision-free path (planners/collision_free)
        check_positive_finite(args.avoid_margin, "--avoid-margin", "e.g. 0.005 (m)")
        check_int(args.avoid_tries, "--avoid-tries", 1, "plan at least one path")
        check_int(args.avoid_seed, "--avoid-seed", 0, "seeds are non-negative integers")
        sc, avoided = collision_free_scenario(sc, margin_m=args.avoid_margin, seed=args.avoid_seed,
                                              tries=args.avoid_tries, through=args.avoid)
        opts = {"clearance_m": args.avoid_margin, **opts} if method == "trajopt" else opts  # trajopt keeps that margin
    actuator, feedforward = carried_drive(args)
    if args.carried:  # priced before planning at the path's speed-limit bound, again after at the plan's duration
        check_drive(sc, actuator, feedforward)
        _check_carried_budget(args, path_time_lower_bound_s(sc.q_path_rad, sc.velocity_limit_rad_s))
        if cells is not None:  # each cell's step and approximation, before planning
            check_spatial_cells(resolve_cells(cells, spatial_default_cell(sc)[0]), "--carried-cells")
    check_success_options(args, sc)  # the uncertainty section, before any planning
    p = _plan(args, sc, row, opts)
    if avoided is not None:
        p = p.replace(extra={**p.extra, "collision_free_path": avoided})
    if getattr(args, "jerk_limited", False):  # qmt_drake/jerk.py: slowed until its jerk is within the limits
        p = jerk_limited_plan(sc, p)
    try:  # TOPP-RA's duration on the family's path: the bound (well under a second on a UR5)
        family = opts.get("family", "via_cubic")
        bound = p.raw_duration_s if method == "toppra" else plan_toppra_spatial(sc, family=family).raw_duration_s
    except QmtInputError:
        bound = None
    holds = p.recheck["max"] <= 1.0 and p.feasible  # feasible: also clear of the obstacles (limits/clearance.py)
    if (args.carried or getattr(args, "success", None) is not None) and not holds:
        raise QmtInputError(f"{'--carried' if args.carried else '--success'}: the {method} plan breaks a limit on the "
                            "re-check; nothing to time-scale (drop it to write the least-violating plan)")
    if args.carried:
        _check_carried_budget(args, p.duration_s)
        search = carried_search(sc, p, k_max=args.carried_max_scale, progress=None if args.quiet else progress,
                                actuator=actuator, feedforward=feedforward, cells=cells)
        if cells is not None and not args.quiet:
            for line in every_cell_lines(search["every_cell"]):
                progress(line)
        p = carried_plan(sc, p, search)
    if getattr(args, "success", None) is not None:
        p = _slow_for_success(args, sc, p)
    if args.json == "-":
        print(json.dumps(p.to_json_dict()))
    elif args.json:
        p.write_json(args.json)
    if args.trajectory_csv:
        p.write_csv(args.trajectory_csv)
    if not (is_stdout(args.json) or is_stdout(args.trajectory_csv)):  # stdout is the JSON or the CSV then
        print(summary_line(sc, p, bound) + _avoided_text(avoided) + ("" if holds else infeasible_text(p)))
    return holds


def infeasible_text(p) -> str:
    """Why a plan is infeasible: the binding limit when one breaks, else its collision (the limits then hold,
    and naming a limit at 0.9999 of itself would point the user at the wrong fix)."""
    if p.recheck["max"] > 1.0 or not p.clearance or p.clearance["clearance_m"] >= 0:
        return f"; INFEASIBLE (least-violating plan; binding limit {p.recheck['binding']} at {p.recheck['max']:.4g} of it)"
    return ("; INFEASIBLE (it collides with world.obstacles, every limit held; plan around them with --avoid or move "
            "the task)")


def _avoided_text(a) -> str:
    """The --avoid path in the summary line (planners/collision_free.py)."""
    return "" if a is None else (f"; along the collision-free path through the task's {a['through']} (seed "
                                 f"{a['seed']}, {a['vertices']} vertices, "
                                 f"certified >= {a['path_clearance_lower_bound_m']:.4f} m)")


def carried_drive(args) -> tuple[str, str]:
    """(actuator, feedforward) of the --carried search: Drake's inverse-dynamics controller (ideal) by
    default, the scenario's DC motors with --carried-feedforward none|back-emf|full given."""
    ff = getattr(args, "carried_feedforward", None)
    return ("ideal", "full") if ff is None else ("dc_motor", ff)


def drive_scenario(name, actuator: str, feedforward: str, explicit: bool = False, success: bool = False):
    """The built scenario, after check_drive's refusals that its plain data shows (an unknown drive, dc_motor
    without actuators.motor; success: motor parameters in its uncertainty section without actuators.motor):
    building the arm (URDF, IK of every path point) takes seconds on a big robot."""
    data = parse_spatial_data(name)
    if actuator != "dc_motor" or data.actuators.motor is None:  # then check_drive reads only these fields
        check_drive(SimpleNamespace(name=data.name, motor=None), actuator, feedforward, explicit)
    drawn = [p for p in (data.uncertainty or {}).get("parameters", {}) if p in MOTOR_PARAMETERS]
    if success and drawn and data.actuators.motor is None:  # (sweep/spatial_cases.check_spatial_spec, once built)
        raise QmtInputError(f"--success: scenario {data.name}'s uncertainty.parameters.{drawn[0]} scales its DC motors, "
                            "and it has no actuators.motor; add actuators.motor or drop that parameter")
    return build_spatial_scenario(data)


def _check_carried_budget(args, motion_time_s: float) -> None:
    """The slowest replay the carried search may run (--carried-max-scale x the motion time), priced."""
    est = replay_estimate(args.carried_max_scale, motion_time_s, cost=SPATIAL_REPLAY)
    check_budget(replace(est, what=f"--carried-max-scale {args.carried_max_scale:g}: {est.what}"),
                 allow_large=getattr(args, "allow_large", False))


def check_success_options(args, sc) -> None:
    """--success P (sweep/robust.plan_for_success on the scenario's uncertainty section): its flags and
    the section, checked in one line before planning."""
    if getattr(args, "success", None) is None:
        return
    if not 0 < args.success < 1:
        raise QmtInputError(f"--success {args.success:g} must be a probability in (0, 1), e.g. 0.9")
    if args.carried:
        raise QmtInputError("--carried and --success both choose the time scale; give one of them")
    check_int(args.success_check_cases, "--success-check-cases", 1, "e.g. 200")
    check_positive_finite(args.success_max_scale, "--success-max-scale", "e.g. 2")
    if args.success_max_scale <= 1:  # the search brackets (1, max]: refused there only after planning
        raise QmtInputError(f"--success-max-scale {args.success_max_scale:g} must exceed 1 (the slowest time scale "
                            "tried; 1 is the plan as planned), e.g. 2")
    check_output_dir(args.success_out, "--success-out")
    need = cases_to_certify(args.success)  # fewer cases can never certify it: the search would run to no end
    search_cases = success_spec(sc).n_cases
    if search_cases < need:
        raise QmtInputError(f"--success {args.success:g}: the scenario's uncertainty.monte_carlo.cases gives "
                            f"{search_cases} cases per time scale, and even all of them carried certify only a 95 % "
                            f"lower bound {wilson_interval(search_cases, search_cases)[0]:.3f}; give >= {need} cases")
    n = args.success_check_cases
    if n < need:
        raise QmtInputError(f"--success-check-cases {args.success_check_cases} cannot confirm P >= {args.success:g} "
                            f"(all carried: 95 % lower bound {wilson_interval(n, n)[0]:.3f}); "
                            f"give >= {need}")
    try:  # the fresh check's sweep (run after the plan and the search), its size and price checked now
        spec = success_spec(sc, cases=args.success_check_cases, name="success-check")
        raw = dict(spec.raw)
        raw["parameters"] = {**raw["parameters"], "time_scale": float(args.success_max_scale)}  # its slowest
        spec = load_spec(raw, name=spec.name)
        workers = os.cpu_count() or 1
        est = (estimate_spatial_sweep(spec, workers) if kind_of(spec.scenario) == registry.SPATIAL
               else estimate_sweep(spec, sc, workers))
        check_budget(est, allow_large=getattr(args, "allow_large", False))
    except QmtInputError as exc:
        raise QmtInputError(f"--success-check-cases {args.success_check_cases}: {exc}") from None


def _slow_for_success(args, sc, p):
    """The plan slowed to the fastest time scale whose P(carried) under the scenario's uncertainty has
    its 95 % Wilson lower bound >= --success (the plan and the controller from the nominal model, the
    plant drawn; resumable under --success-out), checked on fresh cases."""
    if p.recheck["max"] > 1.0:
        raise QmtInputError(f"--success: the {p.method} plan breaks a limit on the re-check; nothing to time-scale")
    with tempfile.TemporaryDirectory() as d:
        base = Path(d) / "base_plan.json"
        p.write_json(base)
        p, _ = plan_for_success(p, base, args.success_out, target=args.success, scenario=sc,
                                check_cases=args.success_check_cases, s_max=args.success_max_scale,
                                progress=None if args.quiet else progress)
    return p


def summary_line(sc, p, bound) -> str:
    ratio = f"{p.duration_s / bound:.4f} x the TOPP-RA bound {bound:.4f} s" if bound else "TOPP-RA bound n/a"
    line = (f"{sc.name} {p.method}: T = {p.duration_s:.4f} s ({ratio}), re-check max ratio {p.recheck['max']:.5f} "
            f"at {sc.recheck_rate_hz:g} Hz, time scale applied {p.hold_scale:.4f}, task poses within "
            f"{p.pose_error[:, 0].max():.1e} m, {p.planning_s:.2f} s")
    pj = peak_jerk(sc, p.trajectory, sc.recheck_rate_hz)
    line += f", peak jerk {pj['peak_jerk_ratio']:.3g} x the limit at {sc.recheck_rate_hz:g} Hz"
    if p.info.get("jerk_limited") == "box_filter":  # qmt_drake/jerk.py
        w = " + ".join(f"{x:.4f}" for x in p.info["jerk_filter_windows_s"])
        line += (f" (jerk-limited: TOPP-RA's timing filtered over {w} s and {p.info['jerk_time_scale']:.4f} x slower, "
                 f"from {p.info['duration_before_jerk_limit_s']:.4f} s)")
    elif p.info.get("jerk_limited"):
        line += (f" (jerk-limited: {p.info['jerk_time_scale']:.4f} x slower than {p.info['duration_before_jerk_limit_s']:.4f} s;"
                 f" not filtered: {p.info['jerk_filter_not_used']})")
    if p.clearance:
        c = p.clearance
        line += (f", clearance >= {c['clearance_m']:.4f} m (no obstacle nearer)" if c["clearance_pair"] is None else
                 f", clearance {c['clearance_m']:+.4f} m ({' vs '.join(c['clearance_pair'])} at "
                 f"{c['clearance_time_s']:.4f} s{'; COLLIDES' if c['clearance_m'] < 0 else ''})")
    s = p.info.get("carried_search")
    if s:
        lost = f", lost at x{s['lost_below']:.4f}" if s["lost_below"] else ", as planned"
        line += f"; carried in the co-simulation at x{s['chosen']:.4f}{lost}"
        if s.get("every_cell"):
            line += every_cell_text(s["every_cell"])
    ok = (p.info.get("success") or {}).get("fresh_check")
    if ok:
        line += success_text(ok, p.info["time_scale"], p.info["success"]["search"]["target"])
    return line


def success_text(check: dict, time_scale: float, target: float) -> str:
    """The --success fresh check in a summary line; a check that misses the target says so (the search's
    own cases met it, the fresh ones do not confirm it)."""
    text = (f"; P(carried) {check['carried']}/{check['cases']} on fresh cases, 95 % Wilson lower bound "
            f"{check['ci_low']:.3f} at x{time_scale:.4f}")
    if not check["meets_target"]:
        text += (f", BELOW the target {target:g}: not confirmed (more fresh cases, --success-check-cases, or a "
                 "slower plan)")
    return text


def simulate(args, energy_options=()) -> int:
    """`qmt-drake simulate` on a spatial scenario (module docstring); 0 whatever the outcome."""
    _refuse_given(args, SIMULATE_REFUSED, energy_options)
    check_outputs(args, "--json", "--record")
    check_positive_finite(args.time_scale, "--time-scale", "1 replays the plan as planned, 2 twice as slow")
    actuator = args.actuator or "ideal"
    feedforward = args.feedforward or "full"
    explicit = bool(getattr(args, "explicit", False))
    check_positive_finite(args.time_step_ms, "--time-step-ms", "the plant step in ms, e.g. 1 or 2")
    sc = drive_scenario(args.scenario, actuator, feedforward, explicit)
    h = None if args.time_step_ms is None else check_spatial_time_step(args.time_step_ms * 1e-3)
    if h is None and sc.simulation.plant.time_step is not None:  # the scenario's simulation.plant.time_step
        h = spatial_time_step(sc, None)
    check_drive(sc, actuator, feedforward, explicit, h)  # refusals (no motor constants, ...) before planning
    if args.plan:
        if args.seed != 0:
            raise QmtInputError("--seed: the plan file is already planned; drop --seed or --plan")
        p = load_plan_file(args.plan, sc)  # a retimed path's file too (retime.load_plan_file)
    else:
        row, opts = checked_method(args, SPATIAL_KIND)
        p = _plan(args, sc, row, opts)
    est = replace(replay_estimate(args.time_scale, p.duration_s, h, cost=SPATIAL_REPLAY),  # at its plant step
                  fix="use a time scale near 1 (the shipped plans are carried at 1-1.5) and the default 1 ms step")
    est = check_budget(est, allow_large=args.allow_large)
    if not args.quiet:
        announce(est)
    traj = p.trajectory if args.time_scale == 1.0 else TimeScaled(p.trajectory, args.time_scale)
    t0 = time.perf_counter()
    r = simulate_spatial(sc, traj, record_path=args.record, actuator=actuator, feedforward=feedforward, time_step_s=h,
                         explicit=explicit)
    wall = time.perf_counter() - t0
    r = with_margin(sc, p, r, expensive=bool(getattr(args, "margin", False)), time_scale=args.time_scale,
                    spatial_kw={"actuator": actuator, "feedforward": feedforward, "time_step_s": h, "explicit": explicit},
                    progress=None if args.quiet else progress)
    emit_json(jsonable({"scenario": sc.name, "method": p.method, "plan_file": args.plan, "time_scale": args.time_scale,
                        "time_step_s": h, "explicit": explicit, **r, "wall_s": wall}), args.json)
    if args.json != "-":
        print(f"{sc.name} {p.method} x{args.time_scale:g}: {verdict_line(r['outcome'], r.get('collided_at_s') or r['lost_at_s'])}, "
              f"T = {r['duration_s']:.4f} s, largest hand ratio while held {apart(r['max_grip_ratio_while_held'], 1.0)}, "
              f"goal error {r['final_goal_error_rad']:.1e} rad, {_where_the_part_ended(r)}, "
              f"real-time factor {(r['duration_s'] + TAIL_S) / wall:.2f}"
              + (f"; recording {args.record}" if args.record else ""))
        print(margin_text(r["margin"]))
    return 0


def _where_the_part_ended(r: dict) -> str:
    """The part's end position in the hand's own terms: off the cup or magnet face, or slid on the tray."""
    if "final_slide_m" in r:  # tray hand: the cup stands free on the tray
        return f"cup {r['final_slide_m']:.3g} m from its seat on the tray at the end"
    return f"part {r['part_distance_from_cup_at_end_m']:.3g} m from the hand at the end"

