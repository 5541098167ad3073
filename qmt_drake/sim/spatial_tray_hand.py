"""The spatial co-simulation's tray hand part (sim/spatial_cosim.assemble): nothing holds the cup. A massless
tray body is welded to H (its z the face axis) with the seed-002 tray's collision box
(systems/tray_object.add_tray_contact), the cup a free body on a 6-DOF joint from it (add_bottle: a ring of
16 point contacts at the cup's radius, Coulomb friction mu, Hunt-Crossley dissipation; the solid cylinder's
inertia of the planners), point contact in the discrete SAP solver at 1 ms; the arm holds the start for
SETTLE_S while the contact takes up the cup's weight, then plays the plan. sim/spatial_hold.TrayLog logs the
plant's state every step in C++; after the run the cup's slide and tilt on the tray (its joint coordinates)
give slid_off / tipped / slipped (final slide > SLIP_TOLERANCE_M) / unfinished / carried.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import ContactModel
from pydrake.multibody.tree import RotationalInertia, SpatialInertia

from qmt_drake.limits.contact_wrench import face_basis
from qmt_drake.limits.tray_contact import TrayContactTerm, TrayCup
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD, transfer_outcome
from qmt_drake.sim.spatial_actuation import tracking_report
from qmt_drake.sim.spatial_hold import HandPart, TrayLog, collision_check
from qmt_drake.sim.spatial_recording import SpatialRecording
from qmt_drake.systems.payload import allow_contact, six_dof_joint_of
from qmt_drake.systems.tray_object import BottleSpec, add_bottle, add_tray_contact, seated_pose_on_tray

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


def add_tray_and_cup(plant, scene_graph, H, sc):
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


def add_tray_hand(builder, plant, H, sc):
    """The tray hand (a part, before Finalize): a SceneGraph, the tray welded to H and the cup standing on it
    (add_tray_and_cup); (scene_graph, tray, cup, spec)."""
    scene_graph = builder.AddSystem(SceneGraph())
    return (scene_graph, *add_tray_and_cup(plant, scene_graph, H, sc))


class TrayCupHand(HandPart):
    """The tray hand part: the cup is a free body standing on the tray box under Coulomb friction (point
    contact, discrete SAP at 1 ms), nothing holds it; after SETTLE_S at the start the plan is played.
    Outcome (qmt_drake/outcome.py): slid_off / tipped / slipped / unfinished / carried.
    max_grip_ratio_while_held: the largest TrayContactTerm ratio of the cup's own contact wrench
    (Newton-Euler on its simulated motion, gravity the only other force) until it first exceeds 1."""

    kind, settle_s, loggers, approximation = "spatial_tray", SETTLE_S, {}, "sap"

    def __init__(self, sc, log_type=TrayLog, default_step_s: float = 1e-3) -> None:
        self.sc, self.log_type, self.default_step_s = sc, log_type, default_step_s

    def configure(self, plant) -> None:
        pass

    def add(self, builder, plant, H) -> None:
        self.scene_graph, self.tray, self.cup, self.spec = add_tray_hand(builder, plant, H, self.sc)

    def recording(self, builder, plant, arm):
        return SpatialRecording.for_scenario(builder, plant, arm, self.sc, self.scene_graph)

    def connect(self, builder, plant, H, rec, continuous: bool) -> None:
        self.connect_scene_graph(builder, plant, rec)
        allow_contact(plant, self.scene_graph, self.tray, self.cup)

    def add_monitor(self, builder, plant, arm, h: float) -> None:
        self.monitor = self.log_type(builder, plant, self.cup, TRAY_LOG_PERIOD_S if h == self.default_step_s else h)

    def ports(self, plant) -> dict:
        return {"cup_state": plant.get_state_output_port(self.cup.model_instance())}

    def finish(self, ctx, plant, H, err, tracking, drive, traj, t_end) -> dict:
        sc, log = self.sc, self.monitor
        t, slide, tilt = log.slide_tilt(ctx)
        seated = t >= SETTLE_S
        slide, tilt = slide[:, seated] - seated_pose_on_tray().translation()[:2, None], tilt[seated]
        lost, lost_at, slipped = classify_tray_run(t[seated] - SETTLE_S, slide, tilt, self.spec, sc.cup.tray_size_m)
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
