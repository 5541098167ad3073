"""Hand plug-ins: each hand kind registers once what it adds to the limit set, what it welds to the
planning arm, and how its transfer is co-simulated and built as a Drake Diagram.

    magnet  the thesis's electromagnetic hand (seed 000): the payload-moment term; DC motors or
            ideal actuators with PID; sim/ builds and runs the diagram
    tray    seed 002's tray with a bottle standing free: slide / tip / lift-off terms; the CRANE-X7's
            Dynamixel servos; tray/ builds and runs the diagram

`hand_plugin(scenario)` looks a scenario's hand up (config/registry.HANDS); the scenario loader,
the builders, `run_simulate`, `build_diagram`, the CLI, the benchmark, the budgets and the sweeps
ask it instead of branching on the hand, so a new hand is one `register_hand` call and seed
packages only plug in (tests/test_architecture.py checks that no `is_tray` branch is left).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydrake.geometry import Meshcat

from qmt_drake.budgets import MAGNET_REPLAY, TRAY_REPLAY, ReplayCost
from qmt_drake.config.registry import HANDS, hand_entry
from qmt_drake.config.scenario import (
    DynamixelServos,
    Scenario,
    TrayHand,
    check_tray_payload,
    check_tray_scenario,
    magnet_moment_limit,
    tray_moment_limit,
)
from qmt_drake.config.validate import parse_magnet_hand, parse_tray_hand
from qmt_drake.energy.execute import build_plan_execution_cosim
from qmt_drake.errors import QmtInputError
from qmt_drake.limits import PayloadMomentTerm
from qmt_drake.outcome import verdict_line
from qmt_drake.plan import Motion, Plan
from qmt_drake.plan_files import check_plan_fits
from qmt_drake.sim.actuation import FEEDFORWARD_OPTIONS
from qmt_drake.sim.cosim_run import CoSim
from qmt_drake.sim.diagram import TransferDiagram, build_transfer_diagram
from qmt_drake.sim.runner import (
    check_simulation_inputs,
    plan_transfer_cosim,
    run_transfer_simulate,
    simulate_transfer,
    transfer_simulate_cosim,
)
from qmt_drake.sim.sim_settings import simulation_of, time_step_of
from qmt_drake.systems.payload import PayloadSpec
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.transfer_scenario import TransferScenario
from qmt_drake.tray.conditions import level_tray_acceleration_cap_m_s2
from qmt_drake.tray.cosim import TrayDiagram, build_tray_diagram, tray_cosim
from qmt_drake.tray.execute import (
    TRAY_CASE_PARAMETERS,
    build_tray_plan_cosim,
    check_tray_simulation,
    drawn_bottle_overrides,
    plan_schedule,
    simulate_tray_plan,
    tray_plan_summary,
)
from qmt_drake.tray.limit_terms import tray_terms


@dataclass(frozen=True)
class HandPlugin:
    """What one hand kind adds (config/registry.HANDS holds one per kind).

    The scenario: parse(raw_section, where) -> its typed hand section; check_payload(payload, where)
    (None: any payload) before the section is read; moment_limit(hand, payload, world, raw_limits,
    where) -> Limits.moment_limit_Nm [N*m]; check_loaded(scenario, where) (None: nothing) once the arm
    is loaded. What is built from it: limit_terms(scenario, arm) -> the hand's limit terms (before the
    motor torques); carried_inertia(scenario) -> the Drake SpatialInertia welded to the planning arm's
    hand; bottle(scenario) -> the BottleSpec of a hand that carries one (None: no bottle).

    The co-simulation: simulate(scenario, plan, **options) -> the summary (the CLI's JSON), in which
    lost_at_key names the time the payload was lost [s]; build_cosim(scenario, plan, **options) -> the
    CoSim that simulate runs (sim/cosim_run.run; simulate's options); build_diagram(scenario, plan,
    **options) -> the diagram; check_simulation(scenario, *, time_step_s, implicit_loop_damping, feedforward) refuses
    (one line) what it cannot simulate, before any planning; carried_check(scenario, plan, *,
    time_scale, feedforward, time_step_s) -> {held, outcome, max_slip_m, detached_at_s, max_tilt_rad,
    sim_wall_s} of one nominal run (the carried search); replay_cost: its budgets.ReplayCost.

    Reports: bang_bang_acceleration_m_s2(scenario) -> the largest tip acceleration [m/s^2] its limit
    allows on a level line (apps/bang_bang.py); limit_caption(scenario, A) names that limit in the
    benchmark's figures, figure_peak_ratio(plan) the ratio their titles show, moment_axis whether a
    payload-moment axis applies; plan_ratios_text(plan) and simulate_text(result): the CLI's lines;
    carried_search_note: why the benchmark does not search its fastest carried plan (None: it does).

    Planners and sweeps: refused_methods, planners that cannot serve it, with the reason;
    case_parameters, the sweep parameters its cases may vary (None: the magnet hand's own case
    runner, every parameter); case_overrides(scenario, payload) -> the scenario overrides of a
    case's drawn payload, whose scenario is then passed to simulate(..., physical=) while the plan
    and the controller keep the nominal one; case_refused: sweep parameters of other hands that this
    one cannot vary."""

    kind: str
    parse: Callable[[dict, str], Any]
    moment_limit: Callable[..., float]
    limit_terms: Callable
    carried_inertia: Callable
    simulate: Callable[..., dict]
    build_diagram: Callable[..., TransferDiagram | TrayDiagram]
    check_simulation: Callable[..., Any]
    carried_check: Callable[..., dict]
    bang_bang_acceleration_m_s2: Callable[..., float]  # (TransferScenario) -> m/s^2
    limit_caption: Callable[[Scenario, float], str]
    figure_peak_ratio: Callable[[Plan], float]
    plan_ratios_text: Callable[[Plan], str]
    simulate_text: Callable[[dict], str]
    check_payload: Callable[..., None] | None = None
    check_loaded: Callable[..., None] | None = None
    bottle: Callable[[Scenario], BottleSpec] | None = None
    lost_at_key: str = "detached_at_s"
    replay_cost: ReplayCost = MAGNET_REPLAY
    moment_axis: bool = True
    carried_search_note: str | None = None
    refused_methods: dict = field(default_factory=dict)
    case_parameters: frozenset | None = None
    case_overrides: Callable | None = None
    case_refused: frozenset = frozenset()
    build_cosim: Callable[..., CoSim] | None = None


def register_hand(plugin: HandPlugin, *, replace: bool = False) -> None:
    """Register a hand kind (a HandPlugin); an existing kind only with replace=True. One line else."""
    if not isinstance(plugin, HandPlugin):
        raise QmtInputError(f"register_hand needs a HandPlugin, got {type(plugin).__name__}; build one with "
                            "qmt_drake.hands.HandPlugin(kind=..., parse=..., ...)")
    HANDS.register(plugin, replace=replace)


def hand_plugin(scenario: Scenario) -> HandPlugin:
    """The registered plug-in of the scenario's hand (the magnet's without a hand section)."""
    plugin: HandPlugin = hand_entry(scenario)
    return plugin


def run_simulate(scenario: TransferScenario, plan: Motion, *, time_scale: float = 1.0, record_path: str | Path | None = None,
                 time_step_s: float | None = None, implicit_loop_damping: bool | None = None,
                 feedforward: str = "none") -> dict:
    """The co-simulation of `plan` on `scenario` through its hand's plug-in (api.simulate documents it)."""
    return hand_plugin(scenario).simulate(scenario, plan, time_scale=time_scale, record_path=record_path,
                                          time_step_s=time_step_s, implicit_loop_damping=implicit_loop_damping,
                                          feedforward=feedforward)


