"""Hand plug-ins: each hand kind registers once what it adds to the limit set, what it welds to the
planning arm, and how its transfer is co-simulated and built as a Drake Diagram.

    magnet  the thesis's electromagnetic hand (seed 000): the payload-moment term; DC motors or
            ideal actuators with PID; sim/ builds and runs the diagram
    tray    seed 002's tray with a bottle standing free: slide / tip / lift-off terms; the CRANE-X7's
            Dynamixel servos; tray/ builds and runs the diagram

`hand_plugin(scenario)` looks a scenario's hand up; `run_simulate` and `build_diagram` dispatch on
it, so the core (sim/, builders.py) holds no `is_tray` branch and seed packages only plug in.
A new hand (e.g. a suction cup on a spatial arm) is one `register_hand` call.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat

from qmt_drake.config.scenario import DynamixelServos, Scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.limits import PayloadMomentTerm
from qmt_drake.plan import Motion, check_plan_fits
from qmt_drake.sim.diagram import TransferDiagram, build_transfer_diagram
from qmt_drake.sim.runner import run_transfer_simulate
from qmt_drake.systems.payload import PayloadSpec
from qmt_drake.tray.cosim import TrayDiagram, build_tray_diagram
from qmt_drake.tray.execute import (
    TRAY_CASE_PARAMETERS,
    check_tray_simulation,
    drawn_bottle_overrides,
    plan_schedule,
    simulate_tray_plan,
)
from qmt_drake.tray.limit_terms import tray_terms


@dataclass(frozen=True)
class HandPlugin:
    """What one hand kind adds. limit_terms(scenario, arm) -> the hand's limit terms (before the
    motor torques); carried_inertia(scenario) -> the Drake SpatialInertia welded to the planning
    arm's hand; simulate(scenario, plan, **options) -> the co-simulation summary (the CLI's JSON);
    build_diagram(scenario, plan, **options) -> the diagram; refused_methods: planners that cannot
    serve it, with the reason. For sweeps (sweep/cases.py): case_parameters, the sweep parameters its
    cases may vary (None: the magnet hand's own case runner, every parameter), and
    case_overrides(scenario, payload) -> the scenario overrides of a case's drawn payload, whose
    scenario is then passed to simulate(..., physical=) while the plan and the controller keep the
    nominal one."""

    kind: str
    limit_terms: Callable
    carried_inertia: Callable
    simulate: Callable[..., dict]
    build_diagram: Callable[..., TransferDiagram | TrayDiagram]
    refused_methods: dict = field(default_factory=dict)
    case_parameters: frozenset | None = None
    case_overrides: Callable | None = None
    case_refused: frozenset = frozenset()  # sweep parameters of other hands that this one cannot vary


HANDS: dict[str, HandPlugin] = {}


def register_hand(plugin: HandPlugin) -> None:
    HANDS[plugin.kind] = plugin


def hand_plugin(scenario: Scenario) -> HandPlugin:
    kind = getattr(scenario.hand, "kind", "magnet") if scenario.hand is not None else "magnet"
    if kind not in HANDS:
        raise QmtInputError(f"scenario {scenario.name}: hand kind {kind!r} has no plug-in (known: {sorted(HANDS)})")
    return HANDS[kind]


def run_simulate(scenario: Scenario, plan: Motion, *, time_scale: float = 1.0, record_path: str | Path | None = None,
                 time_step_s: float | None = None, implicit_loop_damping: bool | None = None,
                 feedforward: str = "none") -> dict:
    """The co-simulation of `plan` on `scenario` through its hand's plug-in (api.simulate documents it)."""
    return hand_plugin(scenario).simulate(scenario, plan, time_scale=time_scale, record_path=record_path,
                                          time_step_s=time_step_s, implicit_loop_damping=implicit_loop_damping,
                                          feedforward=feedforward)


def build_diagram(scenario: Scenario, plan: Motion, **options: Any) -> TransferDiagram | TrayDiagram:
    """The co-simulation Diagram through the hand's plug-in (api.build_diagram documents it)."""
    return hand_plugin(scenario).build_diagram(scenario, plan, **options)


# ------------------------------------------------------------------------------------- magnet
register_hand(HandPlugin(
    kind="magnet",
    limit_terms=lambda sc, arm: [PayloadMomentTerm(arm, sc.moment_per_accel_kgm, sc.limits.moment_limit_Nm)],
    carried_inertia=lambda sc: PayloadSpec.for_scenario(sc).spatial_inertia_about_origin(),
    simulate=run_transfer_simulate,
    build_diagram=build_transfer_diagram,
    case_refused=frozenset({"servo_delay_s"}),  # DC motors with PID: no goal stream to delay
))


# --------------------------------------------------------------------------------------- tray
def _simulate_tray(scenario: Scenario, plan: Motion, *, time_scale: float = 1.0,
                   record_path: str | Path | None = None, time_step_s: float | None = None,
                   implicit_loop_damping: bool | None = None, feedforward: str = "none",
                   physical: Scenario | None = None, servo_delay_s: float = 0.0) -> dict:
    check_tray_simulation(scenario, time_step_s, feedforward, implicit_loop_damping)
    return simulate_tray_plan(scenario, plan, time_scale=time_scale, record_path=record_path, time_step_s=time_step_s,
                              physical=physical, servo_delay_s=servo_delay_s)


def _tray_diagram(scenario: Scenario, plan: Motion, *, time_scale: float = 1.0, time_step_s: float | None = None,
                  meshcat: Meshcat | None = None, **options: Any) -> TrayDiagram:
    check_tray_simulation(scenario, time_step_s)
    check_plan_fits(plan, scenario)
    act = scenario.actuator
    assert isinstance(act, DynamixelServos)  # check_tray_simulation refused every other actuator
    schedule = plan_schedule(plan, time_scale=time_scale, period_s=act.control_period_s,
                             shaped_for=scenario if act.reference == "shaped" else None)
    kw: dict[str, Any] = {} if time_step_s is None else {"time_step_s": time_step_s}
    return build_tray_diagram(schedule, act.gains(), scenario.bottle, servo_period_s=act.control_period_s,
                              meshcat=meshcat, **kw, **options)


register_hand(HandPlugin(
    kind="tray",
    limit_terms=lambda sc, arm: tray_terms(sc.bottle, sc.hand.plan_margin, gravity_m_s2=sc.world.gravity_m_s2),
    carried_inertia=lambda sc: sc.bottle.spatial_inertia(),
    simulate=_simulate_tray,
    build_diagram=_tray_diagram,
    # its B-spline path does not hold the tray level and its constraints have no tray terms: the
    # re-check's slow-down search (finish.py) cannot make it keep the tray limits
    refused_methods={"trajopt": "its path does not hold the tray level and its constraints have no tray terms"},
    case_parameters=TRAY_CASE_PARAMETERS,
    case_overrides=drawn_bottle_overrides,
))
