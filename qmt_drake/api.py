"""The public Python surface: `from qmt_drake import load_scenario, plan_with, simulate, build_diagram, Plan`.

    sc = load_scenario("thesis-ch4")          # plain typed data (a built-in name or a YAML path)
    plan = plan_with("ga", sc, seed=0)        # a Plan, re-checked by sampling at the scenario's check rate
    result = simulate(sc, plan)               # the co-simulation summary: result["outcome"], ...
    td = build_diagram(sc, plan)              # the Drake Diagram, to compose further or run yourself

Every scenario kind goes through the same four calls and gives a Plan: transfer scenarios (a
Scenario), spatial (3-D) ones (`kind: spatial_transfer`: a SpatialScenario, plans are SpatialPlans)
and seed 001's energy-time ones (`kind: energy_time`: an Experiment, plans are EnergyPlans);
`load_plan` (qmt_drake.plan_files) reads the files of all three.

Units: SI throughout (m, s, rad, N m, kg); times in seconds, joint angles in radians.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat

import qmt_drake.builders  # noqa: F401  (registers the scenario's builders)
import qmt_drake.sweep.parameters  # noqa: F401  (registers the check of the scenario's uncertainty section)
from qmt_drake import api_checks as C
from qmt_drake.actuators import check_own_actuator
from qmt_drake.budgets import (
    SPATIAL_REPLAY,
    check_budget,
    check_energy_budget,
    check_plan_budget,
    check_replay_budget,
    replay_estimate,
    spatial_ga_estimate,
)
from qmt_drake.config.fields import show
from qmt_drake.config.resolve import kind_of
from qmt_drake.config.scenario import ENERGY_TIME_KIND, Scenario
from qmt_drake.energy.experiments import Experiment
from qmt_drake.energy.scenario import get_experiment, load_energy_scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import build_diagram as _build_diagram
from qmt_drake.hands import hand_plugin
from qmt_drake.margin_runs import with_margin
from qmt_drake.outputs import check_output_path
from qmt_drake.plan import ENERGY_PLAN_KIND, KIND_WORDS, SPATIAL_PLAN_KIND, Plan, a_kind
from qmt_drake.plan_files import load_plan as _load_plan
from qmt_drake.plan_files import scenario_kind_of
from qmt_drake.planners import registry
from qmt_drake.sim.cosim import CoSim, build_cosim, run
from qmt_drake.sim.spatial_actuation import check_drive
from qmt_drake.sim.spatial_cosim import check_spatial_time_step
from qmt_drake.spatial_task import SPATIAL_KIND, SpatialScenario, load_spatial_scenario
from qmt_drake.transfer_scenario import TransferScenario, build_transfer_scenario
from qmt_drake.transfer_scenario import load_scenario as _load_scenario

AnyScenario = TransferScenario | SpatialScenario | Experiment  # what load_scenario returns

__all__ = ["Plan", "Scenario", "build_diagram", "load_plan", "load_scenario", "plan_with", "simulate"]


def _kind_of_file(name_or_path: str | Path) -> str:
    """The `kind` of a built-in name's or a YAML path's file ('' when it is neither: the transfer loader
    then says why in one line)."""
    return kind_of(name_or_path)


@C.strict_call
def load_scenario(name_or_path: str | Path, overrides: dict | None = None) -> AnyScenario:
    """The scenario `name_or_path`: a built-in name (`qmt-drake scenarios` lists them: thesis-ch2/3/4,
    via5-ch4, crane-tray; ur5-suction-bins, ur5-magnet-part, panda-tray-cup; ohsaka-fig2/3/4) or the
    path of a YAML file, validated (a bad key or value raises QmtInputError with one line naming it
    and the fix). Returns a Scenario (transfer), a SpatialScenario (`kind: spatial_transfer`) or an
    Experiment (`kind: energy_time`). `overrides` is merged into the YAML mapping first, key by key, on
    every kind (e.g. {"limits": {"moment_limit_Nm": 6e-4}} on a transfer scenario, {"payload":
    {"mass_kg": 0.4}} on a spatial one), and checked as the file is."""
    C.path_arg(name_or_path, "load_scenario: name_or_path", "scenario YAML file, or a built-in scenario name")
    if overrides is not None and not isinstance(overrides, dict):
        raise QmtInputError(f"load_scenario: overrides {show(overrides)} must be a dict of sections, e.g. "
                            "{'limits': {'moment_limit_Nm': 6e-4}}")
    kind = _kind_of_file(name_or_path)
    if kind == SPATIAL_KIND:
        return load_spatial_scenario(name_or_path, overrides)
    if kind == ENERGY_TIME_KIND:
        return load_energy_scenario(name_or_path, overrides) if overrides else get_experiment(name_or_path)
    return _load_scenario(name_or_path, overrides)


def _scenario_arg(scenario: Any, where: str) -> AnyScenario:
    """A loaded scenario; a built-in name or a YAML path is loaded (load_scenario), anything else refused."""
    if isinstance(scenario, (TransferScenario, SpatialScenario, Experiment)):
        return scenario
    if isinstance(scenario, Scenario):  # plain data (load_scenario_data): built and checked here
        return build_transfer_scenario(scenario)
    if isinstance(scenario, (str, Path)):
        return load_scenario(scenario)
    raise QmtInputError(f"{where}: scenario {show(scenario)} is not a scenario; pass load_scenario(NAME_OR_PATH)")


def _priced(check: Callable, *args: Any, cli: bool = False, **kwargs: Any) -> None:
    """A budgets.py check whose refusal names the API's keyword (allow_large=True), not the CLI's flag."""
    try:
        check(*args, **kwargs)
    except QmtInputError as exc:
        raise QmtInputError(str(exc) if cli else str(exc).replace("--allow-large", "allow_large=True")) from None


def check_plan_options(method: str, sc: AnyScenario, options: dict, *, allow_large: bool = False,
                       where: str | dict = "plan_with option") -> dict:
    """A planner's options against its row of the one registry (planners/registry.check: the method on
    this kind, the options' names, types and ranges), and the run's budget (budgets.py), before any
    work; `where` names the options in the message (the CLI: its {option: flag} map). Returns the
    options under the planner's own keywords."""
    cli = isinstance(where, dict)
    kind = registry.kind_of_scenario(sc)
    row, opts = registry.check(kind, method, options, where)
    if kind == registry.SPATIAL and row.name == "ga":
        d = row.options()
        size = {k: opts.get(k, d[k]["default"]) for k in ("population", "generations")}
        _priced(check_budget, spatial_ga_estimate(size["population"], size["generations"]), allow_large=allow_large, cli=cli)
    elif kind == registry.ENERGY and isinstance(sc, Experiment):  # (the kind says so; mypy needs the type)
        _priced(check_energy_budget, opts.get("m") or sc.m, opts.get("divisions") or sc.divisions,
                allow_large=allow_large, cli=cli)
    elif kind == registry.TRANSFER:  # the scenario's rates, and the GA's size
        _priced(check_plan_budget, sc, row.name, opts.get("max_generations"), allow_large=allow_large, cli=cli)
    return opts


