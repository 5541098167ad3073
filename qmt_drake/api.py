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

import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat

import qmt_drake.builders  # noqa: F401  (registers the scenario's builders)
import qmt_drake.sweep.parameters  # noqa: F401  (registers the check of the scenario's uncertainty section)
from qmt_drake.config.resolve import kind_of
from qmt_drake.config.scenario import ENERGY_TIME_KIND, Scenario
from qmt_drake.config.scenario import load_scenario as _load_scenario
from qmt_drake.energy.energy_plan import EnergyPlan, plan_energy_time
from qmt_drake.energy.execute import execute_plan
from qmt_drake.energy.experiments import Experiment
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import build_diagram as _build_diagram
from qmt_drake.hands import run_simulate
from qmt_drake.margin_runs import with_margin
from qmt_drake.plan import KIND_WORDS, Plan, a_kind
from qmt_drake.plan_files import load_plan, scenario_kind_of
from qmt_drake.planners import plan_with as _plan_with
from qmt_drake.planners.spatial_methods import ALIASES as SPATIAL_ALIASES
from qmt_drake.planners.spatial_methods import METHODS as SPATIAL_METHODS
from qmt_drake.planners.spatial_methods import PLANNERS as SPATIAL_PLANNERS
from qmt_drake.planners.spatial_plan_io import SpatialPlan
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.diagram import TransferDiagram
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import SPATIAL_KIND, SpatialScenario, load_spatial_scenario
from qmt_drake.tray.cosim import TrayDiagram

AnyScenario = Scenario | SpatialScenario | Experiment

__all__ = ["Plan", "Scenario", "build_diagram", "load_plan", "load_scenario", "plan_with", "simulate"]


def _kind_of_file(name_or_path: str | Path) -> str:
    """The `kind` of a built-in name's or a YAML path's file ('' when it is neither: the transfer loader
    then says why in one line)."""
    return kind_of(name_or_path)


def load_scenario(name_or_path: str | Path, overrides: dict | None = None) -> AnyScenario:
    """The scenario `name_or_path`: a built-in name (`qmt-drake scenarios` lists them: thesis-ch2/3/4,
    via5-ch4, crane-tray; ur5-suction-bins, ur5-magnet-part, panda-tray-cup; ohsaka-fig2/3/4) or the
    path of a YAML file, validated (a bad key or value raises QmtInputError with one line naming it
    and the fix). Returns a Scenario (transfer), a SpatialScenario (`kind: spatial_transfer`) or an
    Experiment (`kind: energy_time`). `overrides` (transfer scenarios only) is merged into the YAML
    mapping first, key by key (e.g. {"limits": {"moment_limit_Nm": 6e-4}})."""
    kind = _kind_of_file(name_or_path)
    if kind in (SPATIAL_KIND, ENERGY_TIME_KIND):
        if overrides:
            raise QmtInputError(f"overrides: scenario {name_or_path} is {a_kind(kind)} scenario; overrides apply to "
                                "transfer scenarios: edit a copy of its YAML file (energy-time weights are "
                                "plan_with options: c1, c2, m, divisions)")
        return load_spatial_scenario(name_or_path) if kind == SPATIAL_KIND else get_experiment(name_or_path)
    return _load_scenario(name_or_path, overrides)


def plan_with(method: str, scenario: AnyScenario, *, seed: int = 0, progress: Callable[[str], None] | None = None,
              **options: Any) -> Plan:
    """Plan `scenario` with `method` and return a Plan whose `feasible`, peaks and ratios come from
    re-sampling the trajectory, not from the planner: plan.motion_time_s [s], plan.sample(t) ->
    (q [rad], qd [rad/s], qdd [rad/s^2]), plan.summary(), plan.write_json(path).
    Transfer scenarios: "ga" (the binary GA over the scenario's trajectory family), "optimum" (the
    family's deterministic best), "thesis" (the reported genes), "toppra", "ruckig", "trajopt"
    (time-optimal baselines under the same limits), re-checked at the scenario's check rate (10 kHz).
    Spatial scenarios (a SpatialPlan): "toppra", "ruckig", "family_optimum" (or "optimum"), "ga",
    "trajopt", re-checked at 10x the check rate; toppra, family_optimum and ga take
    family="via_cubic" | "line_cubic_velocity" | "trapezoid_ptp" (planners/spatial_families.py). Energy-time scenarios (an EnergyPlan, the lowest
    cost of the multi-start): "snopt", "ipopt", "steepest", "collocation"; options c1, c2, m,
    divisions, coords [m], pattern, max_iter. seed: the GA's generator (and the optimum's); progress:
    a callable taking one line of text; options: the planner's keywords (e.g. max_generations for the
    transfer GA, jerk_limit [m/s^3] for Ruckig, generations for the spatial GA)."""
    if isinstance(scenario, SpatialScenario):
        m = SPATIAL_ALIASES.get(method, method)
        if m not in SPATIAL_PLANNERS:
            raise QmtInputError(f"method {method!r} does not plan spatial scenarios; use {'|'.join(SPATIAL_METHODS)}")
        if m == "ga":
            options = {"seed": seed, "progress": progress, **options}
        known = [k for k in inspect.signature(SPATIAL_PLANNERS[m]).parameters if k != "sc"]
        unknown = sorted(set(options) - set(known))
        if unknown:
            raise QmtInputError(f"option {unknown[0]!r}: the spatial {m} planner takes "
                                f"{', '.join(known) or 'no options'}"
                                + (" (family: only toppra, family_optimum and ga take one)" if unknown[0] == "family"
                                   else ""))
        plan: Plan = SPATIAL_PLANNERS[m](scenario, **options)
        return plan
    if isinstance(scenario, Experiment):
        return plan_energy_time(scenario, method, progress=progress, **options)
    return _plan_with(method, scenario, seed=seed, progress=progress, **options)


