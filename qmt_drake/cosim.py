"""Co-simulation of a planned transfer: plan -> PID -> DC motors with gears -> arm -> magnet -> payload.

    TrajectorySource(plan, time-scaled) --desired_state--> JointPidController --voltage--> DcMotorWithGear
        --joint_torque (+ D qd, implicit loop damping)--> MultibodyPlant(arm + free payload, discrete,
        kLagged contact)
    plant.body_poses --> ElectromagnetForce --spatial_forces--> plant (pull on the payload, reaction on hand)
    everything --> TransferMonitor (slip, tilt, detachment, tracking error, motor peaks, energy)

`build_transfer_diagram` returns a `TransferDiagram` (the Diagram plus handles); `simulate_transfer`
runs it and returns a `TransferResult`; `run_simulate` is the CLI's entry point (a JSON-ready dict).

Magnet calibration (`calibrated_coil_current_A`): seed 000 does not report the coil current or
voltage. One rule is applied to both hands: the coil current is the one whose quasi-static hold
limit equals the geometric mean of the thesis's last-success and first-failure moments
(Table 2.3: 3.168e-5 / 3.344e-5 N*m; Table 4.2: 0.633e-3 / 0.727e-3 N*m):

    tau_hold = (F(I, 0) - m g) * min(rho, mu * r_G)

(the part tips about the edge of the contact ring of radius rho when m a r_G exceeds the net
normal force times rho, or slides when m a exceeds mu times it). Everything else is shared by
both hands: the magnet law and its equivalent gap g0, friction, contact stiffness, contact radius
(the 7.8 mm core of both hands). The simulated thresholds are then an outcome of the dynamics,
checked by studies/cosim_calibration.py against every row of both tables (result: ch.2 between
3.2245e-5 and 3.2273e-5 N*m, ch.4 between 0.640e-3 and 0.641e-3 N*m at the default 2 ms step, all
14 rows as in the thesis; ch.4 sits 1% above its lower boundary because the moving arm tips the
part earlier than the static bound). The two calibrated currents cannot come from one supply voltage: the ch.2 coil would need
0.41 of the ch.4 coil's voltage (see out/cosim_calibration.json, shared_voltage_counterfactual).

Assumptions worth knowing: MAGNET_EFFECTIVE_GAP_M (g0 = 0.5 mm) is assumed, not measured; it sets
how fast the pull fades once the part tips, i.e. how surely a tipped part falls. Held payloads
show a drift of the first-order discrete step as slip; it grows in proportion to the plant step
and does not depend on friction or contact stiffness (ch.4 GA move: 0.35 mm at 1 ms, 0.67 mm at
2 ms; studies/contact_drift.py). The stiff thesis-gain position
loop is unstable at 2 ms when the motors drive the plant explicitly; by default its velocity
feedback is stepped implicitly (`add_implicit_damping_actuation`), which runs at 2 ms with the same
motion and motor torques as a 0.25 ms explicit run (studies/bench_cosim.py, tests/test_cosim.py).
"""

from __future__ import annotations

import gc
import math
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.multibody.parsing import Parser
from pydrake.multibody.tree import JointActuatorIndex
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (Adder, ConstantVectorSource, Demultiplexer, LogVectorOutput, MatrixGain,
                                        TrajectorySource, ZeroOrderHold)
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError, QmtSimulationError
from qmt_drake.systems.dc_motor import AppliedMotorSignals, DcMotorParams, DcMotorWithGear
from qmt_drake.systems.electromagnet import THESIS_COILS, ElectromagnetForce, MagnetParams
from qmt_drake.systems.joint_tracking import JointPidController, PidGains, effective_joint_gains
from qmt_drake.systems.payload import PayloadSpec, add_payload, seated_pose_in_hand
from qmt_drake.systems.transfer_monitor import TransferMonitor

