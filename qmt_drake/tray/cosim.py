"""Co-simulation of seed 002's tray transfer.

    goal stream (GoalSchedule, zero-order hold) --goal_position--> DynamixelPositionServo (firmware PID,
        sampled) --voltage_command--> DcMotorWithGear (datasheet XM540-W270 / XM430-W350)
        --joint_torque--> MultibodyPlant(CRANE-X7 planar arm + tray, bottle on its 6-DOF joint to the tray; discrete, SAP lagged,
        point contact) --> loggers of the bottle's joint state and contact forces (logged_series: slide,
        tilt, lift-off, contact force)

The motors drive the plant explicitly (their back-EMF damping b = eta Ke^2 / R, 3.4 / 0.85 N m s/rad,
over the joints' inertia incl. the reflected rotor gives b h / J < 0.05 at h = 1 ms: stable).
The arm starts at rest at the schedule's first goal, the bottle seated on the tray; the settle
phase lets the position loops take up gravity before the move.

`simulate_tray` returns a `TrayResult`; `TrayResult.outcome` classifies the run:
    "on_tray"    on the tray, upright and in contact at the end (whether it slid is `slipped`;
                 the transfer's outcome in the common vocabulary is qmt_drake/outcome.py's)
    "slid_off"   its base centre left the tray surface
    "tipped"     tilt beyond the angle at which its centre of mass passes the ring's edge
    "lifted"     (reported separately as lifted_s: time with zero normal force)
`slip_m` / `creep_m` split the bottle's path on the tray by its sliding speed (SLIP_SPEED_M_S):
real slip vs the solver's creep; `slipped` = slip_m > SLIP_THRESHOLD_M.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2 as GRAVITY_M_S2
from qmt_drake.config.simulation import NO_SIMULATION, Simulation
from qmt_drake.errors import QmtInputError
from qmt_drake.model.actuator_order import connect_joint_torques
from qmt_drake.model.arm import add_urdf
from qmt_drake.recording import add_meshcat_visualizer, make_headless_meshcat, save_recording, start_recording
from qmt_drake.sim.cosim_run import CoSim, run
from qmt_drake.sim.sim_settings import plant_config
from qmt_drake.systems.dc_motor import DcMotorWithGear, dc_motors_as_primitives
from qmt_drake.systems.dynamixel_servo import (
    CONTROL_PERIOD_S,
    CRANE_X7_PLANAR_SERVOS,
    PULSES_PER_RAD,
    PWM_FULL_SCALE,
    DynamixelPositionServo,
    ServoGains,
    motor_params,
)
from qmt_drake.systems.payload import allow_contact, six_dof_joint_of
from qmt_drake.systems.scalar_ops import NUMPY
from qmt_drake.systems.servo_law import CompiledServo
from qmt_drake.systems.transfer_monitor import motion_from_joint
from qmt_drake.systems.tray_object import (
    TRAY_SIZE_M,
    BottleSpec,
    TrayBottleMonitor,
    add_bottle,
    add_tray_contact,
    seated_pose_on_tray,
)
from qmt_drake.tray.crane_ik import URDF_PATH
from qmt_drake.tray.verdict import (  # noqa: F401 (the verdict's names, re-exported where callers find them)
    SEATING_S,
    SLIP_SPEED_M_S,
    SLIP_THRESHOLD_M,
    classify,
    required_friction,
    split_slip_creep,
    tipping_angle_rad,
    tray_margin,
)
from qmt_drake.tray.waypoints import GoalSchedule

JOINTS = ("shoulder_pitch", "elbow", "wrist_pitch")
TIME_STEP_S = 1e-3
LIFT_FORCE_N = 1e-6
# Recordings look at the arm's vertical plane (x-z) from the side, at the tray line's height.
RECORDING_CAMERA_M = ((0.25, -0.9, 0.55), (0.25, 0.0, 0.4))  # (camera, target) in world [m]


@dataclass
class TrayDiagram:
    diagram: object
    plant: object
    scene_graph: object
    arm: object
    tray_body: object
    bottle_body: object
    servo: DynamixelPositionServo | CompiledServo
    loggers: dict
    schedule: GoalSchedule
    bottle: BottleSpec
    X_TB0: object
    visualizer: object = None
    motor: object = None
    time_step_s: float = TIME_STEP_S
    servo_period_s: float = CONTROL_PERIOD_S
    simulator_settings: object = None  # the scenario's simulation.simulator (sim/cosim_run.run applies it)


def _goal_trajectory(schedule: GoalSchedule) -> PiecewisePolynomial:
    t = np.append(schedule.times, max(schedule.t_end_s, schedule.times[-1]) + 1.0)
    g = np.vstack([schedule.goals, schedule.goals[-1:]])
    return PiecewisePolynomial.ZeroOrderHold(t, g.T)


def build_tray_diagram(schedule: GoalSchedule, gains: ServoGains, bottle: BottleSpec | None = None, *,
                       time_step_s: float = TIME_STEP_S, servo_period_s: float = CONTROL_PERIOD_S,
                       bottle_offset_xy=(0.0, 0.0), log_period_s: float = 5e-3, meshcat=None,
                       motor=None, compiled_servo: bool = True, python_monitor: bool = False,
                       step_log: bool = False, contact_approximation: str | None = None,
                       simulation: Simulation = NO_SIMULATION) -> TrayDiagram:
    """The closed loop of the module docstring. Raises QmtInputError (one line) on bad steps.
    motor: DcMotorParams of the three servos' motors (default motor_params(CRANE_X7_PLANAR_SERVOS),
    the lossless equivalent). compiled_servo: the servo law as Drake primitives (systems/servo_law.py,
    the default) or the Python DynamixelPositionServo (the same law, one Python call per period).
    Loggers (every log_period_s; 0: none): the goal, the arm's state, the servos' voltage, the motors'
    current and torque, the bottle's joint state and its generalized contact forces, all plant or
    primitive ports, so the default diagram holds no Python system and is freed after the run (a
    pydrake diagram holding one never is). python_monitor: also log the Python TrayBottleMonitor's
    outputs as monitor_* (the same quantities from poses and contact results: a cross-check).
    step_log: also log the arm's state and the plant's generalized acceleration of the arm (its
    discrete step's (v_next - v) / h) at every plant step, as arm_state_step / arm_accel_step (the
    executed motion that tray/executed.py evaluates the limits on). contact_approximation: the plant's
    MultibodyPlantConfig.discrete_contact_approximation (tamsi, sap, similar, lagged; None: the scenario's
    simulation.plant one, else lagged). simulation: the scenario's `simulation` section (config/simulation.py):
    its plant fields over this plant's config (time_step_s and contact_approximation, resolved by the caller,
    over them), its simulator fields on the run's Simulator."""
    if not time_step_s > 0 or not servo_period_s > 0:
        raise QmtInputError(f"time step {time_step_s} s and servo period {servo_period_s} s must be positive")
    bottle = bottle or BottleSpec.pet_500ml()
    bottle.check_rests(float(np.sum(schedule.q_start)))  # the tray's tilt at the start (0 = level)
    builder = DiagramBuilder()
    cfg = plant_config(MultibodyPlantConfig(time_step=time_step_s, discrete_contact_approximation="lagged",
                                            contact_model="point", use_sampled_output_ports=False),
                       simulation.plant, time_step=time_step_s, discrete_contact_approximation=contact_approximation)
    plant, scene_graph = AddMultibodyPlant(cfg, builder)
    arm = add_urdf(plant, URDF_PATH)
    tray = plant.GetBodyByName("tray", arm)
    add_tray_contact(plant, tray, bottle)
    bottle_body = add_bottle(plant, bottle, tray_body=tray)
    plant.Finalize()
    allow_contact(plant, scene_graph, tray, bottle_body)
    n = 3
    X_TB0 = seated_pose_on_tray(bottle_offset_xy)
    bottle_joint(plant, bottle_body).SetDefaultPose(X_TB0)

    goal = builder.AddNamedSystem("goal_stream", TrajectorySource(_goal_trajectory(schedule)))
    if compiled_servo:
        servo_law = CompiledServo(CRANE_X7_PLANAR_SERVOS, gains, control_period_s=servo_period_s)
        servo = builder.AddSystem(servo_law.system)
    else:
        servo = servo_law = builder.AddNamedSystem("servos", DynamixelPositionServo(
            CRANE_X7_PLANAR_SERVOS, gains, control_period_s=servo_period_s))
    motor = motor or motor_params(CRANE_X7_PLANAR_SERVOS)
    # the motors' one formula compiled (dc_motor.dc_motors_as_primitives), as the servo law: no Python
    # system runs per step in the default tray diagram (the monitor is read at the log period only)
    motors = builder.AddSystem(dc_motors_as_primitives(motor) if compiled_servo else DcMotorWithGear(motor))
    split = builder.AddNamedSystem("arm_state_split", Demultiplexer([n, n]))
    monitor = builder.AddNamedSystem("monitor", TrayBottleMonitor(plant, tray, bottle_body, X_TB0)) if python_monitor else None
    arm_state = plant.get_state_output_port(arm)
    builder.Connect(arm_state, split.get_input_port())
    builder.Connect(goal.get_output_port(), servo.GetInputPort("goal_position"))
    builder.Connect(split.get_output_port(0), servo.GetInputPort("joint_position"))
    builder.Connect(servo.GetOutputPort("voltage_command"), motors.GetInputPort("voltage_command"))
    builder.Connect(split.get_output_port(1), motors.GetInputPort("joint_velocity"))
    connect_joint_torques(builder, plant, arm, JOINTS, motors.GetOutputPort("joint_torque"))  # by name, not index
    if monitor is not None:
        builder.Connect(plant.get_body_poses_output_port(), monitor.GetInputPort("body_poses"))
        builder.Connect(plant.get_contact_results_output_port(), monitor.GetInputPort("contact_results"))
    loggers = {}
    if log_period_s:
        instance = bottle_body.model_instance()
        ports = {"goal": goal.get_output_port(), "arm_state": arm_state,
                 "voltage": servo.GetOutputPort("voltage_command"), "current": motors.GetOutputPort("current"),
                 "joint_torque": motors.GetOutputPort("joint_torque"),
                 "bottle_state": plant.get_state_output_port(instance),
                 "bottle_contact": plant.get_generalized_contact_forces_output_port(instance)}
        if monitor is not None:
            ports.update({f"monitor_{k}": monitor.GetOutputPort(k)
                          for k in ("slide", "tilt", "base_height", "contact_force")})
        loggers = {k: LogVectorOutput(p, builder, log_period_s) for k, p in ports.items()}
    if step_log:
        loggers["arm_state_step"] = LogVectorOutput(arm_state, builder, time_step_s)
        loggers["arm_accel_step"] = LogVectorOutput(plant.get_generalized_acceleration_output_port(arm), builder,
                                                    time_step_s)
    visualizer = None
    if meshcat is not None:
        visualizer = add_meshcat_visualizer(builder, scene_graph, meshcat)
    diagram = builder.Build()
    return TrayDiagram(diagram, plant, scene_graph, arm, tray, bottle_body, servo_law, loggers, schedule, bottle, X_TB0,
                       visualizer, motor, time_step_s, servo_period_s, simulation.simulator)


