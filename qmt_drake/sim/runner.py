"""Running a transfer Diagram and summarising it: `run_diagram`, `simulate_transfer` (-> TransferResult),
and `run_simulate`, the CLI's entry point (a JSON-ready dict)."""

from __future__ import annotations

import gc
import math
from dataclasses import dataclass, field

import numpy as np

from qmt_drake.errors import QmtInputError, QmtSimulationError
from qmt_drake.margin import criterion, verdict_margin
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD, transfer_outcome
from qmt_drake.recording import make_headless_meshcat, save_recording, start_recording
from qmt_drake.sim.actuation import (
    FEEDFORWARD_OPTIONS,
    default_time_step_s,
    explicit_step_known_unstable,
)
from qmt_drake.sim.cosim_run import CoSim, run
from qmt_drake.sim.diagram import TransferDiagram, build_transfer_diagram, transfer_time_step
from qmt_drake.sim.magnet_actuation import magnet_actuation_of
from qmt_drake.sim.magnet_hand import magnet_hand_of
from qmt_drake.systems.transfer_monitor import DETACH_GAP_M, DETACH_SLIP_M, TransferMonitor, check_seated

HELD_SLIP_LIMIT_M = 1e-3  # "held": never detached and slip below 1 mm


@dataclass
class TransferResult:
    """One co-simulated transfer. Times are simulation time: lead_s (0.2 s) of rest, the plan slowed
    by time_scale, settle_s (0.5 s); detached_at_s counts from the start of the lead (None: never).
    outcome: qmt_drake/outcome.py's word (carried / slipped / detached / unfinished); held = outcome is
    carried: never detached, max_slip_m < 1 mm and the arm ended within arrival_tolerance_rad of the
    plan's goal (final_goal_error_rad, max over the joints). peak_motor_torque_ratio is the simulated peak over
    the scenario's rated motor torque; peak_moment_ratio_planned is the time-scaled plan's
    m_o r_G |a_tip| peak over the moment limit. real_time_factor = sim_time_s / sim_wall_s.
    explicit_step_known_unstable: the motors drove the plant explicitly at a step above 1 ms, where
    that loop is known unstable: a loss then says nothing about the physics.
    series (if kept): 5 ms samples of the exported signals, see logged_series."""

    scenario: str
    method: str
    time_scale: float
    held: bool
    outcome: str
    final_goal_error_rad: float
    arrival_tolerance_rad: float
    max_slip_m: float
    max_tilt_rad: float
    max_gap_m: float
    detached_at_s: float | None
    max_tracking_error_rad: float
    peak_motor_torque_Nm: np.ndarray
    peak_motor_torque_ratio: float
    peak_moment_ratio_planned: float
    peak_moment_planned_Nm: float
    peak_motor_torque_planned_Nm: np.ndarray  # inverse dynamics of the plan / N (thesis eq. 2-34)
    energy_J: float
    coil_current_A: float
    time_step_s: float
    implicit_loop_damping: bool
    sim_time_s: float
    sim_wall_s: float
    real_time_factor: float
    explicit_step_known_unstable: bool = False
    series: dict = field(default_factory=dict, repr=False)

    def summary_dict(self) -> dict:
        d = {k: getattr(self, k) for k in (
            "scenario", "method", "time_scale", "outcome", "held", "final_goal_error_rad", "arrival_tolerance_rad",
            "max_slip_m", "max_tilt_rad", "max_gap_m", "detached_at_s",
            "max_tracking_error_rad", "peak_motor_torque_ratio", "peak_moment_ratio_planned",
            "peak_moment_planned_Nm", "energy_J", "coil_current_A", "time_step_s", "implicit_loop_damping",
            "sim_time_s", "sim_wall_s", "real_time_factor", "explicit_step_known_unstable")}
        d["peak_motor_torque_Nm"] = [float(x) for x in self.peak_motor_torque_Nm]
        d["peak_motor_torque_planned_Nm"] = [float(x) for x in self.peak_motor_torque_planned_Nm]
        d = {k: (float(v) if isinstance(v, (np.floating,)) else v) for k, v in d.items()}
        d["margin"] = self.margin()
        return d

    def margin(self) -> dict:
        """The verdict's quantities against their thresholds (qmt_drake/margin.py): slip vs the held
        limit, gap and slip vs the monitor's detach limits, the arm's final error vs the arrival tolerance."""
        return verdict_margin(self.outcome, [
            criterion("max_slip_m", self.max_slip_m, HELD_SLIP_LIMIT_M, "slipped"),
            criterion("max_gap_m", self.max_gap_m, DETACH_GAP_M, "detached"),
            criterion("max_slip_m", self.max_slip_m, DETACH_SLIP_M, "detached"),
            criterion("final_goal_error_rad", self.final_goal_error_rad, self.arrival_tolerance_rad, "unfinished")])