def build_diagram(scenario: TransferScenario, plan: Motion, **options: Any) -> CoSim:
    """The co-simulation Diagram through the hand's plug-in (api.build_diagram documents it), as a CoSim
    that sim/cosim_run.run runs (or user code composes: cosim.diagram)."""
    made = hand_plugin(scenario).build_diagram(scenario, plan, **options)
    time_scale = float(options.get("time_scale", 1.0))
    if isinstance(made, TransferDiagram):
        return plan_transfer_cosim(scenario, plan, made, time_scale)
    if isinstance(made, TrayDiagram):
        return tray_cosim(made, keep_series=False, summarize=lambda r: tray_plan_summary(plan, r, time_scale))
    return made


def energy_cosim(plan: Any, *, record_path: str | Path | None = None, time_scale: float = 1.0,
                 time_step_s: float | None = None, feedforward: str | None = None) -> CoSim:
    """The energy-time arm's co-simulation of `plan` (energy/execute.build_plan_execution_cosim): an
    ideal inverse-dynamics drive, played as planned; time_step_s [s]: a discrete plant at that step (None: the
    scenario's simulation section, else continuous)."""
    for name, given in (("time_scale", time_scale != 1.0), ("feedforward", feedforward not in (None, "full"))):
        if given:  # played at its optimiser's timing; its controller's feedforward is always on
            raise QmtInputError(f"{name}: the energy-time co-simulation does not take it; drop {name}")
    return build_plan_execution_cosim(plan, record_path, time_step_s)