@dataclass
class TrayResult:
    """One co-simulated tray run. Times are simulation time from the start of the settle phase.
    max_slide_m: largest in-plane displacement of the bottle's base from its seat (tray frame);
    slipped: max_slide_m > SLIP_THRESHOLD_M; lifted_s: time with zero tray normal force;
    real_time_factor = sim_time_s / sim_wall_s. series: 5 ms samples (see build_tray_diagram)."""

    label: str
    outcome: str
    lost_at_s: float | None
    max_slide_m: float
    slip_m: float  # distance slid faster than SLIP_SPEED_M_S (until lost)
    creep_m: float  # distance slid slower than that (until lost)
    slipped: bool
    max_tilt_rad: float
    lifted_s: float
    min_normal_force_N: float
    max_tracking_error_rad: np.ndarray
    sim_time_s: float
    sim_wall_s: float
    real_time_factor: float
    time_step_s: float
    servo_period_s: float
    friction: float
    com_height_m: float
    phases: dict
    final_q_rad: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))  # arm joints at the end
    series: dict = field(default_factory=dict, repr=False)
    # the thresholds of the lost outcomes, for the verdict's margin (qmt_drake/margin.py): the tilt at
    # which it tips [rad], and the base's largest offset over the tray's half size, per axis (> 1: off)
    tipping_angle_rad: float = math.nan
    max_edge_ratio: float = math.nan

    def summary_dict(self) -> dict:
        d = {k: getattr(self, k) for k in ("label", "outcome", "lost_at_s", "max_slide_m", "slip_m", "creep_m",
                                           "slipped", "max_tilt_rad",
                                           "lifted_s", "min_normal_force_N", "sim_time_s", "sim_wall_s",
                                           "real_time_factor", "time_step_s", "servo_period_s", "friction",
                                           "com_height_m", "phases", "tipping_angle_rad", "max_edge_ratio")}
        d["max_tracking_error_rad"] = [float(x) for x in self.max_tracking_error_rad]
        return {k: (float(v) if isinstance(v, np.floating) else (bool(v) if isinstance(v, np.bool_) else v))
                for k, v in d.items()}