GRAVITY_M_S2 = 9.81
MAGNET_EFFECTIVE_GAP_M = 0.5e-3  # g0: assumption, shared by both hands (see electromagnet.py)
HELD_SLIP_LIMIT_M = 1e-3  # "held": never detached and slip below 1 mm
# Plant steps: the implicitly damped loop (default) is stable and accurate at 2 ms; the explicit
# loop needs 1 ms (studies/bench_cosim.py measures both against a 0.25 ms explicit reference).
IMPLICIT_TIME_STEP_S = 2e-3
EXPLICIT_TIME_STEP_S = 1e-3

# Thesis slip experiments: the last success and first failure in peak moment [N*m].
SLIP_BOUNDARIES_NM = {
    "ch2": (3.168e-5, 3.344e-5),  # seed 000 Table 2.3
    "ch4": (0.633e-3, 0.727e-3),  # seed 000 Table 4.2
}
HAND_COIL = {"ch2": THESIS_COILS["table_2_2"], "ch4": THESIS_COILS["table_3_2"]}


def hand_of(scenario) -> str:
    """'ch2' for the chapter-2 three-link arm and its Table 2.2 hand, 'ch4' for the ch.3-4 hand."""
    return "ch2" if "three_link" in scenario.urdf_path.stem else "ch4"


def hold_lever_m(payload: PayloadSpec) -> float:
    """min(rho, mu * r_G) [m]: net normal force times this is the quasi-static hold moment."""
    return min(payload.contact_radius_m, payload.friction * payload.com_offset_m)


def calibrated_coil_current_A(scenario, payload: PayloadSpec, *, effective_gap_m: float | None = None,
                              boundary_Nm: tuple[float, float] | None = None) -> float:
    """The calibration rule (module docstring): coil current [A] for this scenario's hand."""
    effective_gap_m = MAGNET_EFFECTIVE_GAP_M if effective_gap_m is None else effective_gap_m
    hand = hand_of(scenario)
    lo, hi = boundary_Nm or SLIP_BOUNDARIES_NM[hand]
    tau_star = math.sqrt(lo * hi)
    force = payload.mass_kg * GRAVITY_M_S2 + tau_star / hold_lever_m(payload)
    return MagnetParams(HAND_COIL[hand], effective_gap_m, payload.face_radius_m).current_for_force_A(force)


# ------------------------------------------------------------------------------------ the plan
def reference_trajectories(plan, time_scale: float = 1.0, lead_s: float = 0.2, rate_hz: float = 1000.0):
    """Cubic-Hermite q(t) and first-order-hold qdd(t) of the plan slowed by `time_scale`
    (t_sim = lead_s + time_scale * t_plan), sampled at rate_hz; returns (pp_q, pp_qdd, t_end_motion)."""
    if not time_scale > 0:
        raise QmtInputError(f"time scale must be positive, got {time_scale}")
    T = float(plan.motion_time_s) * time_scale
    t = np.arange(0.0, lead_s + T + 0.5 / rate_hz, 1.0 / rate_hz)
    t = np.append(t[t < lead_s + T - 1e-9], lead_s + T)
    tp = np.clip((t - lead_s) / time_scale, 0.0, float(plan.motion_time_s))
    q, qd, qdd = (np.asarray(a, float) for a in plan.sample(tp))
    moving = (t >= lead_s)[:, None]
    qd = np.where(moving, qd / time_scale, 0.0)
    qdd = np.where(moving, qdd / time_scale**2, 0.0)
    pp_q = PiecewisePolynomial.CubicHermite(t, q.T, qd.T)
    pp_qdd = PiecewisePolynomial.FirstOrderHold(t, qdd.T)
    return pp_q, pp_qdd, lead_s + T


