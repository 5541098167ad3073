"""The closed-loop transfer Diagram: plan -> PID -> DC motors with gears -> arm -> magnet -> payload.

    TrajectorySource(plan, time-scaled) --desired_state--> JointPidController --voltage--> DcMotorWithGear
        --joint_torque (+ D qd, implicit loop damping)--> MultibodyPlant(arm + free payload, discrete,
        kLagged contact; settings: plant.transfer_plant_config)
    plant.state --> electromagnet_force --generalized_force--> plant (pull on the payload's joint to the hand)
    everything --> TransferMonitor (slip, tilt, detachment, tracking error, motor peaks, energy)

The monitor only observes. With step_logs=True (what simulate_transfer / run_simulate / the sweeps
use) and the implicitly stepped loop it is not called per step: C++ loggers record the plant
state, the reference and the applied joint torque every step and `TransferDiagram.summary` computes
the monitor's summary after the run (`sim.posthoc`; the same numbers, tests/test_cosim.py). Without
it (the default, which keeps the `summary` output port that user code such as
studies/contact_drift.py reads), or with the explicit scheme, the TransferMonitor runs every step.

`build_transfer_diagram` returns a `TransferDiagram` (the Diagram plus handles) whose DEFAULT context
is ready to simulate: the plant's default state is the plan's start with the payload seated, so
`Simulator(td.diagram)` run to td.t_final_s gives the runner's numbers (tests/test_cosim.py).
Everything about the hand, the motors and the payload comes from the scenario's typed sections.
What drives the arm is the scenario's actuator plug-in's (`sim.magnet_actuation.magnet_actuation_of`):
with actuator.kind 'ideal' the PID and the motors are replaced by a joint-side PD torque source
(`add_ideal_torque_actuation`; control.kp/kd in N*m/rad, N*m*s/rad), its damping stepped implicitly.

The payload's coordinates are its pose in the hand frame (systems/payload.py): a held part creeps
only by friction (ch.4 GA move: 0.035 mm at 0.5-2 ms; studies/contact_drift.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource

from qmt_drake.config.scenario import MagnetHand
from qmt_drake.errors import QmtInputError
from qmt_drake.plan_files import check_plan_fits
from qmt_drake.recording import add_floor, add_meshcat_visualizer, frame_arm
from qmt_drake.sim.actuation import add_inverse_dynamics_feedforward, check_time_step, default_time_step_s
from qmt_drake.sim.magnet_actuation import ActuationOptions, ActuationSite, magnet_actuation_of
from qmt_drake.sim.magnet_hand import add_magnet_hand, coil_current_for
from qmt_drake.sim.plant import (
    add_transfer_plant,
    finalize_transfer_plant,
    move_loop_damping_into_plant,
    set_initial_state,
)
from qmt_drake.sim.posthoc import add_step_logs, summary_from_logs
from qmt_drake.sim.reference import plan_start, reference_trajectories
from qmt_drake.sim.sim_settings import simulation_of, time_step_of
from qmt_drake.systems.dc_motor import DcMotorParams
from qmt_drake.systems.payload import PayloadSpec
from qmt_drake.systems.transfer_monitor import TransferMonitor, payload_motion_as_primitives


@dataclass
class TransferDiagram:
    """The built Diagram and what a user needs to run and read it."""

    diagram: object
    plant: object
    scene_graph: object
    arm_instance: object
    payload_body: object
    hand_body: object
    motors: object  # the motors (dc_motors_as_primitives' Diagram, or DcMotorWithGear with inductance); None: ideal
    controller: object  # JointPidController, its PD law as primitives, or the composed motor_actuation law; None: ideal
    magnet: object  # electromagnet_force's Diagram
    monitor: TransferMonitor | None  # None with per-step logs (payload_motion serves slip / tilt / gap)
    loggers: dict
    q_start: np.ndarray
    t_motion_end_s: float
    t_final_s: float
    coil_current_A: float
    payload_spec: PayloadSpec
    motor_params: DcMotorParams | None
    time_step_s: float
    implicit_loop_damping: bool
    visualizer: object = None
    simulator: object = None  # set by run_diagram (its context holds the loggers' data)
    step_logs: dict | None = None  # per-step C++ logs (sim.posthoc); None: the per-step monitor
    delivered: object = None  # the system whose motor_torque / electrical_power are reported
    simulator_settings: object = None  # the scenario's simulation.simulator (sim/cosim_run.run applies it)

    def summary(self, root_context) -> np.ndarray:
        """The monitor's summary (TransferMonitor.SUMMARY_FIELDS + peak motor torques) of the run
        simulated in root_context: from the per-step logs, or the per-step monitor's state."""
        if self.step_logs is not None:
            return summary_from_logs(self, root_context)
        return np.asarray(self.diagram.GetOutputPort("summary").Eval(root_context))

    def set_initial_state(self, root_context) -> None:
        """Arm at the plan's start, payload seated on the face, everything at rest (what the
        default context already holds; use it to reset a context that was changed)."""
        set_initial_state(self.plant, self.plant.GetMyMutableContextFromRoot(root_context), self.arm_instance,
                          self.hand_body, self.payload_body, self.q_start)