@C.strict_call
def plan_with(method: str, scenario: AnyScenario, *, seed: int = 0, progress: Callable[[str], None] | None = None,
              allow_large: bool = False, **options: Any) -> Plan:
    """Plan `scenario` with `method` and return a Plan whose `feasible`, peaks and ratios come from
    re-sampling the trajectory, not from the planner: plan.motion_time_s [s], plan.sample(t) ->
    (q [rad], qd [rad/s], qdd [rad/s^2]), plan.summary(), plan.write_json(path). Every method of every
    kind is a row of the one registry (planners/registry.METHODS; registry.rows(kind) lists them with
    their typed options, Method.options()).
    Transfer scenarios: "ga" (the binary GA over the scenario's trajectory family), "optimum" (the
    family's deterministic best), "thesis" (the reported genes), "toppra", "ruckig", "trajopt"
    (time-optimal baselines under the same limits), re-checked at the scenario's check rate (10 kHz).
    Spatial scenarios: "toppra", "ruckig", "family_optimum" (or "optimum"), "ga", "trajopt",
    re-checked at 10x the check rate; toppra, family_optimum and ga take family="via_cubic" |
    "line_cubic_velocity" | "trapezoid_ptp" (planners/spatial_families.py); the GA takes
    checkpoint_path (resumable, as the transfer GA's). Energy-time scenarios: "snopt", "ipopt",
    "steepest", "collocation"; options c1, c2, m, divisions, coords [m], pattern, max_iter. Limits
    that no plan meets: the least-violating plan (plan.feasible False) where one exists, else
    QmtNoPlanError (errors.py) naming the binding limit. seed: the GA's generator (and the optimum's);
    progress: a callable taking one line of text; options: the planner's keywords (e.g.
    max_generations or generations for a GA, jerk_limit [m/s^3] for Ruckig). `scenario` may be a
    built-in name or a YAML path (loaded first). Every argument is checked first (types, ranges, the
    options' names) and the run priced as the CLI prices it (budgets.py): over the budget raises
    QmtInputError unless allow_large=True."""
    scenario = _scenario_arg(scenario, "plan_with")
    if not isinstance(method, str):
        raise QmtInputError(f"plan_with: method {show(method)} must be a planner's name (a str)")
    C.number(seed, "plan_with: seed", minimum=0, integer=True, fix="seeds are non-negative integers")
    if progress is not None and not callable(progress):
        raise QmtInputError(f"plan_with: progress {show(progress)} must be a callable taking one line, or None")
    if not isinstance(allow_large, bool):
        raise QmtInputError(f"plan_with: allow_large {show(allow_large)} must be True or False")
    check_plan_options(method, scenario, options, allow_large=allow_large)
    plan: Plan = registry.plan(scenario, method, seed=seed, progress=progress, **options)
    return plan