# ------------------------------------------------------------------------------------ the diagram
@dataclass
class TransferDiagram:
    """The built Diagram and what a user needs to run and read it."""

    diagram: object
    plant: object
    scene_graph: object
    arm_instance: object
    payload_body: object
    hand_body: object
    motors: DcMotorWithGear
    controller: JointPidController
    magnet: ElectromagnetForce
    monitor: TransferMonitor
    loggers: dict
    q_start: np.ndarray
    t_motion_end_s: float
    t_final_s: float
    coil_current_A: float
    payload_spec: PayloadSpec
    motor_params: DcMotorParams
    time_step_s: float
    implicit_loop_damping: bool
    visualizer: object = None
    simulator: object = None  # set by run_diagram (its context holds the loggers' data)

    def set_initial_state(self, root_context) -> None:
        """Arm at the plan's start, payload seated on the face, everything at rest."""
        set_initial_state(self.plant, self.plant.GetMyMutableContextFromRoot(root_context), self.arm_instance,
                          self.hand_body, self.payload_body, self.q_start)


def set_initial_state(plant, plant_context, arm_instance, hand_body, payload_body, q_start) -> None:
    plant.SetPositions(plant_context, arm_instance, q_start)
    plant.SetVelocities(plant_context, arm_instance, np.zeros(len(q_start)))
    X_WH = plant.EvalBodyPoseInWorld(plant_context, hand_body)
    plant.SetFreeBodyPose(plant_context, payload_body, X_WH.multiply(seated_pose_in_hand()))
    plant.SetFreeBodySpatialVelocity(plant_context, payload_body, _zero_spatial_velocity())


def _zero_spatial_velocity():
    from pydrake.multibody.math import SpatialVelocity
    return SpatialVelocity(np.zeros(3), np.zeros(3))


def motor_params_for(scenario, with_inductance: bool = False) -> DcMotorParams:
    """One catalogue motor per joint, chosen by the scenario's rated motor torque (dc_motor.py)."""
    return DcMotorParams.for_rated_torques(scenario.limits.motor_torque_limit_Nm, scenario.gear_ratio,
                                           with_inductance=with_inductance)


def pid_gains_for(scenario) -> PidGains:
    c = scenario.control
    if not all(k in c for k in ("kp", "kd")):
        raise QmtInputError(f"scenario '{scenario.name}' has no control.kp/kd gains; add them to its YAML")
    return PidGains.from_thesis(c["kp"], c.get("ki"), c["kd"])


def default_time_step_s(implicit_loop_damping: bool) -> float:
    """The plant step [s] each stepping scheme is run at unless told otherwise (studies/bench_cosim.py)."""
    return IMPLICIT_TIME_STEP_S if implicit_loop_damping else EXPLICIT_TIME_STEP_S


