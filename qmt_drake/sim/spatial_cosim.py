"""Co-simulation of a spatial scenario's plan: the arm in a discrete Drake MultibodyPlant (1 ms), the
part a free body held by a suction cup or a magnet, ideal joint torque actuators saturated at the joint torque
limits, Drake's InverseDynamicsController (PID on acceleration + inverse-dynamics feedforward of the
arm with the part welded to the hand) tracking the plan sampled at 1 kHz.

Suction model: a weld that breaks. The part is a free body welded to the hand frame H (the cup's
centre) by a SAP weld constraint (Drake's discrete solver, implicit, hence stable at 1 ms for a light
wrist). Every 1 ms step's state is logged in C++ and the wrench the cup applies to the part (Newton-Euler
on the part's own motion) is checked after each 250 ms chunk (sim/spatial_hold.py) against the cup's contact-stability set
(limits/suction.GripModel with the finer FINE_GRIP rim and pyramid of the re-check: the round cup's
rim and friction cone approximated more closely than by the planners' inscribed 8x4 polyhedron), or
for a magnet hand against the thesis's moment limit (MagnetMomentTerm, the same as the planners'). The
first step with a ratio above 1 is `detached`: the run goes back to the chunk's start, the weld holds
until that step, then the weld constraint is switched off and the part falls freely for the rest of
the run (the states of a per-step monitor's run, tests/test_cosim_floor.py). A slip along the face without
detaching is not modelled (the weld does not slide), so the outcomes are carried / detached /
unfinished (sim/outcome.transfer_outcome, arrival tolerance ARRIVAL_TOLERANCE_DC_MOTOR_RAD at the end
of a TAIL_S hold at the goal). actuator="dc_motor" drives the arm through DC motors with gears and a PD
voltage law with feedforward instead (sim/spatial_actuation.py); both report the tracking error.

One assembly (`assemble`) for every spatial hand: the arm's plant, a hand part (WeldHand here, the tray's
TrayCupHand in sim/spatial_tray_hand.py, the contact hand's ContactHand in sim/spatial_contact_hand.py:
each adds its bodies, geometry and wiring to the builder and classifies the run from its logs) and a drive
part (add_ideal_controller, or spatial_actuation.SpatialMotorDrive.add_to), composed by build_spatial_cosim
into a CoSim that sim/cosim_run.run runs. time_step_s (default TIME_STEP_S, at most MAX_TIME_STEP_S) is the
plant step, the reference's sampling and the hold check's.
Example-robot-data's Panda declares no actuators: the tray co-simulation adds one per chain joint.
Every run starts in the simulated (possibly drawn) plant's static equilibrium at the plan's first pose, as a
real arm that has settled holding the part (sim/spatial_start: the drive's integral or a PD law's settled
pose, the weld hand's part seated loaded); settled_start=False keeps the old start at rest with zero state.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
from pydrake.geometry import Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.plant import CoulombFriction, DiscreteContactApproximation
from pydrake.multibody.tree import RotationalInertia, SpatialInertia
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Saturation, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.suction import GripModel, cached_grip
from qmt_drake.model.actuator_order import connect_joint_torques
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD, transfer_outcome
from qmt_drake.sim.cosim_run import CoSim, run
from qmt_drake.sim.sim_settings import APPROXIMATION_ENUMS, apply_contact_settings, simulation_of
from qmt_drake.sim.spatial_actuation import (
    SpatialMotorDrive,
    add_tracking_logs,
    spatial_drive,
    tracking_report,
)
from qmt_drake.sim.spatial_contact_hand import ContactHand
from qmt_drake.sim.spatial_hold import (  # noqa: F401 (re-exported)
    COLLISION_CHECK_EVERY,
    HandPart,
    HoldLog,
    TrayLog,
    collision_check,
    run_until_detached,
)
from qmt_drake.sim.spatial_recording import SpatialRecording, add_part_box
from qmt_drake.sim.spatial_reference import closed_loop_reference
from qmt_drake.sim.spatial_start import settle
from qmt_drake.sim.spatial_tray_hand import (  # noqa: F401 (re-exported)
    SETTLE_S,
    SLIP_TOLERANCE_M,
    TRAY_LOG_PERIOD_S,
    CupSpec,
    TrayCupHand,
    add_tray_and_cup,
    add_tray_hand,
    classify_tray_run,
)
from qmt_drake.trajectory import JointTrajectory

TIME_STEP_S = 1e-3  # the plant step by default [s]
MAX_TIME_STEP_S = 5e-3  # the largest plant step a user may choose [s]
KP_1_S2, KD_1_S, KI_1_S3 = 900.0, 60.0, 0.0  # acceleration-level PID of the inverse-dynamics controller
TAIL_S = 0.5
FINE_GRIP = (24, 8)
def _reference(traj, time_step_s: float = TIME_STEP_S):
    """The plan sampled at the plant step and held TAIL_S at its end: (pp, acc, t_end, q_goal)."""
    t = np.arange(0.0, traj.duration_s + TAIL_S + 1e-12, time_step_s)
    q, qd, qdd = traj.sample(np.minimum(t, traj.duration_s))
    after = t > traj.duration_s
    qd[after], qdd[after] = 0.0, 0.0
    return (PiecewisePolynomial.CubicHermite(t, q.T, qd.T), PiecewisePolynomial.FirstOrderHold(t, qdd.T),
            t[-1], q[-1])


def check_spatial_time_step(time_step_s) -> float:
    """The spatial plant step [s]: None is TIME_STEP_S; one line unless 0 < step <= MAX_TIME_STEP_S."""
    if time_step_s is None:
        return TIME_STEP_S
    if not (np.isfinite(time_step_s) and 0.0 < time_step_s <= MAX_TIME_STEP_S):
        raise QmtInputError(f"time step {time_step_s * 1e3:g} ms: the spatial co-simulation takes a plant step in "
                            f"(0, {MAX_TIME_STEP_S * 1e3:g}] ms (default {TIME_STEP_S * 1e3:g} ms)")
    return float(time_step_s)


def spatial_time_step(sc, time_step_s: float | None) -> float:
    """The plant step [s]: the run's time_step_s, else the scenario's simulation.plant.time_step, else
    TIME_STEP_S; checked (check_spatial_time_step), a step from the scenario named so."""
    step = simulation_of(sc).plant.time_step if time_step_s is None else time_step_s
    try:
        return check_spatial_time_step(step)
    except QmtInputError as exc:
        if time_step_s is not None:
            raise
        raise QmtInputError(f"scenario {sc.name}: simulation.plant.time_step: {exc}") from None


def add_ideal_controller(builder, plant, arm, sc, src, src_a) -> None:
    """The ideal drive (a part): Drake's InverseDynamicsController (the carried body welded in its plant) with
    the joint torques saturated at the scenario's limits. None: no motors to log."""
    n = sc.n_dof
    ctrl_plant, _, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, carried=sc.body.as_dict(),
                                      effort_limit_Nm=sc.torque_limit_Nm, velocity_limit_rad_s=sc.velocity_limit_rad_s)
    ctrl = builder.AddSystem(InverseDynamicsController(ctrl_plant, np.full(n, KP_1_S2), np.full(n, KI_1_S3),
                                                       np.full(n, KD_1_S), True))
    sat = builder.AddSystem(Saturation(-sc.torque_limit_Nm, sc.torque_limit_Nm))
    builder.Connect(plant.get_state_output_port(arm), ctrl.get_input_port_estimated_state())
    builder.Connect(src.get_output_port(), ctrl.get_input_port_desired_state())
    builder.Connect(src_a.get_output_port(), ctrl.get_input_port_desired_acceleration())
    builder.Connect(ctrl.get_output_port_control(), sat.get_input_port())
    connect_joint_torques(builder, plant, arm, sc.joint_names, sat.get_output_port())  # by name, not index
    return None