def _check_plan_kind(scenario: AnyScenario, plan: Plan) -> None:
    """One line unless `plan` is a plan of this scenario's kind made for a scenario of this name (a
    transfer plan's fit is checked by its end points, hands.run_simulate; any Motion passes here)."""
    kind = scenario_kind_of(scenario)
    if getattr(plan, "scenario_kind", kind) != kind or (kind != "transfer" and plan.scenario.name != scenario.name):
        raise QmtInputError(f"the {plan.method} plan is {a_kind(plan.scenario_kind)} plan for scenario "
                            f"{plan.scenario.name}, not for the {KIND_WORDS[kind]} scenario {scenario.name}; "
                            "plan this scenario with plan_with")


def simulate(scenario: AnyScenario, plan: Plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
             feedforward: str = "none", record_path: str | Path | None = None, margin: bool = False) -> dict:
    """Execute `plan` in the Drake co-simulation of `scenario` (magnet hand: DC motors with gears,
    PID, the magnet and the part in friction contact; tray: the Dynamixel servos and the bottle
    standing free; spatial arms: Drake's inverse-dynamics controller on ideal joint torques, the part
    held by cup, magnet or tray; energy-time: the vertical arm under inverse-dynamics control) and
    return its summary (the CLI's JSON): "outcome" (carried / slipped / detached / slid_off / tipped /
    unfinished, qmt_drake/outcome.py), "held" (outcome == carried), "max_slip_m",
    "final_goal_error_rad", "max_tracking_error_rad", ... (energy-time: "reached_goal",
    "max_tracking_error_rad", "final_error_rad"). time_scale: replay the plan time_scale times slower
    (< 1 faster); time_step_s: the plant step [s] (default: the scenario's stable default);
    feedforward: "none", "back-emf" or "full" (DC motors); record_path: write a Meshcat HTML replay
    there. Every result holds "margin": the verdict's deciding quantity against its threshold
    (qmt_drake/margin.py); margin=True also searches the time scale at which the verdict flips (to
    0.5 %, at most 12 more runs) and runs the plan at half the plant step ("flip", "half_step";
    not for energy-time plans). A plan made for another scenario, an unstable step or a bad option raises QmtInputError
    (one line) before anything runs; the spatial and energy-time runs take time_scale (spatial) and
    record_path only."""
    _check_plan_kind(scenario, plan)
    if not isinstance(margin, bool):
        raise QmtInputError(f"margin {margin!r} must be True or False")
    if isinstance(scenario, Scenario):
        return with_margin(scenario, plan, run_simulate(scenario, plan, time_scale=time_scale, record_path=record_path,
                                                        time_step_s=time_step_s, implicit_loop_damping=None,
                                                        feedforward=feedforward),
                           expensive=margin, time_scale=time_scale, time_step_s=time_step_s, feedforward=feedforward)
    for name, given in (("time_step_s", time_step_s is not None), ("feedforward", feedforward != "none"),
                        ("time_scale", isinstance(plan, EnergyPlan) and time_scale != 1.0)):
        if given:
            raise QmtInputError(f"{name}: the {KIND_WORDS[plan.scenario_kind]} co-simulation of {scenario.name} "
                                f"does not take it; drop {name}")
    if isinstance(plan, SpatialPlan):
        if not (time_scale > 0 and time_scale < float("inf")):
            raise QmtInputError(f"time_scale {time_scale!r} must be a finite positive number (1: as planned)")
        traj = plan.trajectory if time_scale == 1.0 else TimeScaled(plan.trajectory, time_scale)
        return with_margin(scenario, plan, simulate_spatial(scenario, traj, record_path=record_path), expensive=margin,
                           time_scale=time_scale)
    return with_margin(scenario, plan, execute_plan(plan, record_path=record_path), expensive=margin)


def build_diagram(scenario: AnyScenario, plan: Plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
                  meshcat: Meshcat | None = None, **options: Any) -> TransferDiagram | TrayDiagram:
    """The co-simulation Diagram of `plan` on `scenario`, ready to run: td.diagram (a Drake Diagram
    whose default context starts at the plan's start with the part seated), td.plant, and the
    exported ports and loggers its docstring lists. Magnet scenarios: sim.build_transfer_diagram
    (options: its keywords, e.g. inverse_dynamics_feedforward=True, coil_current_A); tray
    scenarios: tray.cosim.build_tray_diagram with the plan streamed to the servos every servo
    period. time_scale and time_step_s [s] as in `simulate`; meshcat: a pydrake Meshcat to draw in.
    Transfer scenarios only (spatial and energy-time ones run through `simulate`)."""
    if not isinstance(scenario, Scenario):
        kind = scenario_kind_of(scenario)
        raise QmtInputError(f"build_diagram composes transfer scenarios; {scenario.name} is {a_kind(kind)} one: "
                            "run it with simulate(scenario, plan)")
    return _build_diagram(scenario, plan, time_scale=time_scale, time_step_s=time_step_s, meshcat=meshcat, **options)