def build_transfer_diagram(scenario, plan, *, time_step_s: float | None = None, time_scale: float = 1.0,
                           lead_s: float = 0.2, settle_s: float = 0.5, coil_current_A: float | None = None,
                           payload_spec: PayloadSpec | None = None, inverse_dynamics_feedforward: bool = False,
                           back_emf_feedforward: bool = False, log_period_s: float = 5e-3,
                           monitor_period_s: float | None = None,
                           motor_inductance: bool = False, implicit_loop_damping: bool | None = None,
                           meshcat: Meshcat | None = None) -> TransferDiagram:
    """One Diagram for the whole closed loop (see the module docstring).

    Exported output ports (units as in the systems' docstrings): desired_state (2n) [rad, rad/s],
    arm_state (2n), voltage_command (n) [V], joint_torque (n) [N*m], motor_torque (n) [N*m],
    current (n) [A], electrical_power (n) [W], attraction_force (1) [N], slip (1) [m], tilt (1) [rad],
    gap (1) [m], summary (TransferMonitor.SUMMARY_FIELDS + peak motor torques), body_poses,
    contact_results. Raises QmtInputError (one line) when the plan's joint count differs from the
    arm's. coil_current_A=None uses the calibration rule; lead_s of rest precedes the motion and
    settle_s follows it. motor_inductance=True gives the armature current a continuous state
    (L di/dt = v - R i - Ke w; L/R ~ 0.1-0.2 ms, so the integrator takes small steps: slow).

    implicit_loop_damping (default: on, except with motor_inductance) steps the loop's velocity
    feedback implicitly (`add_implicit_damping_actuation`), which keeps the loop stable at the 2 ms
    default step; off, the motors drive the plant directly (explicit) and need time_step_s <= 1 ms
    (the 1 ms default). time_step_s=None picks the scheme's default (`default_time_step_s`)."""
    if implicit_loop_damping is None:
        implicit_loop_damping = not motor_inductance
    if implicit_loop_damping and motor_inductance:
        raise QmtInputError("implicit_loop_damping needs the quasi-static armature; with motor_inductance=True "
                            "pass implicit_loop_damping=False and time_step_s <= 1e-3")
    if time_step_s is None:
        time_step_s = default_time_step_s(implicit_loop_damping)
    if not time_step_s > 0:
        raise QmtInputError(f"time step must be positive, got {time_step_s} s")
    n_plan = int(plan.n_dof)
    builder = DiagramBuilder()
    # Live output ports: with sampled ones, discrete-update systems (monitor, PID integral) reading
    # the plant during its step saw the next state paired with this step's reference.
    cfg = MultibodyPlantConfig(time_step=time_step_s, discrete_contact_approximation="lagged", contact_model="point",
                               use_sampled_output_ports=False)
    plant, scene_graph = AddMultibodyPlant(cfg, builder)
    arm = Parser(plant).AddModels(str(scenario.urdf_path))[0]
    n = sum(plant.get_joint(j).num_velocities() for j in plant.GetJointIndices(arm))
    if n_plan != n:
        raise QmtInputError(f"plan has {n_plan} joints but scenario '{scenario.name}' arm "
                            f"({scenario.urdf_path.name}) has {n}; use a plan made for this scenario")
    hand = plant.GetBodyByName(scenario.hand_frame, arm)
    spec = payload_spec or PayloadSpec.for_scenario(scenario)
    payload = add_payload(plant, spec, hand)
    gains = pid_gains_for(scenario)
    mp = motor_params_for(scenario, with_inductance=motor_inductance)
    loop_damping = effective_joint_gains(gains, mp)[1] if implicit_loop_damping else None
    if loop_damping is not None:
        move_loop_damping_into_plant(plant, arm, loop_damping)
    plant.Finalize()

    coil = HAND_COIL[hand_of(scenario)]
    current = calibrated_coil_current_A(scenario, spec) if coil_current_A is None else float(coil_current_A)
    pp_q, pp_qdd, t_end = reference_trajectories(plan, time_scale, lead_s)

    ref = builder.AddNamedSystem("reference", TrajectorySource(pp_q, output_derivative_order=1))
    ctrl = builder.AddNamedSystem("controller", JointPidController(
        gains, mp.gear_ratio, mp.voltage_limit_V, control_period_s=time_step_s, motor=mp,
        back_emf_feedforward=back_emf_feedforward, torque_feedforward=inverse_dynamics_feedforward))
    motors = builder.AddNamedSystem("motors", DcMotorWithGear(mp))
    split = builder.AddNamedSystem("arm_state_split", Demultiplexer([n, n]))
    magnet_params = MagnetParams(coil, MAGNET_EFFECTIVE_GAP_M, spec.face_radius_m)
    magnet = builder.AddNamedSystem("magnet", ElectromagnetForce(magnet_params, hand.index(), payload.index()))
    coil_src = builder.AddNamedSystem("coil_current", ConstantVectorSource([current]))
    monitor = builder.AddNamedSystem("monitor", TransferMonitor(n, hand.index(), payload.index(),
                                                                period_s=monitor_period_s or time_step_s))

    arm_state = plant.get_state_output_port(arm)
    builder.Connect(ref.get_output_port(), ctrl.GetInputPort("desired_state"))
    builder.Connect(arm_state, ctrl.GetInputPort("estimated_state"))
    builder.Connect(ctrl.GetOutputPort("voltage_command"), motors.GetInputPort("voltage_command"))
    builder.Connect(arm_state, split.get_input_port())
    builder.Connect(split.get_output_port(1), motors.GetInputPort("joint_velocity"))
    # What the motors deliver: their own outputs when stepped explicitly; with implicit loop damping,
    # the torque applied over the last step, read back through the motor model.
    delivered = motors
    if loop_damping is None:
        builder.Connect(motors.GetOutputPort("joint_torque"), plant.get_actuation_input_port(arm))
    else:
        delivered = add_implicit_damping_actuation(builder, plant, arm, motors, split.get_output_port(1),
                                                   loop_damping, time_step_s, mp)
    builder.Connect(plant.get_body_poses_output_port(), magnet.GetInputPort("body_poses"))
    builder.Connect(coil_src.get_output_port(), magnet.GetInputPort("coil_current"))
    builder.Connect(magnet.GetOutputPort("spatial_forces"), plant.get_applied_spatial_force_input_port())
    builder.Connect(plant.get_body_poses_output_port(), monitor.GetInputPort("body_poses"))
    builder.Connect(arm_state, monitor.GetInputPort("arm_state"))
    builder.Connect(ref.get_output_port(), monitor.GetInputPort("desired_state"))
    builder.Connect(delivered.GetOutputPort("motor_torque"), monitor.GetInputPort("motor_torque"))
    builder.Connect(delivered.GetOutputPort("electrical_power"), monitor.GetInputPort("electrical_power"))

    if inverse_dynamics_feedforward:
        add_inverse_dynamics_feedforward(builder, scenario, pp_qdd, ref.get_output_port(),
                                         ctrl.GetInputPort("feedforward_torque"))

    exports = {
        "desired_state": ref.get_output_port(),
        "arm_state": arm_state,
        "voltage_command": ctrl.GetOutputPort("voltage_command"),
        "joint_torque": delivered.GetOutputPort("joint_torque"),
        "motor_torque": delivered.GetOutputPort("motor_torque"),
        "current": delivered.GetOutputPort("current"),
        "electrical_power": delivered.GetOutputPort("electrical_power"),
        "attraction_force": magnet.GetOutputPort("attraction_force"),
        "slip": monitor.GetOutputPort("slip"),
        "tilt": monitor.GetOutputPort("tilt"),
        "gap": monitor.GetOutputPort("gap"),
        "summary": monitor.GetOutputPort("summary"),
        "body_poses": plant.get_body_poses_output_port(),
        "contact_results": plant.get_contact_results_output_port(),
    }
    for name, port in exports.items():
        builder.ExportOutput(port, name)
    loggers = {}
    if log_period_s:
        for name in ("desired_state", "arm_state", "voltage_command", "motor_torque", "current",
                     "electrical_power", "attraction_force", "slip", "tilt", "gap"):
            loggers[name] = LogVectorOutput(exports[name], builder, log_period_s)

    visualizer = None
    if meshcat is not None:
        from qmt_drake.recording import add_meshcat_visualizer
        visualizer = add_meshcat_visualizer(builder, scene_graph, meshcat)

    diagram = builder.Build()
    diagram.set_name(f"transfer[{scenario.name}]")
    q0 = np.asarray(plan.sample(np.array([0.0]))[0], float).reshape(-1)
    return TransferDiagram(diagram, plant, scene_graph, arm, payload, hand, motors, ctrl, magnet, monitor,
                           loggers, q0, t_end, t_end + settle_s, current, spec, mp, time_step_s,
                           bool(implicit_loop_damping), visualizer)