def holding_torque_Nm(plant, ctx, arm, tray_body, bottle_body, bottle: BottleSpec, X_TB0) -> np.ndarray:
    """Joint torques [N m] that hold the arm and the seated bottle still at the context's q."""
    idx = [plant.GetJointByName(j, arm).velocity_start() for j in JOINTS]
    tau = -plant.CalcGravityGeneralizedForces(ctx)[idx]
    p_TG = X_TB0.multiply(np.array([0.0, 0.0, bottle.com_height_m]))
    J = plant.CalcJacobianTranslationalVelocity(ctx, JacobianWrtVariable.kV, tray_body.body_frame(), p_TG,
                                                plant.world_frame(), plant.world_frame())
    J = J[:, idx]
    return tau + J.T @ np.array([0.0, 0.0, bottle.mass_kg * GRAVITY_M_S2])


def bottle_joint(plant, bottle_body):
    """The bottle's 6-DOF joint to the tray (add_bottle with tray_body)."""
    return six_dof_joint_of(plant, bottle_body)


def set_initial_state(td: TrayDiagram, root_context) -> None:
    """Arm and servos in static equilibrium at the first goal (P-only: the sag that balances
    gravity; with I: the integral carries the load, no error), bottle seated, all at rest: the
    run starts without the jolt of a loop taking up its load."""
    plant = td.plant
    ctx = plant.GetMyMutableContextFromRoot(root_context)
    goal = td.schedule.q_start
    mp = td.motor
    nm_per_pwm = mp.joint_torque_per_volt_stall() * mp.voltage_limit_V / PWM_FULL_SCALE
    kpp, kpi, _ = td.servo.gains.firmware()
    q = goal.copy()
    for _ in range(4):  # gravity depends on the sag: a few fixed-point passes
        plant.SetPositions(ctx, td.arm, q)
        pwm = holding_torque_Nm(plant, ctx, td.arm, td.tray_body, td.bottle_body, td.bottle, td.X_TB0) / nm_per_pwm
        e = np.where(kpi > 0, 0.0, pwm / kpp)  # pulses
        q = goal - e / PULSES_PER_RAD
    plant.SetPositions(ctx, td.arm, q)
    plant.SetVelocities(ctx, td.arm, np.zeros(3))
    joint = bottle_joint(plant, td.bottle_body)
    joint.SetPose(ctx, td.X_TB0)
    joint.set_angular_velocity(ctx, np.zeros(3))
    joint.set_translational_velocity(ctx, np.zeros(3))
    integral = np.where(kpi > 0, pwm / np.where(kpi > 0, kpi, 1.0), 0.0)
    td.servo.set_state(root_context, td.servo.state_at_rest(integral, np.round(e), pwm, goal))