@C.strict_call
def load_plan(path: str | Path, scenario: AnyScenario | None = None) -> Plan:
    """Read a plan file of any scenario kind (plan_files.load_plan: refused in one line when it does not
    fit `scenario`); `scenario` None reloads the plan's own scenario, a name or a path is loaded."""
    C.path_arg(path, "load_plan: path", "plan file (JSON)")
    return _load_plan(path, None if scenario is None else _scenario_arg(scenario, "load_plan"))


def _check_plan_kind(scenario: AnyScenario, plan: Plan) -> None:
    """One line unless `plan` is a plan of this scenario's kind made for a scenario of this name (a
    transfer plan's fit is checked by its end points, hands.run_simulate; any Motion passes here)."""
    if not isinstance(plan, Plan):
        raise QmtInputError(f"plan {show(plan)} is not a Plan; pass plan_with(METHOD, scenario) or load_plan(PATH)")
    kind = scenario_kind_of(scenario)
    if getattr(plan, "scenario_kind", kind) != kind or (kind != "transfer" and plan.scenario.name != scenario.name):
        raise QmtInputError(f"the {plan.method} plan is {a_kind(plan.scenario_kind)} plan for scenario "
                            f"{plan.scenario.name}, not for the {KIND_WORDS[kind]} scenario {scenario.name}; "
                            "plan this scenario with plan_with")


def _check_run_args(scenario: AnyScenario, plan: Plan, time_scale: Any, time_step_s: Any, record_path: Any,
                    allow_large: Any, where: str) -> None:
    """simulate's and build_diagram's shared arguments, and the replay's budget (budgets.py) before it runs."""
    _check_plan_kind(scenario, plan)
    C.number(time_scale, f"{where}: time_scale", positive=True, fix="1 replays the plan as planned, 2 twice as slow")
    if time_step_s is not None:
        C.number(time_step_s, f"{where}: time_step_s", positive=True, maximum=0.1,
                 fix="the plant step [s], e.g. 0.002 (None: the scenario's stable default)")
    if record_path is not None:
        C.path_arg(record_path, f"{where}: record_path", "HTML recording")
        check_output_path(record_path, f"{where}: record_path")  # a folder, an unwritable place: before the run
    if not isinstance(allow_large, bool):
        raise QmtInputError(f"{where}: allow_large {show(allow_large)} must be True or False")
    if isinstance(scenario, TransferScenario):
        _priced(check_replay_budget, scenario, time_scale, time_step_s, motion_time_s=plan.motion_time_s,
                allow_large=allow_large)
    elif isinstance(scenario, SpatialScenario):
        _priced(check_budget, replay_estimate(time_scale, plan.motion_time_s, time_step_s, cost=SPATIAL_REPLAY),
                allow_large=allow_large)