def planned_peak_moment_Nm(scenario, plan, time_scale: float = 1.0, rate_hz: float = 10000.0) -> float:
    """max m_o r_G |a_tip| of the time-scaled plan, sampled at rate_hz."""
    t = np.linspace(0.0, float(plan.motion_time_s), int(plan.motion_time_s * rate_hz) + 2)
    q, qd, qdd = plan.sample(t)
    a = scenario.arm.tip_acceleration(q, qd, qdd)
    return float(np.max(np.linalg.norm(a, axis=-1))) * scenario.moment_per_accel_kgm / time_scale**2


def planned_peak_motor_torque_Nm(scenario, plan, time_scale: float = 1.0, rate_hz: float = 1000.0) -> np.ndarray:
    """max |joint torque / N| per motor of the time-scaled plan (arm inverse dynamics, no payload)."""
    t = np.linspace(0.0, float(plan.motion_time_s), int(plan.motion_time_s * rate_hz) + 2)
    q, qd, qdd = plan.sample(t)
    tau = scenario.arm.motor_torque(q, np.asarray(qd) / time_scale, np.asarray(qdd) / time_scale**2)
    return np.max(np.abs(tau), axis=0)


def transfer_cosim(td: TransferDiagram, *, chunk_s: float = 0.25, max_tracking_error_rad: float = 0.5,
                   on_start=None, finish=None, summarize=None) -> CoSim:
    """`td` as a CoSim for cosim_run.run: from the diagram's default context (the plan's start, payload
    seated) to td.t_final_s. The run raises QmtSimulationError naming the failure time when the state
    becomes non-finite, Drake's solver fails, or the arm leaves its reference by more than
    max_tracking_error_rad (an unstable loop: the voltage limit keeps the state finite, so this is how
    divergence shows). After it td.run_summary holds the monitor's summary and td.final_goal_error_rad
    the arm's end against the goal. finish(sim, wall_s) / summarize(result): the caller's result
    (default: (monitor summary, wall seconds), summarised as TransferMonitor.unpack's dict)."""
    def start(sim) -> None:
        ctx = sim.get_mutable_context()
        if td.monitor is None:  # no Python monitor in the diagram to check the seated start at Initialize
            check_seated(*(float(td.diagram.GetOutputPort(k).Eval(ctx)[0]) for k in ("slip", "tilt", "gap")),
                         ctx.get_time())
        sim.Initialize()
        if on_start is not None:
            on_start(sim)

    def advance(sim) -> None:
        ctx = sim.get_mutable_context()
        plant_ctx = td.plant.GetMyContextFromRoot(ctx)
        ref = td.diagram.GetOutputPort("desired_state")
        n = len(td.q_start)
        # The Python systems allocate small arrays every step; the cyclic collector would otherwise
        # run thousands of times per simulated second for nothing (the arrays form no cycles).
        gc_was_enabled = gc.isenabled()
        gc.disable()
        td.simulator = sim
        try:
            _advance(sim, td, ctx, plant_ctx, ref, n, chunk_s, max_tracking_error_rad)
            td.run_summary = np.asarray(td.summary(ctx))  # with per-step logs: computed here, part of the run's cost
            # Where the arm ended against the goal (the reference holds the plan's end state here).
            td.final_goal_error_rad = float(np.max(np.abs(
                ref.Eval(ctx)[:n] - td.plant.GetPositions(plant_ctx, td.arm_instance))))
        finally:
            if gc_was_enabled:
                gc.enable()

    exports = {td.diagram.get_output_port(i).get_name(): td.diagram.get_output_port(i)
               for i in range(td.diagram.num_output_ports())}
    return CoSim("magnet", td.diagram, td.plant, start, advance,
                 finish or (lambda sim, wall: (td.run_summary, wall)),
                 summarize or (lambda result: TransferMonitor.unpack(result[0])),
                 ports=exports, loggers=td.loggers, monitor=td.monitor, handles=td,
                 simulator_settings=getattr(td, "simulator_settings", None))


def run_diagram(td: TransferDiagram, *, chunk_s: float = 0.25, max_tracking_error_rad: float = 0.5,
                on_start=None) -> tuple[np.ndarray, float]:
    """Simulate `td` (transfer_cosim, through the one run); returns (monitor summary, wall seconds)."""
    cosim = transfer_cosim(td, chunk_s=chunk_s, max_tracking_error_rad=max_tracking_error_rad, on_start=on_start)
    run(cosim)
    return cosim.result