def transfer_time_step(scenario, time_step_s: float | None, implicit_loop_damping: bool, *,
                       refuse_unstable: bool = True) -> float:
    """The plant step [s]: the run's time_step_s, else the scenario's simulation.plant.time_step, else the loop
    scheme's default (`default_time_step_s`); checked (`check_time_step`), a step from the scenario named so."""
    step = time_step_of(time_step_s, scenario, default_time_step_s(implicit_loop_damping))
    try:
        check_time_step(step, implicit_loop_damping, refuse_unstable=refuse_unstable)
    except QmtInputError as exc:
        if time_step_s is not None or simulation_of(scenario).plant.time_step is None:
            raise
        raise QmtInputError(f"scenario {scenario.name}: simulation.plant.time_step: {exc}") from None
    return step


def build_transfer_diagram(scenario, plan, *, time_step_s: float | None = None, time_scale: float = 1.0,
                           lead_s: float = 0.2, settle_s: float = 0.5, coil_current_A: float | None = None,
                           payload_spec: PayloadSpec | None = None, inverse_dynamics_feedforward: bool = False,
                           back_emf_feedforward: bool = False, log_period_s: float = 5e-3,
                           monitor_period_s: float | None = None, step_logs: bool = False,
                           primitive_controller: bool = True,
                           motor_inductance: bool = False, implicit_loop_damping: bool | None = None,
                           motor_params: DcMotorParams | None = None, magnet_effective_gap_m: float | None = None,
                           meshcat: Meshcat | None = None, allow_unstable_step: bool = False) -> TransferDiagram:
    """One Diagram for the whole closed loop (see the module docstring); its default context starts
    at the plan's start with the payload seated.

    An explicit motor loop (implicit_loop_damping False) stepped above 1 ms is known unstable (the
    motors chatter between their current limits): refused in one line (QmtInputError) unless
    allow_unstable_step=True, for studies of that instability (the result then says
    explicit_step_known_unstable). With meshcat, a floor is added under the arm (a lost part lands
    on it) and the camera is pointed at the arm from its reach (qmt_drake/recording.py).

    Exported output ports (units as in the systems' docstrings): desired_state (2n) [rad, rad/s],
    arm_state (2n), voltage_command (n) [V], joint_torque (n) [N*m], motor_torque (n) [N*m],
    current (n) [A], electrical_power (n) [W], attraction_force (1) [N], slip (1) [m], tilt (1) [rad],
    gap (1) [m], summary (TransferMonitor.SUMMARY_FIELDS + peak motor torques; only with the
    per-step monitor, otherwise TransferDiagram.summary(context)), body_poses, contact_results. Raises QmtInputError (one line) when the plan's joint count differs from the
    arm's. coil_current_A=None uses the scenario's hand (hand.coil_current_A or the calibration
    rule); lead_s of rest precedes the motion and settle_s follows it. motor_inductance=True gives
    the armature current a continuous state (L di/dt = v - R i - Ke w; L/R ~ 0.1-0.2 ms, so the
    integrator takes small steps: slow). motor_params (DcMotorParams) replaces the scenario's motors
    and magnet_effective_gap_m [m] the hand's g0 (sweeps over motor constants and the gap; the coil
    current is then still the one given or calibrated for the scenario).

    implicit_loop_damping (default: on, except with motor_inductance) steps the loop's velocity
    feedback implicitly (`add_implicit_damping_actuation`), which keeps the loop stable at the 2 ms
    default step; off, the motors drive the plant directly (explicit) and time_step_s must be
    <= 1 ms (the 1 ms default; larger steps are refused). time_step_s=None picks the scheme's
    default (`default_time_step_s`), or the scenario's simulation.plant.time_step when it gives one (its
    other simulation.plant fields replace transfer_plant_config's). step_logs=True (implicit loop only) replaces the per-step
    monitor by per-step C++ logs and TransferDiagram.summary (module docstring); the diagram then
    has no `summary` output port. monitor_period_s samples the per-step monitor more sparsely.
    primitive_controller: a PD law (no integral term) runs as Drake primitives
    (joint_tracking.primitive_pd_controller; False: the Python JointPidController, the same law)."""
    actuation = magnet_actuation_of(scenario)  # the actuator plug-in's: what to check and build
    options = ActuationOptions(implicit_loop_damping=implicit_loop_damping, motor_inductance=motor_inductance,
                               back_emf_feedforward=back_emf_feedforward,
                               inverse_dynamics_feedforward=inverse_dynamics_feedforward,
                               primitive_controller=primitive_controller, motor_params=motor_params)
    implicit_loop_damping = actuation.loop_scheme(scenario, options)
    time_step_s = transfer_time_step(scenario, time_step_s, implicit_loop_damping,
                                     refuse_unstable=not allow_unstable_step)
    if scenario.hand is not None and not isinstance(scenario.hand, MagnetHand):
        raise QmtInputError(f"build_transfer_diagram builds the magnet hand's diagram; scenario {scenario.name} "
                            f"has a {scenario.hand.kind} hand (on a tray: Dynamixel servos): use qmt_drake.build_diagram")
    check_plan_fits(plan, scenario)  # a plan made for another scenario is refused here, not only by the CLI
    builder = DiagramBuilder()
    tp = add_transfer_plant(builder, scenario, time_step_s, payload_spec=payload_spec,
                            n_dof_expected=int(plan.n_dof))
    plant, arm, hand, payload, spec, n = (tp.plant, tp.arm_instance, tp.hand_body, tp.payload_body,
                                          tp.payload_spec, tp.n_dof)
    setup = actuation.setup(scenario, options, implicit_loop_damping)
    if setup.loop_damping is not None:
        move_loop_damping_into_plant(plant, arm, setup.loop_damping)
    q0 = plan_start(plan)
    if meshcat is not None:
        add_floor(plant, arm)
    finalize_transfer_plant(tp, q0)

    current = coil_current_for(scenario, spec) if coil_current_A is None else float(coil_current_A)
    pp_q, pp_qdd, t_end = reference_trajectories(plan, time_scale, lead_s)

    ref = builder.AddNamedSystem("reference", TrajectorySource(pp_q, output_derivative_order=1))
    arm_state = plant.get_state_output_port(arm)
    ports = actuation.add(ActuationSite(builder, plant, arm, n, ref.get_output_port(), arm_state, time_step_s),
                          scenario, setup, options)
    ctrl, motors, delivered = ports.controller, ports.motors, ports.delivered
    magnet = add_magnet_hand(builder, plant, hand, payload, scenario, spec, current, magnet_effective_gap_m,
                             host_has_continuous_state=bool(motor_inductance))
    # Per-step logs instead of a per-step Python monitor when the loop is stepped implicitly (the
    # applied torque is then latched, see sim.posthoc); an explicit monitor_period_s keeps the monitor.
    log_steps = bool(step_logs) and bool(implicit_loop_damping) and monitor_period_s is None
    # With per-step logs nothing in Python runs during the simulation: slip / tilt / gap come from the
    # payload's joint coordinates through primitives, and run_diagram checks the seated start.
    monitor = motion = None
    if log_steps:
        motion = builder.AddNamedSystem("payload_motion", payload_motion_as_primitives(plant, tp.payload_joint))
        builder.Connect(plant.get_state_output_port(), motion.GetInputPort("plant_state"))
    else:
        monitor = builder.AddNamedSystem("monitor", TransferMonitor(
            n, hand.index(), payload.index(), period_s=monitor_period_s or time_step_s))
        motion = monitor

    step_logs = None
    if log_steps:
        step_logs = add_step_logs(builder, plant, ref.get_output_port(),
                                  builder.GetSubsystemByName("applied_joint_torque").get_output_port(), time_step_s)
    if monitor is not None:
        builder.Connect(plant.get_body_poses_output_port(), monitor.GetInputPort("body_poses"))
        builder.Connect(arm_state, monitor.GetInputPort("arm_state"))
        builder.Connect(ref.get_output_port(), monitor.GetInputPort("desired_state"))
        builder.Connect(delivered.GetOutputPort("motor_torque"), monitor.GetInputPort("motor_torque"))
        builder.Connect(delivered.GetOutputPort("electrical_power"), monitor.GetInputPort("electrical_power"))

    if inverse_dynamics_feedforward:
        add_inverse_dynamics_feedforward(builder, scenario, pp_qdd, ref.get_output_port(), ports.feedforward_input)

    exports = {
        "desired_state": ref.get_output_port(),
        "arm_state": arm_state,
        "voltage_command": None if ctrl is None else ctrl.GetOutputPort("voltage_command"),  # no PID: none
        "joint_torque": delivered.GetOutputPort("joint_torque"),
        "motor_torque": delivered.GetOutputPort("motor_torque"),
        "current": delivered.GetOutputPort("current"),
        "electrical_power": delivered.GetOutputPort("electrical_power"),
        "attraction_force": magnet.GetOutputPort("attraction_force"),
        "slip": motion.GetOutputPort("slip"),
        "tilt": motion.GetOutputPort("tilt"),
        "gap": motion.GetOutputPort("gap"),
        "summary": None if log_steps else monitor.GetOutputPort("summary"),  # logs: TransferDiagram.summary
        "body_poses": plant.get_body_poses_output_port(),
        "contact_results": plant.get_contact_results_output_port(),
    }
    exports = {k: v for k, v in exports.items() if v is not None}
    for name, port in exports.items():
        builder.ExportOutput(port, name)
    loggers = {}
    if log_period_s:
        for name in ("desired_state", "arm_state", "voltage_command", "motor_torque", "current",
                     "electrical_power", "attraction_force", "slip", "tilt", "gap"):
            if name in exports:
                loggers[name] = LogVectorOutput(exports[name], builder, log_period_s)

    visualizer = None
    if meshcat is not None:
        visualizer = add_meshcat_visualizer(builder, tp.scene_graph, meshcat)

    diagram = builder.Build()
    diagram.set_name(f"transfer[{scenario.name}]")
    if meshcat is not None:
        ctx = diagram.CreateDefaultContext()
        frame_arm(meshcat, plant, plant.GetMyContextFromRoot(ctx), arm)
    return TransferDiagram(diagram, plant, tp.scene_graph, arm, payload, hand, motors, ctrl, magnet, monitor,
                           loggers, q0, t_end, t_end + settle_s, current, spec, setup.motor_params, time_step_s,
                           bool(implicit_loop_damping), visualizer, step_logs=step_logs, delivered=delivered,
                           simulator_settings=simulation_of(scenario).simulator)