@C.strict_call
def simulate(scenario: AnyScenario, plan: Plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
             feedforward: str | None = None, actuator: str | None = None, record_path: str | Path | None = None,
             allow_large: bool = False, margin: bool = False) -> dict:
    """Execute `plan` in the Drake co-simulation of `scenario` (magnet hand: DC motors with gears,
    PID, the magnet and the part in friction contact; tray: the Dynamixel servos and the bottle
    standing free; spatial arms: Drake's inverse-dynamics controller on ideal joint torques, the part
    held by cup, magnet or tray; energy-time: the vertical arm under inverse-dynamics control) and
    return its summary (the CLI's JSON): "outcome" (carried / slipped / detached / slid_off / tipped /
    unfinished, qmt_drake/outcome.py), "held" (outcome == carried), "max_slip_m",
    "final_goal_error_rad", "max_tracking_error_rad", ... (energy-time: "reached_goal",
    "max_tracking_error_rad", "final_error_rad"). time_scale: replay the plan time_scale times slower
    (< 1 faster); time_step_s: the plant step [s] (default: the scenario's stable default);
    feedforward: "none" (default), "back-emf" or "full" (DC motors; spatial dc_motor: "full" default,
    "gravity", ...); actuator: spatial: "ideal" (default) or "dc_motor" (the scenario's
    actuators.motor constants), planar: only the YAML's own actuator (dc_motor, ideal) as in the CLI;
    record_path: write a Meshcat HTML replay there. A plan made for
    another scenario, an unstable step, a bad option or a replay over the budget (budgets.py; unless
    allow_large=True) raises QmtInputError (one line) before anything runs; the spatial and
    energy-time runs take time_scale (spatial) and record_path only. Every result holds "margin": the
    verdict's deciding quantity against its threshold (qmt_drake/margin.py); margin=True also searches the
    time scale at which the verdict flips (to 0.5 %, at most 12 more runs) and runs the plan at half the
    plant step ("flip", "half_step"; not for energy-time plans)."""
    scenario = _scenario_arg(scenario, "simulate")
    for name, value in (("feedforward", feedforward), ("actuator", actuator)):
        if value is not None and not isinstance(value, str):
            raise QmtInputError(f"simulate: {name} {show(value)} must be a str (or None: the default)")
    if isinstance(scenario, SpatialScenario):  # the drive's refusals (no motor constants, ...) first
        check_drive(scenario, actuator or "ideal", feedforward or "full")
    _check_run_args(scenario, plan, time_scale, time_step_s, record_path, allow_large, "simulate")
    if not isinstance(margin, bool):
        raise QmtInputError(f"simulate: margin {show(margin)} must be True or False")
    if isinstance(scenario, TransferScenario):
        own = check_own_actuator(scenario, actuator, "simulate: actuator")  # as the CLI: only its YAML's own one
        result = run(build_cosim(scenario, plan, time_scale=time_scale, record_path=record_path,
                                 time_step_s=time_step_s, implicit_loop_damping=None,
                                 feedforward=feedforward or "none"))
        if actuator is not None:  # the result says which was run, as the CLI's does
            result = {**result, "actuator": actuator, "actuator_kind": own}
        return with_margin(scenario, plan, result, expensive=margin, time_scale=time_scale, time_step_s=time_step_s,
                           feedforward=feedforward or "none")
    spatial = plan.scenario_kind == SPATIAL_PLAN_KIND
    for name, given in (("feedforward", feedforward is not None and not spatial),
                        ("actuator", actuator is not None and not spatial),
                        ("time_scale", plan.scenario_kind == ENERGY_PLAN_KIND and time_scale != 1.0)):
        if given:
            raise QmtInputError(f"{name}: the {KIND_WORDS[plan.scenario_kind]} co-simulation of {scenario.name} "
                                f"does not take it; drop {name}")
    if spatial:
        actuator, feedforward = actuator or "ideal", feedforward or "full"
        check_spatial_time_step(time_step_s)
        result = run(build_cosim(scenario, plan, time_scale=time_scale, record_path=record_path, actuator=actuator,
                                 feedforward=feedforward, time_step_s=time_step_s))
        return with_margin(scenario, plan, result, expensive=margin, time_scale=time_scale,
                           spatial_kw={"actuator": actuator, "feedforward": feedforward, "time_step_s": time_step_s})
    return with_margin(scenario, plan, run(build_cosim(scenario, plan, record_path=record_path, time_step_s=time_step_s)),
                       expensive=margin)