def _advance(sim, td, ctx, plant_ctx, ref, n, chunk_s, max_tracking_error_rad) -> None:
    t = 0.0
    while t < td.t_final_s - 1e-12:
        t = min(t + chunk_s, td.t_final_s)
        try:
            sim.AdvanceTo(t)
        except RuntimeError as exc:
            raise QmtSimulationError(f"simulation failed at t = {ctx.get_time():.3f} s: "
                                     f"{str(exc).splitlines()[0]}") from None
        x = td.plant.GetPositionsAndVelocities(plant_ctx)
        if not np.all(np.isfinite(x)):
            raise QmtSimulationError(f"simulation diverged at t = {ctx.get_time():.3f} s: non-finite state")
        err = float(np.max(np.abs(ref.Eval(ctx)[:n] - td.plant.GetPositions(plant_ctx, td.arm_instance))))
        if err > max_tracking_error_rad:
            raise QmtSimulationError(
                f"the arm left its reference at t = {ctx.get_time():.3f} s: joint tracking error {err:.3g} rad > "
                f"{max_tracking_error_rad} rad: the motors cannot follow it (a time scale below 1 asks for more "
                "torque than the plan's limits) or the control loop is unstable (then use a smaller time step, "
                f"at most {default_time_step_s(td.implicit_loop_damping) * 1e3:g} ms for this loop)")


def logged_series(td: TransferDiagram) -> dict:
    """The loggers' samples after run_diagram: {'t_s': (K,), port name: (K, width)}."""
    ctx = td.simulator.get_context()
    out = {}
    for name, logger in td.loggers.items():
        log = logger.FindLog(ctx)
        out.setdefault("t_s", log.sample_times().copy())
        out[name] = log.data().T.copy()
    return out


def build_transfer_cosim(scenario, plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
                         record_path=None, keep_series: bool = True, summary_extra: dict | None = None,
                         **build_kw) -> CoSim:
    """The magnet hand's co-simulation as a CoSim: build_transfer_diagram's closed loop, its result a
    TransferResult (summarised by its summary_dict, plus summary_extra)."""
    meshcat = None
    if record_path is not None:
        meshcat = make_headless_meshcat()
    build_kw.setdefault("step_logs", True)  # the monitor's numbers from C++ logs (sim.posthoc)
    td = build_transfer_diagram(scenario, plan, time_step_s=time_step_s, time_scale=time_scale,
                                meshcat=meshcat, log_period_s=5e-3 if keep_series else 0.0, **build_kw)
    on_start = None
    if meshcat is not None:
        on_start = lambda sim: start_recording(td.visualizer)  # noqa: E731

    def finish(sim, wall) -> TransferResult:
        if meshcat is not None:
            save_recording(td.visualizer, meshcat, record_path)
        return make_result(scenario, plan, td, td.run_summary, wall, time_scale,
                           logged_series(td) if keep_series else {})

    return transfer_cosim(td, on_start=on_start, finish=finish,
                          summarize=lambda res: {**res.summary_dict(), **(summary_extra or {})})


def plan_transfer_cosim(scenario, plan, td: TransferDiagram, time_scale: float = 1.0) -> CoSim:
    """A built transfer diagram of `plan` (build_transfer_diagram) as a CoSim whose run gives
    TransferResult.summary_dict (the one outcome vocabulary); no series kept."""
    return transfer_cosim(td, finish=lambda sim, wall: make_result(scenario, plan, td, td.run_summary, wall,
                                                                   time_scale, {}),
                          summarize=lambda res: res.summary_dict())


def simulate_transfer(scenario, plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
                      record_path=None, keep_series: bool = True, **build_kw) -> TransferResult:
    """Build, run and summarise one transfer (see TransferResult)."""
    cosim = build_transfer_cosim(scenario, plan, time_scale=time_scale, time_step_s=time_step_s,
                                 record_path=record_path, keep_series=keep_series, **build_kw)
    run(cosim)
    return cosim.result