def add_drive(builder, plant, arm, ctrl_sc, drive, reference, time_step_s: float):
    """The reference (TrajectorySources of the plan's state and acceleration) and the drive (a part: the
    ideal controller, or the dc_motor drive) wired to the arm; (src, src_a, motors or None)."""
    pp, acc = reference[:2]
    src = builder.AddSystem(TrajectorySource(pp, output_derivative_order=1))
    src_a = builder.AddSystem(TrajectorySource(acc))
    motors = add_ideal_controller(builder, plant, arm, ctrl_sc, src, src_a) if drive is None else \
        drive.add_to(builder, plant, arm, src.get_output_port(), src_a.get_output_port(), time_step_s, (pp, acc))
    return src, src_a, motors


def spatial_ports(plant, arm, src, extra=None) -> dict:
    """The named ports of a spatial CoSim: desired_state, arm_state, body_poses (and the hand's extra)."""
    return {"desired_state": src.get_output_port(), "arm_state": plant.get_state_output_port(arm),
            "body_poses": plant.get_body_poses_output_port(), **(extra or {})}


def finish_build(builder, plant, arm, q0, ports: dict, export: bool):
    """Export the named ports (export: composed in user code, api.build_diagram), build, and make the
    diagram's default context start at the plan's start (q0) at rest; the diagram."""
    if export:
        for name, port in ports.items():
            builder.ExportOutput(port, name)
    diagram = builder.Build()
    plant.SetDefaultPositions(arm, np.asarray(q0, float))
    return diagram


