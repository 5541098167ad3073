"""Execute a plan of a tray scenario through the CRANE-X7 servos with the bottle free on the tray.

`plan_schedule(plan)` streams the plan's joint positions to the servos as goal positions every
servo period (zero-order hold, as the seed streams its waypoints), after a settle phase at the
start and followed by a tail at the goal; `simulate_tray_plan(scenario, plan)` runs the tray
co-simulation (tray/cosim.py) with the scenario's bottle, servo gains and servo period and returns
the summary the shared CLI prints (`held`, `max_slip_m`, `max_tracking_error_rad`,
`real_time_factor`), the outcome in the common vocabulary (qmt_drake/outcome.py: carried / slipped /
slid_off / tipped / unfinished, with the arm's final error against the plan's goal), slip vs
creep, tilt and lift-off time.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.config.scenario import World
from qmt_drake.errors import QmtInputError
from qmt_drake.outcome import ARRIVAL_TOLERANCE_SERVO_RAD, transfer_outcome
from qmt_drake.plan_files import check_plan_fits
from qmt_drake.sim.cosim_run import CoSim, run
from qmt_drake.sim.sim_settings import simulation_of, time_step_of
from qmt_drake.systems.dynamixel_servo import CRANE_X7_PLANAR_SERVOS
from qmt_drake.systems.servo_reference import hold_mean_motion, shaped_goals
from qmt_drake.tray.cosim import TIME_STEP_S, URDF_PATH, build_tray_cosim, tray_margin
from qmt_drake.tray.waypoints import GoalSchedule, _stream

SETTLE_S = 1.0
TAIL_S = 1.5
# The sweep parameters a tray case varies (sweep/spec.PARAMETERS names): the bottle as drawn, the
# replay speed and step, the planner seed. Coil, magnet, DC-motor and gain parameters belong to
# the magnet hand's co-simulation and are refused for a tray scenario.
TRAY_CASE_PARAMETERS = frozenset({"friction", "mass_kg", "mass_scale", "com_offset_m", "com_offset_scale",
                                  "time_scale", "time_step_s", "seed", "servo_delay_s"})
MAX_SERVO_DELAY_S = 0.1


def plan_schedule(plan, *, time_scale: float = 1.0, period_s: float = 1e-3, settle_s: float = SETTLE_S,
                  tail_s: float = TAIL_S, shaped_for=None, plant_step_s: float = TIME_STEP_S) -> GoalSchedule:
    """Goal stream of `plan` played time_scale times slower, one goal per period_s [s]. shaped_for:
    a tray scenario whose servos the goals are shaped for (systems/servo_reference.py: the goals
    that make the firmware's loop execute the plan), or None to stream the plan itself. plant_step_s [s]:
    the simulated plant's step; with a servo period longer than it, the shaped goals' PWM is the plan's mean
    over each hold's plant steps (servo_reference.hold_mean_motion)."""
    if not (np.isfinite(time_scale) and time_scale > 0):
        raise QmtInputError(f"time scale {time_scale} must be a positive number")
    T = float(plan.motion_time_s) * time_scale
    t = np.arange(0.0, T + 0.5 * period_s, period_s)
    t[-1] = min(t[-1], T)
    if t[-1] < T:  # a plan shorter than one period still ends at its goal
        t = np.append(t, T)
    label = f"{plan.method} x{time_scale:g}"
    if shaped_for is None:
        return _stream(plan.sample(t / time_scale)[0], t, settle_s, tail_s, label)
    # shaped: the loop's inverse runs on through the tail too (the plan rests at its goal there), so
    # the goal eases back onto the plan's end as the integral takes up the new static load
    t_all = np.arange(0.0, T + tail_s, period_s)
    def sample(ts):
        q, qd, qdd = plan.sample(ts / time_scale)
        return q, qd / time_scale, qdd / time_scale**2

    q, qd, qdd = sample(t_all)
    held = (q, qd, qdd) if period_s <= plant_step_s * (1 + 1e-9) else hold_mean_motion(sample, t_all, period_s,
                                                                                        plant_step_s)
    tau = shaped_for.arm.joint_torque(*held)
    goals = shaped_goals(q, qd, qdd, tau, shaped_for.actuator.datasheets(), shaped_for.actuator.gains(), period_s,
                         pwm_speed_rad_s=held[1])
    return GoalSchedule(np.concatenate([[0.0], settle_s + t_all]), np.vstack([goals[:1], goals]),
                        settle_s + T + tail_s, {"settle": (0.0, settle_s), "move": (settle_s, settle_s + T)},
                        label + " shaped")


def check_tray_simulation(scenario, time_step_s: float | None = None, feedforward: str = "none",
                          implicit_loop_damping: bool | None = None) -> None:
    """One-line QmtInputError unless the tray co-simulation models this scenario's hardware, the
    plant step (None: the default) is no coarser than the servos' control period, and no DC-motor
    option (feedforward, the explicit loop: implicit_loop_damping False) is asked for."""
    if feedforward != "none" or implicit_loop_damping is False:
        raise QmtInputError("--explicit and --feedforward are options of the DC-motor co-simulation; the tray "
                            "co-simulation drives the servos' own firmware loop: drop them")
    if scenario.urdf_path.resolve() != URDF_PATH.resolve():
        raise QmtInputError(f"{scenario.source_path}: the tray co-simulation models {URDF_PATH.name} only, "
                            f"not {scenario.urdf_path.name}")
    if scenario.world != World():
        raise QmtInputError(f"{scenario.source_path}: the tray co-simulation models the CRANE-X7 under standard "
                            f"gravity; world.gravity_m_s2 {list(scenario.world.gravity_m_s2)} is for planning only: "
                            "drop it to simulate")
    act = scenario.actuator
    if getattr(act, "kind", None) != "dynamixel" or act.datasheets() != CRANE_X7_PLANAR_SERVOS:
        raise QmtInputError(f"{scenario.source_path}: the tray co-simulation needs actuator kind 'dynamixel' with "
                            "servos [XM540-W270, XM430-W350, XM430-W350] (the CRANE-X7's)")
    period_ms = act.control_period_s * 1e3
    given = None if time_step_s is None else f"--time-step-ms {time_step_s * 1e3:g}"
    if time_step_s is None and simulation_of(scenario).plant.time_step is not None:  # the scenario's step
        time_step_s = simulation_of(scenario).plant.time_step
        given = f"{scenario.name}: simulation.plant.time_step {time_step_s:g} s"
    if time_step_s is not None and time_step_s * 1e3 > period_ms * (1 + 1e-9):
        # a plant step coarser than the servo loop changes the verdict (5 ms: the seed's 5 s move
        # "slips" 2.6 mm; 1 ms: carried), so it would be a silent wrong answer
        raise QmtInputError(f"{given}: the tray co-simulation's plant step must not "
                            f"exceed the servos' control period ({period_ms:g} ms); use {period_ms:g} or less")


def delayed(schedule: GoalSchedule, delay_s: float) -> GoalSchedule:
    """The goal stream reaching the servos delay_s [s] late (a bus or host latency): the first goal held
    until then, every later one shifted, the run and its phases delay_s longer."""
    if not (np.isfinite(delay_s) and 0.0 <= delay_s <= MAX_SERVO_DELAY_S):
        raise QmtInputError(f"servo delay {delay_s} s must lie in [0, {MAX_SERVO_DELAY_S:g}] s")
    if delay_s == 0.0:
        return schedule
    return GoalSchedule(np.concatenate([[0.0], schedule.times + delay_s]),
                        np.vstack([schedule.goals[:1], schedule.goals]), schedule.t_end_s + delay_s,
                        {k: (a + delay_s, b + delay_s) for k, (a, b) in schedule.phases.items()},
                        f"{schedule.label} delayed {delay_s * 1e3:g} ms")


def build_tray_plan_cosim(scenario, plan, *, time_scale: float = 1.0, record_path=None,
                          time_step_s: float | None = None, physical=None, servo_delay_s: float = 0.0,
                          contact_approximation: str | None = None) -> CoSim:
    """`plan` on `scenario`'s CRANE-X7 as a CoSim (the tray plug-in's build_cosim); its summary is
    simulate_tray_plan's (see the module docstring).
    physical: the scenario whose bottle (mass, centre of mass, friction) is simulated, when it
    differs from the one the servos' goals are shaped for (a sweep case's drawn bottle: the
    controller knows only the nominal one); None: `scenario` itself. servo_delay_s: the goal stream
    arrives that late (`delayed`). contact_approximation: the plant's discrete contact approximation
    (tamsi, sap, similar, lagged: studies/verdict_margins.py; None: the scenario's simulation.plant one, else
    lagged). time_step_s None: the scenario's simulation.plant.time_step, else TIME_STEP_S."""
    check_tray_simulation(scenario, time_step_s)
    check_plan_fits(plan, scenario)  # a plan made for another scenario is refused by the library
    act = scenario.actuator
    sched = plan_schedule(plan, time_scale=time_scale, period_s=act.control_period_s,
                          shaped_for=scenario if act.reference == "shaped" else None)
    sched = delayed(sched, float(servo_delay_s))

    return build_tray_cosim(sched, act.gains(), (physical or scenario).bottle,
                            time_step_s=time_step_of(time_step_s, scenario, TIME_STEP_S),
                            servo_period_s=act.control_period_s, keep_series=False, recording_path=record_path,
                            contact_approximation=contact_approximation, simulation=simulation_of(scenario),
                            summarize=lambda r: tray_plan_summary(plan, r, time_scale))


def tray_plan_summary(plan, r, time_scale: float = 1.0) -> dict:
    """The TrayResult `r` of `plan` played time_scale times slower as the summary in the one outcome
    vocabulary (qmt_drake/outcome.py): the arm's final error against the plan's goal, slip, tracking."""
    d = r.summary_dict()
    q_goal = plan.sample(np.array([float(plan.motion_time_s)]))[0][0]
    final_error = float(np.max(np.abs(q_goal - r.final_q_rad)))
    outcome = transfer_outcome(None if r.outcome == "on_tray" else r.outcome, r.slipped, final_error,
                               ARRIVAL_TOLERANCE_SERVO_RAD)
    d.update(outcome=outcome, held=outcome == "carried", final_goal_error_rad=final_error,
             arrival_tolerance_rad=ARRIVAL_TOLERANCE_SERVO_RAD, max_slip_m=float(r.slip_m),
             max_tracking_error_rad=float(np.max(r.max_tracking_error_rad)),
             per_joint_tracking_error_rad=[float(x) for x in r.max_tracking_error_rad],
             motion_time_s=float(plan.motion_time_s) * time_scale, time_scale=float(time_scale),
             method=plan.method, plan_feasible=bool(plan.feasible))
    d["margin"] = tray_margin(d)
    return d


def simulate_tray_plan(scenario, plan, *, time_scale: float = 1.0, record_path=None,
                       time_step_s: float | None = None, physical=None, servo_delay_s: float = 0.0,
                       contact_approximation: str | None = None) -> dict:
    """The summary of `plan` executed on `scenario`'s CRANE-X7 (build_tray_plan_cosim, the one run)."""
    return run(build_tray_plan_cosim(scenario, plan, time_scale=time_scale, record_path=record_path,
                                     time_step_s=time_step_s, physical=physical, servo_delay_s=servo_delay_s,
                                     contact_approximation=contact_approximation))


def drawn_bottle_overrides(scenario, payload: dict) -> dict:
    """Scenario overrides of a sweep case's drawn bottle. payload: PayloadSpec field -> an absolute
    value or ["scale", x] times the nominal one (sweep/cases.Case.payload): friction [-] goes to
    hand.friction, mass_kg [kg] and com_offset_m [m, centre of mass above the base] to payload."""
    nominal = {"friction": ("hand", scenario.hand.friction), "mass_kg": ("payload", scenario.payload.mass_kg),
               "com_offset_m": ("payload", scenario.payload.com_offset_m)}
    out: dict = {}
    for name, v in payload.items():
        if name not in nominal:
            raise QmtInputError(f"a tray case cannot vary the payload's {name}; vary friction, mass or com_offset")
        section, value = nominal[name]
        out.setdefault(section, {})[name] = float(value) * v[1] if isinstance(v, (list, tuple)) else float(v)
    return out