def logged_series(td: TrayDiagram, root_context) -> dict:
    """The loggers' samples {'t': (K,), port name: (width, K)} plus the bottle's motion on the tray
    derived from its joint (coordinates = its pose in the tray frame T, velocities and forces in T's
    axes): slide (2, K) [m] of the base centre from its seat, tilt (1, K) [rad] of its axis from
    T's z (transfer_monitor.motion_from_joint), base_height (1, K) [m] above the surface, and
    contact_force (3, K) [N] on the bottle in T's axes (the translational generalized contact
    forces of its joint)."""
    series = {}
    for k, lg in td.loggers.items():
        log = lg.FindLog(root_context)
        series["t_step" if k.endswith("_step") else "t"] = log.sample_times()  # step_log: every plant step
        series[k] = log.data()
    q = series["bottle_state"][:7]
    series["slide"] = q[4:6] - np.asarray(td.X_TB0.translation())[:2, None]
    series["tilt"] = motion_from_joint(tuple(q), ops=NUMPY)[1][None, :]
    series["base_height"] = q[6:7].copy()
    series["contact_force"] = series["bottle_contact"][3:6].copy()
    return series


def tray_cosim(td: TrayDiagram, *, recording=None, keep_series: bool = True, summarize=None) -> CoSim:
    """`td` as a CoSim for cosim_run.run: arm and servos in equilibrium at the first goal, the bottle
    seated (set_initial_state), run over the schedule; its result a TrayResult (summarised by its
    summary_dict, or `summarize`). recording: (meshcat, path) of a Meshcat HTML replay."""
    schedule = td.schedule

    def start(sim) -> None:
        set_initial_state(td, sim.get_mutable_context())
        sim.Initialize()
        if td.visualizer is not None:
            start_recording(td.visualizer)

    def finish(sim, wall) -> TrayResult:
        if td.visualizer is not None and recording is not None:
            save_recording(td.visualizer, *recording)
        return tray_result(td, sim.get_context(), wall, keep_series)

    return CoSim("tray", td.diagram, td.plant, start, lambda sim: sim.AdvanceTo(schedule.t_end_s), finish,
                 summarize or (lambda r: r.summary_dict()), loggers=td.loggers, handles=td,
                 simulator_settings=td.simulator_settings,
                 ports={"arm_state": td.plant.get_state_output_port(td.arm),
                        "bottle_state": td.plant.get_state_output_port(td.bottle_body.model_instance())})