def simulate_spatial(sc, traj, **options) -> dict:
    """Run the plan `traj` (spatial_trajectory kind) on scenario sc (build_spatial_cosim, the one run);
    dict with the outcome word and the tracking error."""
    return run(build_spatial_cosim(sc, traj, **options))


def build_spatial_cosim(sc, traj, *, grip: GripModel | None = None, actuator: str = "ideal",
                        feedforward: str = "full", record_path=None, contact: dict | None = None, controller_sc=None,
                        drive: SpatialMotorDrive | None = None, time_step_s: float | None = None,
                        export: bool = False, explicit: bool = False,
                        contact_approximation: str | None = None, settled_start: bool = True) -> CoSim:
    """The co-simulation of `traj` on scenario sc as a CoSim, its parts chosen by the hand (the weld, the
    contact hand, the tray) and the actuator. grip: the suction hand's stability set in the co-simulation
    (default: the scenario's cup with the finer FINE_GRIP polyhedron). actuator: 'ideal' (the
    inverse-dynamics controller) or 'dc_motor' (sim/spatial_actuation: PD voltage law, DC motors with gears,
    `feedforward` one of none / back-emf / full). record_path: also write a Meshcat recording there
    (sim/spatial_recording). contact: with hand.physics contact, keyword overrides of
    spatial_contact_hand.build_contact_cosim. controller_sc: the model the controller and its feedforward
    are built from (default sc; a sweep case simulates a drawn sc under the nominal controller); drive: a
    prepared dc_motor drive instead. time_step_s: the plant step [s] (default TIME_STEP_S; the plan is
    sampled and the hold checked at it). export: export the named ports (user composition). explicit: the
    dc_motor law applies its loop damping itself, nothing folded into the plant (SpatialMotorDrive).
    contact_approximation: the plant's discrete contact approximation (a run option over the scenario's
    simulation.plant and the hand's own). settled_start: start in the simulated plant's static equilibrium
    (sim/spatial_start.settle: the drive's integral, or a PD law's settled pose); False: at rest at the plan's
    first pose with the law's zero state."""
    if contact_approximation is not None and contact_approximation not in APPROXIMATION_ENUMS:
        raise QmtInputError(f"contact approximation {contact_approximation!r}: use one of "
                            f"{', '.join(APPROXIMATION_ENUMS)}")
    h = spatial_time_step(sc, time_step_s)
    ctrl = sc if controller_sc is None else controller_sc
    if drive is None:
        drive = spatial_drive(ctrl, traj.sample([0.0])[0][0], actuator, feedforward, explicit)
    elif explicit:
        drive = dataclasses.replace(drive, explicit=True)
    if sc.hand_kind == "suction" and grip is None:  # built once per cup (its hull is 12 % of a run)
        grip = cached_grip(sc.grip.radius_m, sc.grip.pull_force_N, sc.grip.friction, face_normal=sc.grip.basis[2],
                           rim_points=FINE_GRIP[0], pyramid_edges=FINE_GRIP[1])
    if sc.hand_kind == "tray":
        hand = TrayCupHand(sc, TrayLog, TIME_STEP_S)
    elif sc.hand_physics == "contact":  # the part held by contact and a pull, not a weld (sim/spatial_contact_hand)
        kw = {"time_step_s": h, **(contact or {})}
        h = kw.pop("time_step_s")
        hand = ContactHand(sc, grip, **kw)  # (its controller: ctrl, the nominal model when sc is drawn)
    else:
        hand = WeldHand(sc, sc.hand_term(grip), actuator)
    traj = closed_loop_reference(traj, feedforward, drive, h)  # feedforward 'shaped': sim/spatial_reference
    return assemble(sc, traj, hand, drive, ctrl, record_path, h, export, contact_approximation, settled_start)