@C.strict_call
def build_diagram(scenario: AnyScenario, plan: Plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
                  meshcat: Meshcat | None = None, allow_large: bool = False, **options: Any) -> CoSim:
    """The co-simulation of `plan` on `scenario`, built and not run: a CoSim (qmt_drake/sim/cosim.py) whose
    .diagram is a Drake Diagram to compose in your own DiagramBuilder or run with your own Simulator,
    .plant its MultibodyPlant, .ports and .loggers its named signals; `qmt_drake.sim.cosim.run(cosim)` runs
    it as `simulate` does. Magnet scenarios: sim.build_transfer_diagram (options: its keywords, e.g.
    inverse_dynamics_feedforward=True, coil_current_A; the CoSim answers the TransferDiagram's attributes,
    cosim.t_final_s, cosim.summary(context)); tray scenarios: tray.cosim.build_tray_diagram with the plan
    streamed to the servos every servo period; spatial scenarios (options: actuator, feedforward as in
    `simulate`): the arm, its hand and drive with the ports desired_state, arm_state, body_poses and the
    part's (part_state, or cup_state on a tray) exported, the default context at the plan's start with the
    part seated (on your own Simulator the weld holds: its release at the first step past the hand's limit
    is run's, from cosim.monitor's logs); energy-time scenarios: the vertical arm's diagram (no option).
    time_scale and time_step_s [s] as in `simulate` (checked the same way, the replay priced); meshcat: a
    pydrake Meshcat to draw in (planar scenarios). Compose it with discrete-time systems (or none): its
    per-step laws are Drake SymbolicVectorSystems, which Drake 1.51 cannot ask for time derivatives, so a
    Simulator of a diagram that also holds continuous state (an Integrator of yours) stops with
    "DoCalcTimeDerivatives(): condition ... failed"."""
    scenario = _scenario_arg(scenario, "build_diagram")
    _check_run_args(scenario, plan, time_scale, time_step_s, None, allow_large, "build_diagram")
    if meshcat is not None and not isinstance(meshcat, Meshcat):
        raise QmtInputError(f"build_diagram: meshcat {show(meshcat)} must be a pydrake Meshcat (or None)")
    if not isinstance(scenario, TransferScenario):
        if meshcat is not None:
            raise QmtInputError(f"build_diagram: meshcat: the {KIND_WORDS[scenario_kind_of(scenario)]} co-simulation "
                                "draws only into its own recording; record with simulate(..., record_path=PATH)")
        if isinstance(scenario, SpatialScenario):
            unknown = sorted(set(options) - {"actuator", "feedforward"})
            if unknown:
                raise QmtInputError(f"build_diagram option {unknown[0]}: the spatial co-simulation takes actuator "
                                    "and feedforward")
            check_drive(scenario, options.get("actuator") or "ideal", options.get("feedforward") or "full")
            check_spatial_time_step(time_step_s)
            return build_cosim(scenario, plan, time_scale=time_scale, time_step_s=time_step_s, export=True, **options)
        if options:
            raise QmtInputError(f"build_diagram option {sorted(options)[0]}: the energy-time co-simulation takes none")
        return build_cosim(scenario, plan, time_scale=time_scale, time_step_s=time_step_s)
    C.check_options(hand_plugin(scenario).build_diagram, options, "build_diagram option",
                    f"the {hand_plugin(scenario).kind} hand's diagram",
                    skip=("scenario", "plan", "time_scale", "time_step_s", "meshcat"))
    try:
        return _build_diagram(scenario, plan, time_scale=time_scale, time_step_s=time_step_s, meshcat=meshcat,
                              **options)
    except TypeError as exc:  # a plug-in taking **options passes them on: an unknown one surfaces here
        if "unexpected keyword argument" not in str(exc):
            raise
        raise QmtInputError(f"build_diagram: {exc}; see the hand's diagram builder for its options") from None