def make_result(scenario, plan, td, summary, wall, time_scale, series) -> TransferResult:
    s = TransferMonitor.unpack(summary)
    detached = None if math.isnan(s["detached_at_s"]) else s["detached_at_s"]
    peak = s["peak_motor_torque_Nm"]
    moment = planned_peak_moment_Nm(scenario, plan, time_scale)
    final_error = float(getattr(td, "final_goal_error_rad", math.nan))
    outcome = transfer_outcome(None if detached is None else "detached", s["max_slip_m"] >= HELD_SLIP_LIMIT_M,
                               final_error, ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
    return TransferResult(
        scenario=scenario.name, method=str(getattr(plan, "method", "")), time_scale=float(time_scale),
        held=outcome == "carried", outcome=outcome, final_goal_error_rad=final_error,
        arrival_tolerance_rad=ARRIVAL_TOLERANCE_DC_MOTOR_RAD,
        max_slip_m=s["max_slip_m"], max_tilt_rad=s["max_tilt_rad"], max_gap_m=s["max_gap_m"],
        detached_at_s=detached, max_tracking_error_rad=s["max_tracking_error_rad"], peak_motor_torque_Nm=peak,
        peak_motor_torque_ratio=float(np.max(peak / scenario.limits.motor_torque_limit_Nm)),
        peak_moment_ratio_planned=moment / scenario.limits.moment_limit_Nm, peak_moment_planned_Nm=moment,
        peak_motor_torque_planned_Nm=planned_peak_motor_torque_Nm(scenario, plan, time_scale),
        energy_J=s["energy_J"], coil_current_A=td.coil_current_A, time_step_s=td.time_step_s,
        implicit_loop_damping=td.implicit_loop_damping,
        sim_time_s=td.t_final_s, sim_wall_s=wall, real_time_factor=td.t_final_s / wall,
        explicit_step_known_unstable=explicit_step_known_unstable(td.time_step_s, td.implicit_loop_damping),
        series=series)


def feedforward_keywords(scenario, feedforward: str) -> dict:
    """build_transfer_diagram keywords of a CLI --feedforward choice for this scenario's actuator, as
    its plug-in's magnet actuation takes it (an ideal torque source has no back EMF: 'full' is the
    inverse dynamics alone, 'back-emf' is refused). One-line QmtInputError for an unknown choice."""
    if feedforward not in FEEDFORWARD_OPTIONS:
        spatial = " ('shaped' shapes a spatial arm's reference; a planar plan is played as planned)" \
            if feedforward == "shaped" else ""
        raise QmtInputError(f"feedforward must be one of {sorted(FEEDFORWARD_OPTIONS)}, got {feedforward!r}{spatial}")
    return magnet_actuation_of(scenario).feedforward_keywords(scenario, feedforward)


def check_simulation_inputs(scenario, *, time_step_s: float | None = None,
                            implicit_loop_damping: bool | None = None, feedforward: str = "none") -> dict:
    """Everything `run_simulate` needs from the scenario and the options, checked before any planning
    or building: the hand, the actuator and its gains (its plug-in's magnet actuation checks them),
    the feedforward choice, the step (explicit steps above the known stable limit are refused).
    Returns the feedforward keywords."""
    magnet_hand_of(scenario)
    kw = feedforward_keywords(scenario, feedforward)
    magnet_actuation_of(scenario).check(scenario, implicit_loop_damping=implicit_loop_damping)
    implicit = True if implicit_loop_damping is None else bool(implicit_loop_damping)
    transfer_time_step(scenario, time_step_s, implicit)  # the run's step, or the scenario's simulation.plant's
    return kw


def transfer_simulate_cosim(scenario, plan, time_scale: float = 1.0, record_path=None,
                            time_step_s: float | None = None, implicit_loop_damping: bool | None = None,
                            feedforward: str = "none") -> CoSim:
    """The magnet hand's co-simulation as the CLI runs it (the plug-in's build_cosim): its summary is
    TransferResult.summary_dict with the feedforward choice (and the recording's path). feedforward: a
    FEEDFORWARD_OPTIONS key (the controller's feedforward terms). Refuses (one line) bad options, and
    steps the loop is known unstable at, before building anything (`check_simulation_inputs`)."""
    kw = check_simulation_inputs(scenario, time_step_s=time_step_s, implicit_loop_damping=implicit_loop_damping,
                                 feedforward=feedforward)
    extra = {"feedforward": feedforward, **({} if record_path is None else {"record_path": str(record_path)})}
    return build_transfer_cosim(scenario, plan, time_scale=time_scale, record_path=record_path, keep_series=False,
                                time_step_s=time_step_s, implicit_loop_damping=implicit_loop_damping,
                                summary_extra=extra, **kw)


def run_transfer_simulate(scenario, plan, time_scale: float = 1.0, record_path=None, time_step_s: float | None = None,
                          implicit_loop_damping: bool | None = None, feedforward: str = "none") -> dict:
    """The magnet hand's co-simulation as a JSON-ready dict (see TransferResult.summary_dict);
    hands.run_simulate dispatches here (transfer_simulate_cosim, run)."""
    return run(transfer_simulate_cosim(scenario, plan, time_scale, record_path, time_step_s, implicit_loop_damping,
                                       feedforward))