def assemble(sc, traj, hand, drive, ctrl, record_path, h: float, export: bool,
             contact_approximation: str | None = None, equilibrium: bool = True) -> CoSim:
    """The spatial co-simulation's one assembly: the arm's URDF plant (1 ms discrete by default), the hand
    part (its plant settings, bodies and geometry before Finalize, its wiring after), the drive part and
    the reference, the tracking logs and the hand's monitor; the run's start (equilibrium: in the plant's static
    equilibrium, sim/spatial_start; its result in handles.start), advance and finish."""
    builder = DiagramBuilder()
    plant, H, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, time_step_s=h,
                                 effort_limit_Nm=sc.torque_limit_Nm, velocity_limit_rad_s=sc.velocity_limit_rad_s,
                                 finalize=False)
    # SAP (weld constraints, the tray's contact)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap if hand.approximation == "sap"
                                             else hand.approximation)
    hand.configure(plant)
    apply_contact_settings(plant, simulation_of(sc).plant)  # the scenario's simulation.plant over the hand's
    if contact_approximation is not None:  # the run's option over both
        plant.set_discrete_contact_approximation(APPROXIMATION_ENUMS[contact_approximation])
    builder.AddSystem(plant)
    arm = H.model_instance()
    hand.add(builder, plant, H)
    if drive is not None:
        drive.prepare_plant(plant, arm, sc)
    rec = None if record_path is None else hand.recording(builder, plant, arm)
    plant.Finalize()
    hand.connect(builder, plant, H, rec, continuous=drive is None)
    reference = _reference(_Delayed(traj, hand.settle_s) if hand.settle_s else traj, h)
    t_end, q_goal = reference[2:]
    src, src_a, motors = add_drive(builder, plant, arm, ctrl, drive, reference, h)
    logs = add_tracking_logs(builder, plant.get_state_output_port(arm), src.get_output_port(), h, motors)
    hand.add_monitor(builder, plant, arm, h)
    q0 = traj.sample([0.0])[0][0]
    ports = spatial_ports(plant, arm, src, hand.ports(plant))
    diagram = finish_build(builder, plant, arm, q0, ports, export)
    hand.set_default(plant, H)

    def start(sim) -> None:
        root = sim.get_mutable_context()
        pctx = plant.GetMyMutableContextFromRoot(root)
        plant.SetPositions(pctx, arm, q0)
        hand.start(plant, pctx, H)
        if equilibrium:  # the drive's state holding the drawn plant still (sim/spatial_start)
            law = diagram.GetSubsystemByName("controller") if diagram.HasSubsystemNamed("controller") else None
            ahead = (diagram.GetSubsystemByName("hold_compensated_reference")
                     if diagram.HasSubsystemNamed("hold_compensated_reference") else None)
            handles.start = settle(root, plant, arm, H, src, src_a, reference, q0, lambda c: hand.start(plant, c, H),
                                   law, None if drive is None else drive.gains.ki_V_per_rad_s, hand.welded_part(),
                                   ahead)
        if rec is not None:
            rec.start(plant, pctx, sc.path_points_m)

    def finish(sim, wall) -> dict:
        if rec is not None:
            rec.save(record_path)
        ctx = sim.get_context()
        err = float(np.abs(q_goal - plant.GetPositions(plant.GetMyContextFromRoot(ctx), arm)).max())
        return hand.finish(ctx, plant, H, err, logs, drive, traj, t_end)

    handles = SimpleNamespace(t_final_s=t_end, q_goal=q_goal, arm_instance=arm, hand=hand, start=None)
    return CoSim(hand.kind, diagram, plant, start, lambda sim: hand.advance(sim, diagram, t_end), finish, dict,
                 ports=ports, loggers={**logs, **hand.loggers}, monitor=hand.monitor, handles=handles,
                 simulator_settings=simulation_of(sc).simulator)


def add_weld_hand(plant, H, sc):
    """The breakable weld (a part, before Finalize): the part a free body with the scenario's payload
    inertia, welded to the hand frame H by a SAP weld constraint; (part body, weld constraint id)."""
    b = sc.body
    M = SpatialInertia.MakeFromCentralInertia(b.mass_kg, np.asarray(b.com_m, float),
                                              RotationalInertia(*np.diag(b.inertia_kgm2)))
    part = plant.AddRigidBody("part", plant.AddModelInstance("part"), M)
    return part, plant.AddWeldConstraint(H.body(), H.GetFixedPoseInBodyFrame(), part, RigidTransform())