def move_loop_damping_into_plant(plant, arm_instance, loop_damping) -> None:
    """Before Finalize: add loop_damping [N*m*s/rad] (one per actuator, in actuator order) to the
    actuated joints' damping, which the discrete plant steps implicitly, and lift the actuators'
    effort limits (the motor model limits the torque; the actuation input now also carries D*qd)."""
    actuators = [JointActuatorIndex(i) for i in range(plant.num_actuators())
                 if plant.get_joint_actuator(JointActuatorIndex(i)).model_instance() == arm_instance]
    for d, index in zip(loop_damping, actuators):
        actuator = plant.get_mutable_joint_actuator(index)
        joint = plant.get_mutable_joint(actuator.joint().index())
        joint.set_default_damping(joint.default_damping() + float(d))
        actuator.set_effort_limit(float("inf"))


def add_implicit_damping_actuation(builder, plant, arm_instance, motors, joint_velocity_port, loop_damping,
                                   time_step_s, motor_params):
    """Wire the motors into the plant with their velocity feedback stepped implicitly.

    Linearly implicit stepping: the loop's stiff part is its damping D = dtau_j/dqd (the PID's
    derivative through the motors plus the back EMF, `effective_joint_gains`). The plant's joints
    carry D as joint damping, which the discrete solver steps implicitly, and the actuation input is
    tau_motor(x_n) + D qd_n, so over a step the arm receives tau_motor(x_n) - D (qd_{n+1} - qd_n):
    exactly the motors' torque in their linear range, and stable at steps where the explicit loop is
    not (ch.4 poles to -900 rad/s). The torque actually applied over step n is known after it:
    a zero-order hold keeps u_n, and u_n - D qd_{n+1} goes through the motor model backwards
    (`AppliedMotorSignals`) for the current, motor torque and power that are reported; the motors'
    own outputs, evaluated at x_n, overstate the torque by about D h / J. Returns the
    AppliedMotorSignals system."""
    n = len(loop_damping)
    D = np.diag(np.asarray(loop_damping, float))
    add_back = builder.AddNamedSystem("damping_add_back", MatrixGain(D))
    actuation = builder.AddNamedSystem("actuation", Adder(2, n))
    builder.Connect(joint_velocity_port, add_back.get_input_port())
    builder.Connect(motors.GetOutputPort("joint_torque"), actuation.get_input_port(0))
    builder.Connect(add_back.get_output_port(), actuation.get_input_port(1))
    builder.Connect(actuation.get_output_port(), plant.get_actuation_input_port(arm_instance))
    latch = builder.AddNamedSystem("actuation_latch", ZeroOrderHold(time_step_s, n))
    damping_now = builder.AddNamedSystem("damping_now", MatrixGain(-D))
    applied = builder.AddNamedSystem("applied_joint_torque", Adder(2, n))
    builder.Connect(actuation.get_output_port(), latch.get_input_port())
    builder.Connect(joint_velocity_port, damping_now.get_input_port())
    builder.Connect(latch.get_output_port(), applied.get_input_port(0))
    builder.Connect(damping_now.get_output_port(), applied.get_input_port(1))
    signals = builder.AddNamedSystem("applied_motor_signals", AppliedMotorSignals(motor_params))
    builder.Connect(applied.get_output_port(), signals.GetInputPort("applied_joint_torque"))
    builder.Connect(joint_velocity_port, signals.GetInputPort("joint_velocity"))
    return signals