# ------------------------------------------------------------------------------------- magnet
def _magnet_carried(scenario: TransferScenario, plan: Motion, *, time_scale: float = 1.0, feedforward: str = "full",
                    time_step_s: float | None = None) -> dict:
    r = simulate_transfer(scenario, plan, time_scale=time_scale, time_step_s=time_step_s, keep_series=False,
                          **FEEDFORWARD_OPTIONS[feedforward])
    return {"held": bool(r.held), "outcome": r.outcome, "max_slip_m": float(r.max_slip_m),
            "detached_at_s": r.detached_at_s, "max_tilt_rad": float(r.max_tilt_rad), "sim_wall_s": float(r.sim_wall_s)}


def _magnet_ratios_text(plan: Plan) -> str:
    s = plan.summary()
    return (f"moment {s['peak_moment_ratio']:.4f} of limit, motor torque {s['peak_motor_torque_ratio']:.4f} "
            "of limit")


def _magnet_simulate_text(r: dict) -> str:
    return (f"{verdict_line(r['outcome'], r['detached_at_s'])}, max slip {r['max_slip_m'] * 1e3:.3f} mm, "
            f"tracking error {r['max_tracking_error_rad']:.2e} rad, real-time factor {r['real_time_factor']:.1f}")


register_hand(HandPlugin(
    kind="magnet",
    build_cosim=transfer_simulate_cosim,
    parse=parse_magnet_hand,
    moment_limit=magnet_moment_limit,
    limit_terms=lambda sc, arm: [PayloadMomentTerm(arm, sc.moment_per_accel_kgm, sc.limits.moment_limit_Nm)],
    carried_inertia=lambda sc: PayloadSpec.for_scenario(sc).spatial_inertia_about_origin(),
    simulate=run_transfer_simulate,
    build_diagram=build_transfer_diagram,
    check_simulation=check_simulation_inputs,
    carried_check=_magnet_carried,
    # the moment limit over m_o r_G (eq. 2-24)
    bang_bang_acceleration_m_s2=lambda sc: float(sc.limits.moment_limit_Nm / sc.moment_per_accel_kgm),
    limit_caption=lambda sc, A: f"the limit A = {A:.4g} m/s² = {sc.limits.moment_limit_Nm * 1e3:.4g} mN·m",
    figure_peak_ratio=lambda plan: plan.check.peak_moment_ratio,
    plan_ratios_text=_magnet_ratios_text,
    simulate_text=_magnet_simulate_text,
    case_refused=frozenset({"servo_delay_s"}),  # DC motors with PID: no goal stream to delay
))


# --------------------------------------------------------------------------------------- tray
def _simulate_tray(scenario: TransferScenario, plan: Motion, *, time_scale: float = 1.0,
                   record_path: str | Path | None = None, time_step_s: float | None = None,
                   implicit_loop_damping: bool | None = None, feedforward: str = "none",
                   physical: TransferScenario | None = None, servo_delay_s: float = 0.0) -> dict:
    check_tray_simulation(scenario, time_step_s, feedforward, implicit_loop_damping)
    return simulate_tray_plan(scenario, plan, time_scale=time_scale, record_path=record_path, time_step_s=time_step_s,
                              physical=physical, servo_delay_s=servo_delay_s)


def _tray_cosim(scenario: TransferScenario, plan: Motion, *, time_scale: float = 1.0,
                record_path: str | Path | None = None, time_step_s: float | None = None,
                implicit_loop_damping: bool | None = None, feedforward: str = "none",
                physical: TransferScenario | None = None, servo_delay_s: float = 0.0) -> CoSim:
    check_tray_simulation(scenario, time_step_s, feedforward, implicit_loop_damping)
    return build_tray_plan_cosim(scenario, plan, time_scale=time_scale, record_path=record_path,
                                 time_step_s=time_step_s, physical=physical, servo_delay_s=servo_delay_s)


def _check_tray_simulation(scenario: TransferScenario, *, time_step_s: float | None = None,
                           implicit_loop_damping: bool | None = None, feedforward: str = "none") -> None:
    check_tray_simulation(scenario, time_step_s, feedforward, implicit_loop_damping)