class WeldHand(HandPart):
    """The weld hand part (module docstring): the hold checked on C++ logs (HoldLog) after each chunk, the
    weld released at the first step the hand term's ratio passes 1 (run_until_detached)."""

    kind, settle_s, loggers, approximation = "spatial_weld", 0.0, {}, "sap"

    def __init__(self, sc, term, actuator: str) -> None:
        self.sc, self.term, self.actuator, self.out = sc, term, actuator, {}

    def configure(self, plant) -> None:  # SAP (assemble): its weld constraints
        pass

    def add(self, builder, plant, H) -> None:
        self.plant = plant
        self.part, self.weld_id = add_weld_hand(plant, H, self.sc)

    def recording(self, builder, plant, arm):
        rec = SpatialRecording.for_scenario(builder, plant, arm, self.sc)
        size, com = 4.0 * rec.link_radius_m, np.asarray(self.sc.body.com_m, float)
        add_part_box(plant, self.part, com, size)
        # only the part and the floor collide: a detached part lands instead of falling for ever
        plant.RegisterCollisionGeometry(self.part, RigidTransform(com), Sphere(size / 2), "part_collision",
                                        CoulombFriction(0.5, 0.5))
        return rec

    def connect(self, builder, plant, H, rec, continuous: bool) -> None:
        if rec is not None:
            rec.connect(builder, plant)

    def add_monitor(self, builder, plant, arm, h: float) -> None:
        self.monitor = HoldLog(builder, plant, self.part, self.term, h)

    def ports(self, plant) -> dict:
        return {"part_state": plant.get_state_output_port(self.part.model_instance())}

    def welded_part(self):  # its weld carries the part's weight from the start (sim/spatial_start)
        return self.part

    def set_default(self, plant, H) -> None:  # the part seated in the cup at the plan's start
        plant.SetDefaultFloatingBaseBodyPose(self.part, H.CalcPoseInWorld(plant.CreateDefaultContext()))

    def start(self, plant, pctx, H) -> None:
        plant.SetFreeBodyPose(pctx, self.part, H.CalcPoseInWorld(pctx))

    def advance(self, sim, diagram, t_end: float) -> None:
        plant = self.plant

        def release(root_context):  # the cup lets go: the part flies free for the rest of the run
            plant.SetConstraintActiveStatus(plant.GetMyMutableContextFromRoot(root_context), self.weld_id, False)

        self.out = dict(zip(("detached", "lost_at_s", "largest"),
                            run_until_detached(sim, diagram, self.monitor, t_end, release)))

    def finish(self, ctx, plant, H, err, logs, drive, traj, t_end) -> dict:
        pctx = plant.GetMyContextFromRoot(ctx)
        detached, lost_at_s = self.out["detached"], self.out["lost_at_s"]
        lost = "detached" if detached else None
        outcome = transfer_outcome(lost, False, err, ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
        outcome, hit = collision_check(self.sc, logs, ctx, outcome, lost_at_s if lost else None)
        gap = float(np.linalg.norm(plant.GetFreeBodyPose(pctx, self.part).translation()
                                   - H.CalcPoseInWorld(pctx).translation()))
        return {"outcome": outcome, "held": outcome == "carried", "lost_at_s": lost_at_s,
                "max_grip_ratio_while_held": self.out["largest"], "final_goal_error_rad": err,
                "duration_s": traj.duration_s, "part_distance_from_cup_at_end_m": gap, "actuator": self.actuator,
                **tracking_report(logs, ctx, traj.duration_s, self.sc, drive), **hit}


class _Delayed(JointTrajectory):
    """traj (a JointTrajectory that holds its end value, a spatial kind) after `settle_s` of rest at its start."""

    holds_end_value = True

    def __init__(self, traj, settle_s: float) -> None:
        self.inner, self.settle_s = traj, settle_s
        self.duration_s = traj.duration_s + settle_s

    n_dof = property(lambda self: self.inner.n_dof)
    breakpoints_s = property(lambda self: np.unique(np.r_[0.0, self.settle_s + self.inner.breakpoints_s]))

    def sample(self, t):
        t = np.atleast_1d(np.asarray(t, float)) - self.settle_s
        q, qd, qdd = self.inner.sample(np.maximum(t, 0.0))
        qd[t < 0], qdd[t < 0] = 0.0, 0.0
        return q, qd, qdd


def simulate_tray_hand(sc, traj, **options) -> dict:
    """simulate_spatial for a tray hand (build_spatial_cosim, the one run)."""
    return run(build_spatial_cosim(sc, traj, **options))