def add_inverse_dynamics_feedforward(builder, scenario, pp_qdd, desired_state_port, feedforward_input):
    """Drake InverseDynamics of the arm alone (continuous plant, reflected rotor inertia included),
    evaluated on the desired state and acceleration, into the controller's feedforward_torque."""
    id_plant = scenario.arm.plant
    inv = builder.AddNamedSystem("inverse_dynamics", InverseDynamics(id_plant))
    acc = builder.AddNamedSystem("desired_acceleration", TrajectorySource(pp_qdd))
    builder.Connect(desired_state_port, inv.get_input_port_estimated_state())
    builder.Connect(acc.get_output_port(), inv.get_input_port_desired_acceleration())
    builder.Connect(inv.get_output_port_generalized_force(), feedforward_input)


# ------------------------------------------------------------------------------------ simulation
@dataclass
class TransferResult:
    """One co-simulated transfer. Times are simulation time: lead_s (0.2 s) of rest, the plan slowed
    by time_scale, settle_s (0.5 s); detached_at_s counts from the start of the lead (None: never).
    held = never detached and max_slip_m < 1 mm. peak_motor_torque_ratio is the simulated peak over
    the scenario's rated motor torque; peak_moment_ratio_planned is the time-scaled plan's
    m_o r_G |a_tip| peak over the moment limit. real_time_factor = sim_time_s / sim_wall_s.
    series (if kept): 5 ms samples of the exported signals, see logged_series."""

    scenario: str
    method: str
    time_scale: float
    held: bool
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
    series: dict = field(default_factory=dict, repr=False)

    def summary_dict(self) -> dict:
        d = {k: getattr(self, k) for k in (
            "scenario", "method", "time_scale", "held", "max_slip_m", "max_tilt_rad", "max_gap_m", "detached_at_s",
            "max_tracking_error_rad", "peak_motor_torque_ratio", "peak_moment_ratio_planned",
            "peak_moment_planned_Nm", "energy_J", "coil_current_A", "time_step_s", "implicit_loop_damping",
            "sim_time_s", "sim_wall_s", "real_time_factor")}
        d["peak_motor_torque_Nm"] = [float(x) for x in self.peak_motor_torque_Nm]
        d["peak_motor_torque_planned_Nm"] = [float(x) for x in self.peak_motor_torque_planned_Nm]
        return {k: (float(v) if isinstance(v, (np.floating,)) else v) for k, v in d.items()}


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