def _tray_carried(scenario: TransferScenario, plan: Motion, *, time_scale: float = 1.0, feedforward: str = "full",
                  time_step_s: float | None = None) -> dict:
    # through the servos' own firmware loop: the DC-motor feedforward does not apply
    r = _simulate_tray(scenario, plan, time_scale=time_scale, time_step_s=time_step_s)
    return {"held": bool(r["held"]), "outcome": r["outcome"], "max_slip_m": float(r["max_slip_m"]),
            "detached_at_s": r.get("lost_at_s"), "max_tilt_rad": float(r["max_tilt_rad"]),
            "sim_wall_s": float(r["sim_wall_s"])}


def _tray_diagram(scenario: TransferScenario, plan: Motion, *, time_scale: float = 1.0, time_step_s: float | None = None,
                  meshcat: Meshcat | None = None, **options: Any) -> TrayDiagram:
    check_tray_simulation(scenario, time_step_s)
    check_plan_fits(plan, scenario)
    act = scenario.actuator
    assert isinstance(act, DynamixelServos)  # check_tray_simulation refused every other actuator
    schedule = plan_schedule(plan, time_scale=time_scale, period_s=act.control_period_s,
                             shaped_for=scenario if act.reference == "shaped" else None)
    step = time_step_of(time_step_s, scenario, None)  # the run's, else the scenario's simulation.plant.time_step
    kw: dict[str, Any] = {"simulation": simulation_of(scenario), **({} if step is None else {"time_step_s": step})}
    return build_tray_diagram(schedule, act.gains(), scenario.bottle, servo_period_s=act.control_period_s,
                              meshcat=meshcat, **kw, **options)


def _tray(scenario: Scenario) -> TrayHand:
    assert isinstance(scenario.hand, TrayHand)  # this plug-in serves tray hands only
    return scenario.hand


def _tray_bottle(scenario: Scenario) -> BottleSpec:
    b, p, h = scenario.payload.body, scenario.payload, scenario.hand
    assert b is not None and isinstance(h, TrayHand)  # check_tray_payload and parse_tray_hand at load
    return BottleSpec(p.name, float(p.mass_kg), b.radius_m, b.length_m, float(p.com_offset_m), b.shell_mass_kg,
                      h.contact_radius_m, friction=h.friction, n_contact_points=h.n_contact_points)


def _tray_simulate_text(r: dict) -> str:
    return (f"{verdict_line(r['outcome'], r['lost_at_s'])}, slip {r['max_slip_m'] * 1e3:.3f} mm, creep "
            f"{r['creep_m'] * 1e3:.3f} mm, tilt {r['max_tilt_rad']:.2e} rad, tracking error "
            f"{r['max_tracking_error_rad']:.2e} rad, real-time factor {r['real_time_factor']:.2f}")


register_hand(HandPlugin(
    kind="tray",
    build_cosim=_tray_cosim,
    parse=parse_tray_hand,
    check_payload=check_tray_payload,
    moment_limit=tray_moment_limit,
    check_loaded=check_tray_scenario,
    limit_terms=lambda sc, arm: tray_terms(sc.bottle, _tray(sc).plan_margin, gravity_m_s2=sc.world.gravity_m_s2),
    carried_inertia=lambda sc: sc.bottle.spatial_inertia(),
    bottle=_tray_bottle,
    simulate=_simulate_tray,
    build_diagram=_tray_diagram,
    check_simulation=_check_tray_simulation,
    carried_check=_tray_carried,
    lost_at_key="lost_at_s",
    replay_cost=TRAY_REPLAY,
    # the level tray: the smaller of the planning friction's mu g (no slide) and g r_c / h_G (no tip)
    bang_bang_acceleration_m_s2=lambda sc: level_tray_acceleration_cap_m_s2(sc.bottle, _tray(sc).plan_margin,
                                                                            sc.world.g_m_s2),
    limit_caption=lambda sc, A: (f"the level tray's bang-bang acceleration A = {A:.4g} m/s² (slide or tip at the "
                                 "planning margin); titles: worst limit ratio"),
    figure_peak_ratio=lambda plan: plan.check.worst_ratio,  # the worst of slide / tip / lift / motors / speeds
    moment_axis=False,
    plan_ratios_text=lambda plan: "peak ratios " + ", ".join(f"{k} {v:.4f}" for k, v in plan.check.peak_ratios.items()),
    simulate_text=_tray_simulate_text,
    # the benchmark's search converges the magnet co-simulation's plant step; the tray's servos fix it
    # at their control period, and its search per bottle is a study of its own
    carried_search_note=("not searched here for a tray scenario: qmt-drake plan crane-tray --method toppra "
                         "--carried, or per friction and fill python -m studies.tray_carried"),
    case_parameters=TRAY_CASE_PARAMETERS,
    case_overrides=drawn_bottle_overrides,
))
