"""The public Python surface: `from qmt_drake import load_scenario, plan_with, simulate, build_diagram, Plan`.

    sc = load_scenario("thesis-ch4")          # plain typed data (a built-in name or a YAML path)
    plan = plan_with("ga", sc, seed=0)        # a Plan, re-checked by sampling at the scenario's check rate
    result = simulate(sc, plan)               # the co-simulation summary: result["outcome"], ...
    td = build_diagram(sc, plan)              # the Drake Diagram, to compose further or run yourself

Units: SI throughout (m, s, rad, N m, kg); times in seconds, joint angles in radians.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat

import qmt_drake.builders  # noqa: F401  (registers the scenario's builders)
import qmt_drake.sweep.parameters  # noqa: F401  (registers the check of the scenario's uncertainty section)
from qmt_drake.config.scenario import Scenario
from qmt_drake.config.scenario import load_scenario as _load_scenario
from qmt_drake.hands import build_diagram as _build_diagram
from qmt_drake.hands import run_simulate
from qmt_drake.plan import Plan
from qmt_drake.planners import plan_with as _plan_with
from qmt_drake.sim.diagram import TransferDiagram
from qmt_drake.tray.cosim import TrayDiagram

__all__ = ["Plan", "Scenario", "build_diagram", "load_scenario", "plan_with", "simulate"]


def load_scenario(name_or_path: str | Path, overrides: dict | None = None) -> Scenario:
    """The scenario `name_or_path`: a built-in name (`qmt-drake scenarios` lists them: thesis-ch2/3/4,
    via5-ch4, crane-tray, ...) or the path of a YAML file, validated (a bad key or value raises
    QmtInputError with one line naming it and the fix). `overrides` is merged into the YAML mapping
    first, key by key (e.g. {"limits": {"moment_limit_Nm": 6e-4}}). Energy-time experiments
    (ohsaka-fig2/3/4) are planned through the CLI (`qmt-drake plan ohsaka-fig3 --method snopt`)."""
    return _load_scenario(name_or_path, overrides)


def plan_with(method: str, scenario: Scenario, *, seed: int = 0, progress: Callable[[str], None] | None = None,
              **options: Any) -> Plan:
    """Plan `scenario` with `method`: "ga" (the binary GA over the scenario's trajectory family),
    "optimum" (the family's deterministic best), "thesis" (the reported genes), "toppra", "ruckig",
    "trajopt" (time-optimal baselines under the same limits). seed: the GA's generator; progress: a
    callable taking one line of text; options: the planner's keywords (e.g. max_generations for the
    GA, jerk_limit [m/s^3] for Ruckig). Returns a Plan whose `feasible`, peaks and ratios come from
    re-sampling the trajectory at the scenario's check rate (10 kHz), not from the planner;
    plan.motion_time_s [s], plan.sample(t) -> (q [rad], qd [rad/s], qdd [rad/s^2])."""
    return _plan_with(method, scenario, seed=seed, progress=progress, **options)


def simulate(scenario: Scenario, plan: Plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
             feedforward: str = "none", record_path: str | Path | None = None) -> dict:
    """Execute `plan` in the Drake co-simulation of `scenario` (magnet hand: DC motors with gears,
    PID, the magnet and the part in friction contact; tray: the Dynamixel servos and the bottle
    standing free) and return its summary (the CLI's JSON): "outcome" (carried / slipped /
    detached / slid_off / tipped / unfinished, qmt_drake/outcome.py), "held" (outcome == carried),
    "max_slip_m", "final_goal_error_rad", "max_tracking_error_rad", "real_time_factor", ...
    time_scale: replay the plan time_scale times slower (< 1 faster); time_step_s: the plant step
    [s] (default: the scenario's stable default); feedforward: "none", "back-emf" or "full" (DC
    motors); record_path: write a Meshcat HTML replay there. A plan made for another scenario, an
    unstable step or a bad option raises QmtInputError (one line) before anything runs."""
    return run_simulate(scenario, plan, time_scale=time_scale, record_path=record_path, time_step_s=time_step_s,
                        implicit_loop_damping=None, feedforward=feedforward)


def build_diagram(scenario: Scenario, plan: Plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
                  meshcat: Meshcat | None = None, **options: Any) -> TransferDiagram | TrayDiagram:
    """The co-simulation Diagram of `plan` on `scenario`, ready to run: td.diagram (a Drake Diagram
    whose default context starts at the plan's start with the part seated), td.plant, and the
    exported ports and loggers its docstring lists. Magnet scenarios: sim.build_transfer_diagram
    (options: its keywords, e.g. inverse_dynamics_feedforward=True, coil_current_A); tray
    scenarios: tray.cosim.build_tray_diagram with the plan streamed to the servos every servo
    period. time_scale and time_step_s [s] as in `simulate`; meshcat: a pydrake Meshcat to draw in."""
    return _build_diagram(scenario, plan, time_scale=time_scale, time_step_s=time_step_s, meshcat=meshcat, **options)