def run_diagram(td: TransferDiagram, *, chunk_s: float = 0.05, max_tracking_error_rad: float = 0.5,
                on_start=None) -> tuple[np.ndarray, float]:
    """Simulate to td.t_final_s; returns (monitor summary, wall seconds). Raises QmtSimulationError
    naming the failure time when the state becomes non-finite, Drake's solver fails, or the arm
    leaves its reference by more than max_tracking_error_rad (an unstable loop: the voltage limit
    keeps the state finite, so this is how divergence shows)."""
    sim = Simulator(td.diagram)
    ctx = sim.get_mutable_context()
    td.set_initial_state(ctx)
    sim.Initialize()
    if on_start is not None:
        on_start(sim)
    plant_ctx = td.plant.GetMyContextFromRoot(ctx)
    ref = td.diagram.GetOutputPort("desired_state")
    n = len(td.q_start)
    t_wall = time.perf_counter()
    # The Python systems allocate small arrays every step; the cyclic collector would otherwise
    # run thousands of times per simulated second for nothing (the arrays form no cycles).
    gc_was_enabled = gc.isenabled()
    gc.disable()
    try:
        _advance(sim, td, ctx, plant_ctx, ref, n, chunk_s, max_tracking_error_rad)
    finally:
        if gc_was_enabled:
            gc.enable()
    wall = time.perf_counter() - t_wall
    summary = td.diagram.GetOutputPort("summary").Eval(ctx)
    td.simulator = sim
    return np.asarray(summary), wall


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
                f"simulation diverged at t = {ctx.get_time():.3f} s: joint tracking error {err:.3g} rad > "
                f"{max_tracking_error_rad} rad (unstable control loop: use a smaller time step, "
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


def simulate_transfer(scenario, plan, *, time_scale: float = 1.0, time_step_s: float | None = None,
                      record_path=None, keep_series: bool = True, **build_kw) -> TransferResult:
    """Build, run and summarise one transfer (see TransferResult)."""
    meshcat = None
    if record_path is not None:
        from qmt_drake.recording import make_headless_meshcat
        meshcat = make_headless_meshcat()
    td = build_transfer_diagram(scenario, plan, time_step_s=time_step_s, time_scale=time_scale,
                                meshcat=meshcat, log_period_s=5e-3 if keep_series else 0.0, **build_kw)
    on_start = None
    if meshcat is not None:
        from qmt_drake.recording import start_recording
        on_start = lambda sim: start_recording(td.visualizer)  # noqa: E731
    summary, wall = run_diagram(td, on_start=on_start)
    if meshcat is not None:
        from qmt_drake.recording import save_recording
        save_recording(td.visualizer, meshcat, record_path)
    return make_result(scenario, plan, td, summary, wall, time_scale, logged_series(td) if keep_series else {})


