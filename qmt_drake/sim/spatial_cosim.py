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

Tray hand (simulate_tray_hand): nothing holds the cup. A massless tray body is welded to H (its z
the face axis) with the seed-002 tray's collision box (systems/tray_object.add_tray_contact), the cup
a free body on a 6-DOF joint from it (add_bottle: a ring of 16 point contacts at the cup's radius,
Coulomb friction mu, Hunt-Crossley dissipation; the solid cylinder's inertia of the planners), point
contact in the discrete SAP solver at 1 ms; the arm holds the start for SETTLE_S while the contact
takes up the cup's weight, then plays the plan. sim/spatial_hold.TrayLog logs the plant's state every
step in C++; after the run the cup's slide and tilt on the tray (its joint coordinates) give
slid_off / tipped / slipped (final slide > SLIP_TOLERANCE_M) / unfinished / carried.
Example-robot-data's Panda declares no actuators: the tray co-simulation adds one per chain joint.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from pydrake.geometry import SceneGraph, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import ContactModel, CoulombFriction, DiscreteContactApproximation
from pydrake.multibody.tree import RotationalInertia, SpatialInertia
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Saturation, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.clearance import clearance_of_states
from qmt_drake.limits.contact_wrench import face_basis
from qmt_drake.limits.suction import GripModel, cached_grip
from qmt_drake.limits.tray_contact import TrayContactTerm, TrayCup
from qmt_drake.model.actuator_order import connect_joint_torques
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD, transfer_outcome, with_collision
from qmt_drake.sim.cosim_run import CoSim, run
from qmt_drake.sim.spatial_actuation import (
    SpatialMotorDrive,
    add_tracking_logs,
    spatial_drive,
    tracking_report,
)
from qmt_drake.sim.spatial_contact_hand import CONTACT_SETTLE_S, build_contact_cosim
from qmt_drake.sim.spatial_hold import HoldLog, TrayLog, run_until_detached
from qmt_drake.sim.spatial_recording import SpatialRecording, add_part_box
from qmt_drake.systems.payload import allow_contact, six_dof_joint_of
from qmt_drake.systems.tray_object import (
    BottleSpec,
    add_bottle,
    add_tray_contact,
    seated_pose_on_tray,
)

TIME_STEP_S = 1e-3  # the plant step by default [s]
MAX_TIME_STEP_S = 5e-3  # the largest plant step a user may choose [s]
KP_1_S2, KD_1_S, KI_1_S3 = 900.0, 60.0, 0.0  # acceleration-level PID of the inverse-dynamics controller
TAIL_S = 0.5
FINE_GRIP = (24, 8)
COLLISION_CHECK_EVERY = 5  # logged 1 ms states: every 5th, then state by state near the minima (limits/clearance.py)


def collision_check(sc, logs, root_context, outcome: str, lost_at_s, settle_s: float = 0.0) -> tuple[str, dict]:
    """After the run (no system in the loop): the clearance of the logged arm and its carried part from the
    scenario's obstacles until the part was lost; (outcome, facts) with outcome 'collided' when it went
    below 0 first (outcome.with_collision; collided_at_s and collision_pair: the first touch). The obstacles
    push nothing in the simulated dynamics: the first touch ends the transfer. No obstacles: (outcome, {})."""
    if not sc.obstacles:
        return outcome, {}
    log = logs["arm_state"].FindLog(root_context)
    t = log.sample_times() - settle_s
    keep = (t >= 0.0) & (t <= (np.inf if lost_at_s is None else lost_at_s))
    c = clearance_of_states(sc, t[keep], log.data()[:sc.n_dof, keep].T, every=COLLISION_CHECK_EVERY)
    first = c.pop("first_contact")
    at = None if first is None else first["time_s"]
    return with_collision(outcome, at, lost_at_s), {**c, "collided_at_s": at,
                                                    "collision_pair": None if first is None else first["pair"]}


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
    ideal controller, or the dc_motor drive) wired to the arm; (src, motors or None)."""
    pp, acc = reference[:2]
    src = builder.AddSystem(TrajectorySource(pp, output_derivative_order=1))
    src_a = builder.AddSystem(TrajectorySource(acc))
    motors = add_ideal_controller(builder, plant, arm, ctrl_sc, src, src_a) if drive is None else \
        drive.add_to(builder, plant, arm, src.get_output_port(), src_a.get_output_port(), time_step_s)
    return src, motors


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
                        export: bool = False) -> CoSim:
    """The co-simulation of `traj` on scenario sc as a CoSim, its parts chosen by the hand (the weld, the
    contact hand, the tray) and the actuator. grip: the suction hand's stability set in the co-simulation
    (default: the scenario's cup with the finer FINE_GRIP polyhedron). actuator: 'ideal' (the
    inverse-dynamics controller) or 'dc_motor' (sim/spatial_actuation: PD voltage law, DC motors with gears,
    `feedforward` one of none / back-emf / full). record_path: also write a Meshcat recording there
    (sim/spatial_recording). contact: with hand.physics contact, keyword overrides of
    spatial_contact_hand.build_contact_cosim. controller_sc: the model the controller and its feedforward
    are built from (default sc; a sweep case simulates a drawn sc under the nominal controller); drive: a
    prepared dc_motor drive instead. time_step_s: the plant step [s] (default TIME_STEP_S; the plan is
    sampled and the hold checked at it). export: export the named ports (user composition)."""
    h = check_spatial_time_step(time_step_s)
    ctrl = sc if controller_sc is None else controller_sc
    if drive is None:
        drive = spatial_drive(ctrl, traj.sample([0.0])[0][0], actuator, feedforward)
    if sc.hand_kind == "tray":
        return build_tray_hand_cosim(sc, traj, drive=drive, record_path=record_path, controller_sc=ctrl,
                                     time_step_s=h, export=export)
    if sc.hand_kind == "suction" and grip is None:  # built once per cup (its hull is 12 % of a run)
        grip = cached_grip(sc.grip.radius_m, sc.grip.pull_force_N, sc.grip.friction, face_normal=sc.grip.basis[2],
                           rim_points=FINE_GRIP[0], pyramid_edges=FINE_GRIP[1])
    if sc.hand_physics == "contact":  # the part held by contact and a pull, not a weld (sim/spatial_contact_hand)
        kw = {"time_step_s": h, **(contact or {})}
        return build_contact_cosim(sc, traj, drive, _reference(_Delayed(traj, CONTACT_SETTLE_S), kw["time_step_s"]),
                                   add_drive, grip=grip, record_path=record_path, export=export, **kw)
    return build_weld_cosim(sc, traj, drive, ctrl, sc.hand_term(grip), actuator, record_path, h, export)


def add_weld_hand(plant, H, sc):
    """The breakable weld (a part, before Finalize): the part a free body with the scenario's payload
    inertia, welded to the hand frame H by a SAP weld constraint; (part body, weld constraint id)."""
    b = sc.body
    M = SpatialInertia.MakeFromCentralInertia(b.mass_kg, np.asarray(b.com_m, float),
                                              RotationalInertia(*np.diag(b.inertia_kgm2)))
    part = plant.AddRigidBody("part", plant.AddModelInstance("part"), M)
    return part, plant.AddWeldConstraint(H.body(), H.GetFixedPoseInBodyFrame(), part, RigidTransform())


def build_weld_cosim(sc, traj, drive, ctrl, term, actuator, record_path, h: float, export: bool) -> CoSim:
    """The weld hand's co-simulation (module docstring): the hold checked on C++ logs (HoldLog) after each
    chunk, the weld released at the first step the hand term's ratio passes 1 (run_until_detached)."""
    builder = DiagramBuilder()
    plant, H, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, time_step_s=h,
                                 effort_limit_Nm=sc.torque_limit_Nm, velocity_limit_rad_s=sc.velocity_limit_rad_s,
                                 finalize=False)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)  # SAP: weld constraints
    builder.AddSystem(plant)
    part, weld_id = add_weld_hand(plant, H, sc)
    if drive is not None:
        drive.prepare_plant(plant, H.model_instance(), sc)
    rec = None
    if record_path is not None:
        rec = SpatialRecording.for_scenario(builder, plant, H.model_instance(), sc)
        size = 4.0 * rec.link_radius_m
        add_part_box(plant, part, sc.body.com_m, size)
        # only the part and the floor collide: a detached part lands instead of falling for ever
        plant.RegisterCollisionGeometry(part, RigidTransform(np.asarray(sc.body.com_m, float)), Sphere(size / 2),
                                        "part_collision", CoulombFriction(0.5, 0.5))
    plant.Finalize()
    if rec is not None:
        rec.connect(builder, plant)
    arm = H.model_instance()
    reference = _reference(traj, h)
    t_end, q_goal = reference[2:]
    src, motors = add_drive(builder, plant, arm, ctrl, drive, reference, h)
    logs = add_tracking_logs(builder, plant.get_state_output_port(arm), src.get_output_port(), h, motors)
    hold = HoldLog(builder, plant, part, term, h)
    q0 = traj.sample([0.0])[0][0]
    ports = spatial_ports(plant, arm, src, {"part_state": plant.get_state_output_port(part.model_instance())})
    diagram = finish_build(builder, plant, arm, q0, ports, export)
    ctx0 = plant.CreateDefaultContext()
    X_WP0 = H.CalcPoseInWorld(ctx0)  # the part seated in the cup at the plan's start
    plant.SetDefaultFloatingBaseBodyPose(part, X_WP0)
    out = {}

    def start(sim) -> None:
        pctx = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
        plant.SetPositions(pctx, arm, q0)
        plant.SetFreeBodyPose(pctx, part, H.CalcPoseInWorld(pctx))
        if rec is not None:
            rec.start(plant, pctx, sc.path_points_m)

    def release(root_context):  # the cup lets go: the part flies free for the rest of the run
        plant.SetConstraintActiveStatus(plant.GetMyMutableContextFromRoot(root_context), weld_id, False)

    def advance(sim) -> None:
        out["detached"], out["lost_at_s"], out["largest"] = run_until_detached(sim, diagram, hold, t_end, release)

    def finish(sim, wall) -> dict:
        if rec is not None:
            rec.save(record_path)
        ctx = sim.get_context()
        pctx = plant.GetMyContextFromRoot(ctx)
        q_end = plant.GetPositions(pctx, arm)
        detached, lost_at_s = out["detached"], out["lost_at_s"]
        lost = "detached" if detached else None
        err = float(np.abs(q_goal - q_end).max())
        outcome = transfer_outcome(lost, False, err, ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
        outcome, hit = collision_check(sc, logs, ctx, outcome, lost_at_s if lost else None)
        gap = float(np.linalg.norm(plant.GetFreeBodyPose(pctx, part).translation()
                                   - H.CalcPoseInWorld(pctx).translation()))
        return {"outcome": outcome, "held": outcome == "carried", "lost_at_s": lost_at_s,
                "max_grip_ratio_while_held": out["largest"], "final_goal_error_rad": err, "duration_s": traj.duration_s,
                "part_distance_from_cup_at_end_m": gap, "actuator": actuator,
                **tracking_report(logs, ctx, traj.duration_s, sc, drive), **hit}

    return CoSim("spatial_weld", diagram, plant, start, advance, finish, dict, ports=ports, loggers=logs, monitor=hold,
                 handles=SimpleNamespace(t_final_s=t_end, q_goal=q_goal, arm_instance=arm, part_body=part))


# --- tray hand: the cup a free body in friction contact with a tray box welded to the hand ---------

SETTLE_S = 0.2  # the arm holds the start while the cup's contact takes up its weight (tray/cosim.SEATING_S)
TRAY_LOG_PERIOD_S = 1e-3
# carried: the cup ends on the tray with its base within this of its seat (chosen: a cup moved by 5 mm
# on the tray is still where it was put; the shipped plans, carried, end within 8 um of the seat)
SLIP_TOLERANCE_M = 5e-3


@dataclass(frozen=True)
class CupSpec(BottleSpec):
    """The scenario's cup as systems/tray_object's BottleSpec (its contact ring at the cup's radius,
    point contact with the seed-002 tray's stiffness and dissipation), with the solid cylinder's
    inertia of limits/tray_contact.TrayCup (the planners' body) instead of the bottle's shell."""

    inertia_T_kgm2: tuple = ()

    @classmethod
    def from_cup(cls, cup: TrayCup) -> CupSpec:
        return cls("cup", cup.mass_kg, cup.radius_m, cup.height_m, cup.h_G, cup.mass_kg, cup.radius_m,
                   friction=cup.friction, inertia_T_kgm2=tuple(np.diag(cup.inertia_T())))

    def spatial_inertia(self) -> SpatialInertia:
        return SpatialInertia.MakeFromCentralInertia(self.mass_kg, np.array([0.0, 0.0, self.com_height_m]),
                                                     RotationalInertia(*self.inertia_T_kgm2))


class _Delayed:
    """traj after `settle_s` of rest at its start (a spatial_trajectory kind)."""

    def __init__(self, traj, settle_s: float) -> None:
        self.inner, self.settle_s = traj, settle_s
        self.duration_s = traj.duration_s + settle_s

    def sample(self, t):
        t = np.atleast_1d(np.asarray(t, float)) - self.settle_s
        q, qd, qdd = self.inner.sample(np.maximum(t, 0.0))
        qd[t < 0], qdd[t < 0] = 0.0, 0.0
        return q, qd, qdd


def _add_tray_and_cup(plant, scene_graph, H, sc):
    """Register the plant with scene_graph; a massless tray body welded to H (its z the face axis,
    surface at H's origin) with its box, and the cup on a 6-DOF joint from it; (tray, cup, spec)."""
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    plant.set_contact_model(ContactModel.kPoint)
    spec = CupSpec.from_cup(sc.cup)
    tray = plant.AddRigidBody("tray", plant.AddModelInstance("tray"), SpatialInertia.Zero())
    X_HT = RigidTransform(RotationMatrix(face_basis(sc.face_axis).T), np.zeros(3))
    plant.WeldFrames(H, tray.body_frame(), X_HT)
    add_tray_contact(plant, tray, spec, size_m=sc.cup.tray_size_m, visual=True)
    cup = add_bottle(plant, spec, "cup", tray_body=tray)
    six_dof_joint_of(plant, cup).SetDefaultPose(seated_pose_on_tray())
    return tray, cup, spec


def classify_tray_run(t, slide, tilt, spec: CupSpec, tray_size_m) -> tuple[str | None, float | None, bool]:
    """(lost outcome or None, time lost, slipped) from the logged slide (2, S) [m] and tilt (S,) [rad]:
    slid_off when the base centre leaves the tray surface, tipped when the tilt passes the angle at
    which the centre of mass is over the base's edge, atan(r / h_G); slipped when the cup ends more
    than SLIP_TOLERANCE_M from its seat (tray/cosim.classify's rules, for the cup)."""
    off = np.any(np.abs(slide.T) > np.asarray(tray_size_m[:2]) / 2, axis=1)
    tipped = tilt > np.arctan2(spec.contact_radius_m, spec.com_height_m)
    lost = off | tipped
    if lost.any():
        k = int(np.argmax(lost))
        return ("slid_off" if off[k] and not tipped[k] else "tipped"), float(t[k]), True
    return None, None, bool(np.hypot(*slide[:, -1]) > SLIP_TOLERANCE_M)


def simulate_tray_hand(sc, traj, **options) -> dict:
    """simulate_spatial for a tray hand (build_tray_hand_cosim, the one run)."""
    return run(build_tray_hand_cosim(sc, traj, **options))


def add_tray_hand(builder, plant, H, sc):
    """The tray hand (a part, before Finalize): a SceneGraph, the tray welded to H and the cup standing on it
    (_add_tray_and_cup); (scene_graph, tray, cup, spec)."""
    scene_graph = builder.AddSystem(SceneGraph())
    return (scene_graph, *_add_tray_and_cup(plant, scene_graph, H, sc))


def build_tray_hand_cosim(sc, traj, *, drive: SpatialMotorDrive | None = None, record_path=None,
                          controller_sc=None, time_step_s: float = TIME_STEP_S, export: bool = False) -> CoSim:
    """The tray hand's co-simulation: the cup is a free body standing on the tray box under Coulomb
    friction (point contact, discrete SAP at 1 ms), nothing holds it; after SETTLE_S at the start the
    plan is played. Outcome (qmt_drake/outcome.py): slid_off / tipped / slipped / unfinished / carried.
    max_grip_ratio_while_held: the largest TrayContactTerm ratio of the cup's own contact wrench
    (Newton-Euler on its simulated motion, gravity the only other force) until it first exceeds 1.
    drive: the DC motors (spatial_drive) instead of the ideal inverse-dynamics controller; controller_sc:
    the ideal controller's model (default sc); time_step_s: the plant step [s] (and the log period)."""
    ctrl = sc if controller_sc is None else controller_sc
    h = time_step_s
    builder = DiagramBuilder()
    plant, H, names = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, time_step_s=h,
                                     effort_limit_Nm=sc.torque_limit_Nm,
                                     velocity_limit_rad_s=sc.velocity_limit_rad_s, finalize=False)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    builder.AddSystem(plant)
    scene_graph, tray, cup, spec = add_tray_hand(builder, plant, H, sc)
    if drive is not None:
        drive.prepare_plant(plant, H.model_instance(), sc)
    rec = None if record_path is None else SpatialRecording.for_scenario(builder, plant, H.model_instance(), sc,
                                                                              scene_graph)
    plant.Finalize()
    builder.Connect(plant.get_geometry_pose_output_port(), scene_graph.get_source_pose_port(plant.get_source_id()))
    builder.Connect(scene_graph.get_query_output_port(), plant.get_geometry_query_input_port())
    if rec is not None:
        rec.connect(builder, plant, geometry_connected=True)
    allow_contact(plant, scene_graph, tray, cup)
    arm = H.model_instance()
    reference = _reference(_Delayed(traj, SETTLE_S), h)
    t_end, q_goal = reference[2:]
    src, motors = add_drive(builder, plant, arm, ctrl, drive, reference, h)
    tracking = add_tracking_logs(builder, plant.get_state_output_port(arm), src.get_output_port(), h, motors)
    log = TrayLog(builder, plant, cup, TRAY_LOG_PERIOD_S if h == TIME_STEP_S else h)
    q0 = traj.sample([0.0])[0][0]
    ports = spatial_ports(plant, arm, src, {"cup_state": plant.get_state_output_port(cup.model_instance())})
    diagram = finish_build(builder, plant, arm, q0, ports, export)

    def start(sim) -> None:
        pctx = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
        plant.SetPositions(pctx, arm, q0)
        if rec is not None:
            rec.start(plant, pctx, sc.path_points_m)

    def finish(sim, wall) -> dict:
        if rec is not None:
            rec.save(record_path)
        ctx = sim.get_context()
        t, slide, tilt = log.slide_tilt(ctx)
        seated = t >= SETTLE_S
        slide, tilt = slide[:, seated] - seated_pose_on_tray().translation()[:2, None], tilt[seated]
        lost, lost_at, slipped = classify_tray_run(t[seated] - SETTLE_S, slide, tilt, spec, sc.cup.tray_size_m)
        err = float(np.abs(q_goal - plant.GetPositions(plant.GetMyContextFromRoot(ctx), arm)).max())
        outcome = transfer_outcome(lost, slipped and lost is None, err, ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
        outcome, hit = collision_check(sc, tracking, ctx, outcome, lost_at, settle_s=SETTLE_S)
        # the tray term's ratio of the cup's contact wrench from the first update at SETTLE_S, up to and
        # including its first value above 1
        t_up, r = log.ratios(ctx, TrayContactTerm(sc.cup, sc.gravity_m_s2), SETTLE_S)
        over = np.flatnonzero(r > 1.0)
        largest = float(np.max(r[:over[0] + 1] if len(over) else r, initial=0.0))
        return {"outcome": outcome, "held": outcome == "carried", "lost_at_s": lost_at,
                "max_grip_ratio_while_held": largest,
                "contact_ratio_first_above_1_s": float(t_up[over[0]]) - SETTLE_S if len(over) else None,
                "final_goal_error_rad": err, "duration_s": traj.duration_s,
                "max_slide_m": float(np.max(np.hypot(*slide))), "final_slide_m": float(np.hypot(*slide[:, -1])),
                "max_tilt_rad": float(np.max(tilt)), "actuator": "ideal" if drive is None else "dc_motor",
                **tracking_report(tracking, ctx, t_end, sc, drive), **hit}

    return CoSim("spatial_tray", diagram, plant, start, lambda sim: sim.AdvanceTo(t_end), finish, dict,
                 ports=ports, loggers=tracking, monitor=log,
                 handles=SimpleNamespace(t_final_s=t_end, q_goal=q_goal, arm_instance=arm, part_body=cup))