def tray_result(td: TrayDiagram, root_context, wall: float, keep_series: bool) -> TrayResult:
    """The TrayResult of the run simulated in root_context (classify, slip vs creep, tracking)."""
    schedule, bottle = td.schedule, td.bottle
    series = logged_series(td, root_context)
    outcome, lost_at = classify(series, bottle)
    after = series["t"] >= SEATING_S
    slide_norm = np.hypot(series["slide"][0], series["slide"][1])[after]
    fn = series["contact_force"][2][after]
    dt = np.diff(series["t"], prepend=series["t"][0])[after]
    q = series["arm_state"][:3]
    err = np.max(np.abs(series["goal"] - q), axis=1)
    slip, creep = split_slip_creep(series, lost_at)
    edge = float(np.max(np.abs(series["slide"]).T / (np.array(TRAY_SIZE_M[:2]) / 2)))  # classify's slid_off rule
    return TrayResult(schedule.label, outcome, lost_at, float(np.max(slide_norm)), slip, creep,
                      bool(slip > SLIP_THRESHOLD_M), float(np.max(series["tilt"][0][after])),
                      float(np.sum(dt[fn <= LIFT_FORCE_N])), float(np.min(fn)), err, float(schedule.t_end_s), wall,
                      float(schedule.t_end_s / wall), td.time_step_s, td.servo_period_s, bottle.friction,
                      bottle.com_height_m, dict(schedule.phases), q[:, -1].copy(), series if keep_series else {},
                      tipping_angle_rad(bottle), edge)


def build_tray_cosim(schedule: GoalSchedule, gains: ServoGains, bottle: BottleSpec | None = None, *,
                     time_step_s: float = TIME_STEP_S, servo_period_s: float = CONTROL_PERIOD_S,
                     keep_series: bool = True, recording_path=None, bottle_offset_xy=(0.0, 0.0), motor=None,
                     step_log: bool = False, contact_approximation: str | None = None, summarize=None,
                     simulation: Simulation = NO_SIMULATION) -> CoSim:
    """The tray co-simulation over the schedule as a CoSim (build_tray_diagram, tray_cosim); with
    recording_path, a Meshcat HTML replay is written there."""
    bottle = bottle or BottleSpec.pet_500ml()
    meshcat = None
    if recording_path is not None:
        meshcat = make_headless_meshcat(*RECORDING_CAMERA_M)
    td = build_tray_diagram(schedule, gains, bottle, time_step_s=time_step_s, servo_period_s=servo_period_s,
                            meshcat=meshcat, bottle_offset_xy=bottle_offset_xy, motor=motor, step_log=step_log,
                            contact_approximation=contact_approximation, simulation=simulation)
    return tray_cosim(td, recording=None if meshcat is None else (meshcat, recording_path), keep_series=keep_series,
                      summarize=summarize)


def simulate_tray(schedule: GoalSchedule, gains: ServoGains, bottle: BottleSpec | None = None, *,
                  time_step_s: float = TIME_STEP_S, servo_period_s: float = CONTROL_PERIOD_S,
                  keep_series: bool = True, recording_path=None, bottle_offset_xy=(0.0, 0.0), motor=None,
                  step_log: bool = False, contact_approximation: str | None = None) -> TrayResult:
    """Run the diagram over the schedule (build_tray_cosim, the one run); with recording_path, write a
    Meshcat HTML replay there. step_log: the series also hold the arm's state and acceleration at every
    plant step (build_tray_diagram). contact_approximation: the plant's discrete contact approximation."""
    cosim = build_tray_cosim(schedule, gains, bottle, time_step_s=time_step_s, servo_period_s=servo_period_s,
                             keep_series=keep_series, recording_path=recording_path,
                             bottle_offset_xy=bottle_offset_xy, motor=motor, step_log=step_log,
                             contact_approximation=contact_approximation)
    run(cosim)
    return cosim.result