def make_result(scenario, plan, td, summary, wall, time_scale, series) -> TransferResult:
    s = TransferMonitor.unpack(summary)
    detached = None if math.isnan(s["detached_at_s"]) else s["detached_at_s"]
    peak = s["peak_motor_torque_Nm"]
    moment = planned_peak_moment_Nm(scenario, plan, time_scale)
    return TransferResult(
        scenario=scenario.name, method=str(getattr(plan, "method", "")), time_scale=float(time_scale),
        held=bool(detached is None and s["max_slip_m"] < HELD_SLIP_LIMIT_M),
        max_slip_m=s["max_slip_m"], max_tilt_rad=s["max_tilt_rad"], max_gap_m=s["max_gap_m"],
        detached_at_s=detached, max_tracking_error_rad=s["max_tracking_error_rad"], peak_motor_torque_Nm=peak,
        peak_motor_torque_ratio=float(np.max(peak / scenario.limits.motor_torque_limit_Nm)),
        peak_moment_ratio_planned=moment / scenario.limits.moment_limit_Nm, peak_moment_planned_Nm=moment,
        peak_motor_torque_planned_Nm=planned_peak_motor_torque_Nm(scenario, plan, time_scale),
        energy_J=s["energy_J"], coil_current_A=td.coil_current_A, time_step_s=td.time_step_s,
        implicit_loop_damping=td.implicit_loop_damping,
        sim_time_s=td.t_final_s, sim_wall_s=wall, real_time_factor=td.t_final_s / wall, series=series)


FEEDFORWARD_OPTIONS = {  # CLI --feedforward -> build_transfer_diagram keywords
    "none": {},
    "back-emf": {"back_emf_feedforward": True},
    "full": {"back_emf_feedforward": True, "inverse_dynamics_feedforward": True},
}


def run_simulate(scenario, plan, time_scale: float = 1.0, record_path=None, time_step_s: float | None = None,
                 implicit_loop_damping: bool | None = None, feedforward: str = "none") -> dict:
    """CLI entry point: simulate and return a JSON-ready dict (see TransferResult.summary_dict).
    feedforward: a FEEDFORWARD_OPTIONS key (the controller's feedforward terms)."""
    if feedforward not in FEEDFORWARD_OPTIONS:
        raise QmtInputError(f"feedforward must be one of {sorted(FEEDFORWARD_OPTIONS)}, got {feedforward!r}")
    res = simulate_transfer(scenario, plan, time_scale=time_scale, record_path=record_path, keep_series=False,
                            time_step_s=time_step_s, implicit_loop_damping=implicit_loop_damping,
                            **FEEDFORWARD_OPTIONS[feedforward])
    d = res.summary_dict()
    d["feedforward"] = feedforward
    if record_path is not None:
        d["record_path"] = str(record_path)
    return d


# ------------------------------------------------------------------------------------ gene plans
class GenesPlan:
    """A minimal plan (the Plan contract: motion_time_s, n_dof, sample(t), method, scenario) made
    straight from a scenario's trajectory family and one gene vector; held at the goal after T0."""

    def __init__(self, scenario, genes, method: str = "genes"):
        from qmt_drake.families import make_family
        self.family = make_family(scenario)
        self.genes = np.asarray(genes, float)
        self.method = method
        self.scenario = scenario.name
        self.motion_time_s = float(self.family.motion_time_s(self.genes[None])[0])
        self.n_dof = self.family.n_dof

    def sample(self, t):
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.motion_time_s)
        return self.family.sample(self.genes, t)
