"""The spatial co-simulation's contact hand (`hand.physics: contact`): the part a free body held by physics.

sim/spatial_cosim.simulate_spatial's default hand (`hand.physics: weld`) welds the part to the hand and
declares it detached the first millisecond its required wrench leaves the hand's limit. Here nothing
holds the part but contact and a pull, so a loss is simulated, not declared:

- frames: F, the hand's face frame on the hand body (origin at H's origin, z_F = -u with u the scenario's
  face_axis, so the part hangs on the -z side of F as in systems/payload.py); the part P on a 6-DOF joint
  from F (seated: X_FP = I), its mass, centre of mass and central inertia the scenario's payload. Its
  joint coordinates are its pose in F: gap = -z (>0: away from the face), slide = |(x, y)|.
- magnet (hand.kind magnet): the thesis's hand (systems/payload.add_payload's geometry, sim/magnet_hand's
  wiring): a box on the hand whose lower face is the attraction face, and a ring of small spheres on the
  part at the core's radius (PayloadSpec.steel_cylinder's contact data: 3.9 mm ring, mu 0.3, 1e6 N/m per
  sphere, Hunt-Crossley 5 s/m), the pull systems/electromagnet.electromagnet_force (ONE implementation of
  F(I, gap, slide)) of the thesis's chapter-3 coil (THESIS_COILS table_3_2, g0 0.5 mm), its current set by
  sim/magnet_hand's calibration rule with the scenario's moment limit as the boundary: the quasi-static
  hold moment (F(I, 0) - m g) min(rho, mu r_G) equals hand.moment_limit_Nm.
- suction (hand.kind suction): the cup's rim as `grip.rim_points` spheres on the hand on a circle of the
  grip's radius (sphere bottoms in the face plane), pressing on a flat box face on the part (friction
  grip.friction, RIM_STIFFNESS_N_PER_M shared by the rim, RIM_DISSIPATION_S_PER_M); the vacuum pull
  grip.pull_force_N (the scenario's vacuum_force_N, pressure x area) on the part along the cup axis z_F,
  applied at the cup's centre, while sealed (the part's face within SEAL_GAP_M of the face plane at the
  cup's centre), nothing beyond: a cup that lifts off loses its vacuum.
- point contact, MultibodyPlant's discrete lagged approximation (the planar hands', sim/plant.py) at the
  co-simulation's 1 ms; the arm holds its start for CONTACT_SETTLE_S while the contact takes up the load,
  then plays the plan (times below are from the plan's start).
- dissipation under every approximation: Drake's TAMSI, similar and lagged use the Hunt-Crossley
  dissipation d [s/m], SAP only a relaxation time tau [s] and ignores d (DiscreteContactApproximation,
  "Accessing point contact parameters"); a geometry without one gets Drake's default 0.1 s, so a pair 0.2 s
  (the pair's tau is the sum of its two geometries'). Normal force with x = -phi >= 0 the penetration:
  Hunt-Crossley f = k x (1 + d xdot) (MultibodyPlant's contact model), SAP's linear Kelvin-Voigt
  f = k (x + tau xdot) (SapHuntCrossley/SapFrictionConeConstraint: gamma_n / dt = (-k phi - tau k v_n)_+).
  Both have stiffness k; their damping coefficients are k d x and k tau, equal at x when tau = d x. Matched
  at the seat (`relaxation_time_s`): x the static penetration of each contact under the part's seat load,
  the part hanging under a face-down hand (the picks' and places' pose): the pull at the seat minus m g
  (the pull alone if that is not positive) shared by the rim's or the ring's points, x = load / (points
  x the pair's stiffness). Each of the pair's two geometries gets tau / 2. Suction: (40 - 2 x 9.81) N on
  1e5 N/m, x = 0.204 mm, tau = 20 s/m x x = 4.08 ms; magnet: 0.146 N on 8 x 5e5 N/m, x = 37 nm,
  tau = 0.18 us (the ring's Hunt-Crossley damping is negligible at the seat, SAP's default was 1e6 times it).
- the arrival (`arrival_error`): the part may still rock on its rim when the plan's hold at the goal
  (spatial_cosim.TAIL_S) ends, and the arm, under a law without a model of the rocking part, rocks with it
  (UR5 suction at x1.0212, 0.5 ms lagged: +-1.2 mrad at about 2.5 Hz, decaying over about 2 s to a
  steady 0.08 mrad), so the error at one instant is a phase of that oscillation. The run goes on past the
  tail in ARRIVAL_CHUNK_S chunks, the arm holding the goal, until every joint position has varied by less
  than ARRIVAL_STEADY_FRACTION of the arrival tolerance over the last ARRIVAL_WINDOW_S (at most
  ARRIVAL_MAX_WAIT_S; not when the part is already lost), and the arrival error is the largest goal error
  over that last window (steady or not: no phase decides it). The wait is reported (arrival_wait_s,
  arrival_steady); the part must stay held through it.

Monitoring after the run from logged signals (VectorLogSink, no Python system in the loop): the part's
joint state every step (the arrival's wait reads the logged arm state between chunks). Lost ("detached",
qmt_drake/outcome.py) at the first step the gap exceeds LOST_GAP_M or the slide LOST_SLIDE_M; slipped when
held but the final slide exceeds SLIP_TOLERANCE_M.
Diagnostics (`_diagnostics`): the hand's limit ratio (the weld's threshold, the planners' constraint) of
the hand motion this run actually made while the part was held (logged arm state and acceleration
through sc.chain), its largest value and the first time it passed 1: where the threshold would have
declared a loss; for the magnet also the rigid-body hold condition of its contact ring and pull.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake import symbolic
from pydrake.geometry import (
    AddContactMaterial,
    Box,
    ProximityProperties,
    SceneGraph,
    Sphere,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import ContactModel, CoulombFriction, DiscreteContactApproximation
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    QuaternionFloatingJoint,
    RotationalInertia,
    SpatialInertia,
)
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, MatrixGain

from qmt_drake.catalog import THESIS_COILS
from qmt_drake.limits.contact_wrench import face_basis
from qmt_drake.limits.suction import SuctionTerm, cached_grip
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD, transfer_outcome
from qmt_drake.sim.magnet_hand import MAGNET_EFFECTIVE_GAP_M, hold_lever_m
from qmt_drake.sim.spatial_actuation import tracking_report
from qmt_drake.sim.spatial_hold import HandPart
from qmt_drake.sim.spatial_recording import SpatialRecording
from qmt_drake.systems.electromagnet import MagnetParams, electromagnet_force
from qmt_drake.systems.payload import PayloadSpec, allow_contact
from qmt_drake.systems.scalar_ops import symbolic_law

CONTACT_SETTLE_S = 0.2  # the arm holds the start while the contact takes up the part's load
MAGNET_COIL = "table_3_2"  # the thesis's chapter-3 coil (156 turns): the UR5 magnet task's moment limit is ch.3's
# suction rim (chosen, stated): a cup lip of 1e5 N/m over the whole rim, lightly damped (Hunt-Crossley)
RIM_STIFFNESS_N_PER_M = 1.0e5
RIM_DISSIPATION_S_PER_M = 20.0
RIM_SPHERE_RADIUS_M = 1.0e-3
PART_FACE_HALF_M = 0.05  # the suction part's flat face (a box 100 mm square under the cup)
SEAL_GAP_M = 2.0e-3  # the vacuum holds while the part's face is within this of the cup at its centre
LOST_GAP_M = 5.0e-3  # lost: the part's face more than this from the hand's face ...
LOST_SLIDE_M = 10.0e-3  # ... or slid more than this along it
SLIP_TOLERANCE_M = 5.0e-3  # held to the end but ended further than this from its seat: slipped
# the arrival (module docstring): steady when every joint varied less than this fraction of the tolerance ...
ARRIVAL_STEADY_FRACTION = 0.1
ARRIVAL_WINDOW_S = 0.5  # ... over this window (longer than the rocking's period, 0.3-0.5 s) ...
ARRIVAL_CHUNK_S = 0.1  # ... checked after each such chunk past the plan's tail ...
ARRIVAL_MAX_WAIT_S = 4.0  # ... for at most this long
# what the contact hand's runs mean (studies key stored runs by it): 2 = SAP's relaxation time matched to the
# Hunt-Crossley dissipation and the arrival measured steady (session 18); 1 = before
CONTACT_HAND_REVISION = 2


def face_frame_rotation(face_axis) -> np.ndarray:
    """R_HF: F's axes in H's, columns (t1, -t2, -u) of face_basis(u), right-handed, z_F = -u."""
    t1, t2, u = face_basis(face_axis)
    return np.column_stack([t1, -t2, -u])


def magnet_spec(sc) -> PayloadSpec:
    """The thesis's part and contact data for the scenario's mass and r_G (the centre of mass's distance
    along the face normal): PayloadSpec.steel_cylinder (its face radius from the steel's density)."""
    r_G = float(np.asarray(sc.body.com_m, float) @ (np.asarray(sc.face_axis, float) / np.linalg.norm(sc.face_axis)))
    return PayloadSpec.steel_cylinder(float(sc.body.mass_kg), r_G)


def magnet_current_A(sc, spec: PayloadSpec, params: MagnetParams) -> float:
    """sim/magnet_hand's calibration rule with the boundary the scenario's moment limit: the coil current
    whose quasi-static hold moment (F(I, 0) - m g) min(rho, mu r_G) is hand.moment_limit_Nm."""
    force = spec.mass_kg * float(np.linalg.norm(sc.gravity_m_s2)) + sc.moment_limit_Nm / hold_lever_m(spec)
    return params.current_for_force_A(force)


def seat_load_N(sc, pull_N: float) -> float:
    """The contact's total normal force [N] at the seat, the part hanging under a face-down hand: the pull
    minus its weight m |g| (the pull alone when that is not positive: a part too heavy to hang)."""
    load = pull_N - float(sc.body.mass_kg) * float(np.linalg.norm(sc.gravity_m_s2))
    return load if load > 0.0 else float(pull_N)


def relaxation_time_s(dissipation_s_per_m: float, load_N: float, stiffness_N_per_m: float) -> float:
    """SAP's relaxation time [s] equivalent to a Hunt-Crossley dissipation d at the static penetration
    x = load / stiffness (module docstring: k x (1 + d xdot) and k (x + tau xdot) damp alike at x when
    tau = d x). load_N and stiffness_N_per_m: one contact's, or all of them together (their ratio is x)."""
    return dissipation_s_per_m * load_N / stiffness_N_per_m


def _props(stiffness_N_per_m: float, dissipation_s_per_m: float, friction: float,
           pair_relaxation_time_s: float) -> ProximityProperties:
    """One geometry's contact material; its relaxation time half the pair's (Drake sums the two)."""
    props = ProximityProperties()
    AddContactMaterial(dissipation=dissipation_s_per_m, point_stiffness=stiffness_N_per_m,
                       friction=CoulombFriction(friction, friction), properties=props)
    props.AddProperty("material", "relaxation_time", 0.5 * pair_relaxation_time_s)
    return props


def _add_part(plant, sc, F_frame, R_HF):
    """The part: a free body on a 6-DOF joint from F, its inertia the scenario's payload expressed in F."""
    R_FH = R_HF.T
    I_F = R_FH @ np.asarray(sc.body.inertia_kgm2, float) @ R_HF
    M = SpatialInertia.MakeFromCentralInertia(
        float(sc.body.mass_kg), R_FH @ np.asarray(sc.body.com_m, float),
        RotationalInertia(I_F[0, 0], I_F[1, 1], I_F[2, 2], I_F[0, 1], I_F[0, 2], I_F[1, 2]))
    part = plant.AddRigidBody("part", plant.AddModelInstance("part"), M)
    joint = plant.AddJoint(QuaternionFloatingJoint("part_on_hand", F_frame, part.body_frame()))
    return part, joint


def magnet_relaxation_time_s(sc, spec: PayloadSpec, pull_N: float) -> float:
    """The ring's pair relaxation time [s] (module docstring): both geometries have the spec's stiffness, so
    each ring contact has half of it in series."""
    return relaxation_time_s(spec.hunt_crossley_dissipation_s_per_m, seat_load_N(sc, pull_N),
                             spec.n_contact_points * 0.5 * spec.point_stiffness_N_per_m)


def suction_relaxation_time_s(sc, pull_N: float, rim_stiffness_N_per_m: float, rim_dissipation_s_per_m: float) -> float:
    """The rim's pair relaxation time [s] (module docstring): the rim's total stiffness carries the seat load."""
    return relaxation_time_s(rim_dissipation_s_per_m, seat_load_N(sc, pull_N), rim_stiffness_N_per_m)


def _add_magnet_geometry(plant, hand_body, X_BF, part, spec: PayloadSpec, tau_s: float) -> None:
    """systems/payload.add_payload's geometry in the face frame F: the hand's face box, the part's ring;
    tau_s: the pair's relaxation time."""
    props = _props(spec.point_stiffness_N_per_m, spec.hunt_crossley_dissipation_s_per_m, spec.friction, tau_s)
    half, thick = 8.0e-3, 4.0e-3
    plant.RegisterCollisionGeometry(hand_body, X_BF @ RigidTransform([0.0, 0.0, thick / 2]),
                                    Box(2 * half, 2 * half, thick), "magnet_face", props)
    for k in range(spec.n_contact_points):
        a = 2.0 * math.pi * k / spec.n_contact_points
        p = [spec.contact_radius_m * math.cos(a), spec.contact_radius_m * math.sin(a), -spec.sphere_radius_m]
        plant.RegisterCollisionGeometry(part, RigidTransform(p), Sphere(spec.sphere_radius_m), f"ring_{k}", props)


def _add_suction_geometry(plant, hand_body, X_BF, part, grip, rim_stiffness_N_per_m: float,
                          rim_dissipation_s_per_m: float, tau_s: float) -> None:
    """The cup's rim: grip.rim_points spheres on the hand (bottoms in the face plane z_F = 0) on the grip's
    radius; the part's flat face a box top at z_P = 0. Both geometries get twice the per-point stiffness:
    Drake combines them in series, so each rim contact has rim_stiffness / rim_points. tau_s: the pair's
    relaxation time."""
    k = 2.0 * rim_stiffness_N_per_m / grip.rim_points
    props = _props(k, rim_dissipation_s_per_m, grip.friction, tau_s)
    r, s = grip.radius_m, RIM_SPHERE_RADIUS_M
    for i in range(grip.rim_points):
        a = 2.0 * math.pi * i / grip.rim_points
        plant.RegisterCollisionGeometry(hand_body, X_BF @ RigidTransform([r * math.cos(a), r * math.sin(a), s]),
                                        Sphere(s), f"rim_{i}", props)
    thick = 5.0e-3
    plant.RegisterCollisionGeometry(part, RigidTransform([0.0, 0.0, -thick / 2]),
                                    Box(2 * PART_FACE_HALF_M, 2 * PART_FACE_HALF_M, thick), "part_face", props)


def seal_law(plant, joint, pull_N: float, *, host_has_continuous_state: bool):
    """The vacuum: pull_N [N] on the part along z_F, applied at the cup's centre (F's origin), while the
    part's face is within SEAL_GAP_M of it; as generalized forces of the part's joint (plant state in,
    nv out; a SymbolicVectorSystem compiled once). With p_FP = (x, y, z) the force f z_F at F's origin is
    the moment (-y f, x f, 0) about P's origin (F's axes: the joint's angular velocities) and f on z."""
    nq, nv = plant.num_positions(), plant.num_velocities()
    q0, v0 = joint.position_start(), joint.velocity_start()
    pick = np.zeros((3, nq + nv))
    pick[[0, 1, 2], [q0 + 4, q0 + 5, q0 + 6]] = 1.0
    x, y, z = (symbolic.Variable(v) for v in ("x", "y", "z"))
    f = symbolic.if_then_else(z < -SEAL_GAP_M, symbolic.Expression(0.0), symbolic.Expression(pull_N))
    law = symbolic_law([x, y, z], [-y * f, x * f, f], host_has_continuous_state=host_has_continuous_state)
    to_joint = np.zeros((nv, 3))
    to_joint[[v0, v0 + 1, v0 + 5], [0, 1, 2]] = 1.0
    return pick, law, to_joint


def classify_contact_run(t, q_part, lost_gap_m: float = LOST_GAP_M, lost_slide_m: float = LOST_SLIDE_M):
    """From the logged part joint positions (7, S) [quaternion w x y z, p_FP] at times t (S,): (lost word or
    None, time lost, gap (S,) [m], slide (S,) [m], tilt (S,) [rad])."""
    gap, slide = -q_part[6], np.hypot(q_part[4], q_part[5])
    w = np.abs(q_part[0]) / np.linalg.norm(q_part[:4], axis=0)
    tilt = 2.0 * np.arccos(np.clip(w, 0.0, 1.0))
    lost = (gap > lost_gap_m) | (slide > lost_slide_m)
    if lost.any():
        return "detached", float(t[int(np.argmax(lost))]), gap, slide, tilt
    return None, None, gap, slide, tilt


def magnet_params(spec: PayloadSpec) -> MagnetParams:
    """The magnet hand's coil (MAGNET_COIL) on the part's face."""
    return MagnetParams(THESIS_COILS[MAGNET_COIL], MAGNET_EFFECTIVE_GAP_M, spec.face_radius_m)


def hand_pull(sc, grip, coil_current_A: float | None = None) -> tuple[float, float | None]:
    """The pull at the seat [N] and the magnet's coil current [A] (None for a cup): the calibrated current
    (magnet_current_A) unless coil_current_A is given; the cup's grip.pull_force_N."""
    if sc.hand_kind != "magnet":
        return float(grip.pull_force_N), None
    spec = magnet_spec(sc)
    params = magnet_params(spec)
    current = magnet_current_A(sc, spec, params) if coil_current_A is None else float(coil_current_A)
    return params.force_N(current), current


def add_contact_hand(builder, plant, H, sc, grip, rim_stiffness_N_per_m: float, rim_dissipation_s_per_m: float,
                     pull_N: float):
    """The contact hand (a part, before Finalize): a SceneGraph, the face frame F on the hand, the part on
    its 6-DOF joint from F and the magnet's or the suction rim's contact geometry, its relaxation time
    matched to its Hunt-Crossley dissipation at the seat load of pull_N [N] (hand_pull); (scene_graph, part,
    joint, magnet PayloadSpec or None, the pair relaxation time [s])."""
    scene_graph = builder.AddSystem(SceneGraph())
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    R_HF = face_frame_rotation(sc.face_axis)
    X_BF = H.GetFixedPoseInBodyFrame() @ RigidTransform(RotationMatrix(R_HF), np.zeros(3))
    F_frame = plant.AddFrame(FixedOffsetFrame("hand_face", H.body().body_frame(), X_BF))
    part, joint = _add_part(plant, sc, F_frame, R_HF)
    spec = magnet_spec(sc) if sc.hand_kind == "magnet" else None
    if spec is not None:
        tau = magnet_relaxation_time_s(sc, spec, pull_N)
        _add_magnet_geometry(plant, H.body(), X_BF, part, spec, tau)
    else:
        tau = suction_relaxation_time_s(sc, pull_N, rim_stiffness_N_per_m, rim_dissipation_s_per_m)
        _add_suction_geometry(plant, H.body(), X_BF, part, grip, rim_stiffness_N_per_m, rim_dissipation_s_per_m, tau)
    return scene_graph, part, joint, spec, tau


class ContactHand(HandPart):
    """The contact hand part (module docstring), for spatial_cosim.assemble: the part held by contact and a
    pull, its loss simulated. grip: the suction cup's GripModel (the co-simulation's finer rim: its
    rim_points, radius, friction, pull). rim_*: the suction rim's total stiffness [N/m] and Hunt-Crossley
    dissipation [s/m]; coil_current_A: the magnet's current instead of the calibrated one. Result keys as
    the weld's, plus the pull at the seat, the contact's gap, slide and tilt and the threshold diagnostic
    (max_grip_ratio_while_held: the threshold's largest ratio on this run's hand motion while held)."""

    kind, settle_s, monitor, approximation = "spatial_contact", CONTACT_SETTLE_S, None, DiscreteContactApproximation.kLagged

    def __init__(self, sc, grip=None, *, rim_stiffness_N_per_m: float = RIM_STIFFNESS_N_PER_M,
                 rim_dissipation_s_per_m: float = RIM_DISSIPATION_S_PER_M, coil_current_A: float | None = None) -> None:
        if sc.hand_kind not in ("magnet", "suction"):
            raise ValueError(f"contact hand: hand kind {sc.hand_kind!r} is neither magnet nor suction")
        self.sc, self.grip, self.coil_current_A = sc, grip, coil_current_A
        self.rim = (rim_stiffness_N_per_m, rim_dissipation_s_per_m)

    def configure(self, plant) -> None:  # (after its approximation, kLagged: the planar hands')
        plant.set_contact_model(ContactModel.kPoint)

    def add(self, builder, plant, H) -> None:
        self.pull, self.current = hand_pull(self.sc, self.grip, self.coil_current_A)
        (self.scene_graph, self.part, self.joint, self.spec,
         self.relaxation_time_s) = add_contact_hand(builder, plant, H, self.sc, self.grip, *self.rim, self.pull)

    def recording(self, builder, plant, arm):
        return SpatialRecording.add(builder, plant, arm, self.scene_graph)

    def connect(self, builder, plant, H, rec, continuous: bool) -> None:
        self.connect_scene_graph(builder, plant, rec)
        allow_contact(plant, self.scene_graph, H.body(), self.part)
        # the ideal actuator's controller integrates its error (continuous state); the dc_motor drive has none
        _add_pull(builder, plant, self.joint, self.spec, self.grip, self.current, continuous=continuous)

    def add_monitor(self, builder, plant, arm, h: float) -> None:
        self.n_arm = plant.num_positions(arm)
        self.loggers = {"part_state": LogVectorOutput(plant.get_state_output_port(self.part.model_instance()),
                                                      builder, h),
                        "arm_acceleration": LogVectorOutput(plant.get_generalized_acceleration_output_port(arm),
                                                            builder, h),
                        "arm_state_for_arrival": LogVectorOutput(plant.get_state_output_port(arm), builder, h)}

    def advance(self, sim, diagram, t_end: float) -> None:
        """To the tail's end, then on while the arm is not steady (module docstring, the arrival)."""
        sim.AdvanceTo(t_end)
        ctx = sim.get_context()
        wait = 0.0
        while wait < ARRIVAL_MAX_WAIT_S - 1e-9 and not self._steady(ctx):
            wait = min(wait + ARRIVAL_CHUNK_S, ARRIVAL_MAX_WAIT_S)
            sim.AdvanceTo(t_end + wait)
        self.arrival_wait_s = wait

    def _steady(self, ctx) -> bool:
        """The part lost (no arrival to wait for), or every arm joint within ARRIVAL_STEADY_FRACTION of the
        arrival tolerance over the last ARRIVAL_WINDOW_S."""
        part = self.loggers["part_state"].FindLog(ctx)
        if classify_contact_run(part.sample_times(), part.data()[:7])[0] is not None:
            return True
        log = self.loggers["arm_state_for_arrival"].FindLog(ctx)
        t, q = log.sample_times(), log.data()[:self.n_arm]
        w = q[:, t >= t[-1] - ARRIVAL_WINDOW_S + 1e-9]
        return bool((w.max(axis=1) - w.min(axis=1)).max() < ARRIVAL_STEADY_FRACTION * ARRIVAL_TOLERANCE_DC_MOTOR_RAD)

    def ports(self, plant) -> dict:
        return {"part_state": plant.get_state_output_port(self.part.model_instance())}

    def finish(self, ctx, plant, H, err, logs, drive, traj, t_end) -> dict:
        sc = self.sc
        log = self.loggers["part_state"].FindLog(ctx)
        t = log.sample_times() - CONTACT_SETTLE_S
        lost, lost_at, gap, slide, tilt = classify_contact_run(t, log.data()[:7])
        moving = t >= 0.0
        held = moving & (t < lost_at) if lost is not None else moving
        slipped = lost is None and bool(slide[-1] > SLIP_TOLERANCE_M)
        err_now, err = err, arrival_error(logs["arm_state"].FindLog(ctx), logs["desired_state"].FindLog(ctx), sc.n_dof)
        outcome = transfer_outcome(lost, slipped, err, ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
        threshold = _diagnostics(sc, self.grip, self.spec, self.pull, logs["arm_state"].FindLog(ctx),
                                 self.loggers["arm_acceleration"].FindLog(ctx), lost_at)
        return {"outcome": outcome, "held": outcome == "carried", "lost_at_s": lost_at, "hand_physics": "contact",
                "final_goal_error_rad": err, "goal_error_at_end_rad": err_now, "arrival_wait_s": self.arrival_wait_s,
                "arrival_steady": self.arrival_wait_s < ARRIVAL_MAX_WAIT_S - 1e-9 or self._steady(ctx),
                "relaxation_time_s": self.relaxation_time_s, "duration_s": traj.duration_s, "pull_N": self.pull,
                "max_gap_while_held_m": float(gap[held].max(initial=0.0)),
                "max_slide_while_held_m": float(slide[held].max(initial=0.0)),
                "max_tilt_while_held_rad": float(tilt[held].max(initial=0.0)),
                "final_slide_on_face_m": float(slide[-1]),
                "final_gap_m": float(gap[-1]), "max_slide_m": float(slide[moving].max(initial=0.0)),
                "max_gap_m": float(gap[moving].max(initial=0.0)),  # the loss included (margin_runs.spatial_margin)
                "part_distance_from_cup_at_end_m": float(np.linalg.norm(log.data()[4:7, -1])),
                "max_grip_ratio_while_held": threshold["threshold_max_ratio"],  # the weld's key: its threshold, held
                **threshold, "actuator": "ideal" if drive is None else "dc_motor",
                **tracking_report(logs, ctx, traj.duration_s + CONTACT_SETTLE_S, sc, drive)}


def arrival_error(arm_log, desired_log, n: int) -> float:
    """The arrival error [rad] (module docstring): the largest |q_goal - q| of the arm's n joints over the
    run's last ARRIVAL_WINDOW_S, q_goal the reference's last sample."""
    t = arm_log.sample_times()
    w = t >= t[-1] - ARRIVAL_WINDOW_S + 1e-9
    goal = desired_log.data()[:n, -1:]
    return float(np.abs(goal - arm_log.data()[:n, w]).max())


def _add_pull(builder, plant, joint, spec, grip, current_A: float | None, continuous: bool) -> None:
    """Wire the magnet's (its coil at current_A) or the vacuum's pull into the plant's applied generalized
    force."""
    if spec is not None:
        params = magnet_params(spec)
        magnet = builder.AddNamedSystem("magnet", electromagnet_force(params, plant, joint,
                                                                      host_has_continuous_state=continuous))
        coil = builder.AddNamedSystem("coil_current", ConstantVectorSource([current_A]))
        builder.Connect(plant.get_state_output_port(), magnet.GetInputPort("plant_state"))
        builder.Connect(coil.get_output_port(), magnet.GetInputPort("coil_current"))
        builder.Connect(magnet.GetOutputPort("generalized_force"), plant.get_applied_generalized_force_input_port())
        return
    pick, law, to_joint = seal_law(plant, joint, grip.pull_force_N, host_has_continuous_state=continuous)
    sel = builder.AddNamedSystem("part_translation", MatrixGain(pick))
    law = builder.AddNamedSystem("vacuum", law)
    out = builder.AddNamedSystem("vacuum_on_joint", MatrixGain(to_joint))
    builder.Connect(plant.get_state_output_port(), sel.get_input_port())
    builder.Connect(sel.get_output_port(), law.get_input_port())
    builder.Connect(law.get_output_port(), out.get_input_port())
    builder.Connect(out.get_output_port(), plant.get_applied_generalized_force_input_port())


def _over(name: str, ratio, t) -> dict:
    over = np.flatnonzero(ratio > 1.0)
    return {f"{name}_max_ratio": float(np.max(ratio, initial=0.0)),
            f"{name}_first_above_1_s": float(t[over[0]]) if len(over) else None}


def _diagnostics(sc, grip, spec, pull_N: float, arm_log, acc_log, lost_at_s) -> dict:
    """The weld's threshold on this run's hand motion while the part was held (from the plan's start to
    the loss): the hand term's ratio (the planners' limit; the co-simulation's finer grip for a cup) of a
    part moving rigidly with the hand, from the logged arm state and acceleration through sc.chain; its
    largest value and the first time it passed 1. For the magnet also `ring_grip`: the suction cup's
    contact-stability set (limits/suction.GripModel) of the magnet's own contact ring (its points, radius
    and friction, a pyramid of 8 edges) with the pull at the seat: the rigid-body hold condition of the
    contact model, normal force included, which the face-plane moment limit leaves out."""
    t = arm_log.sample_times() - CONTACT_SETTLE_S
    n = sc.n_dof
    x, a = arm_log.data(), acc_log.data()
    k = (t >= 0.0) & (t < (np.inf if lost_at_s is None else lost_at_s))
    state = sc.chain.evaluate(x[:n, k].T, x[n:, k].T, a[:, k].T)
    out = _over("threshold", np.max(sc.hand_term(grip).columns(state), axis=1), t[k])
    if spec is not None:
        ring = cached_grip(spec.contact_radius_m, pull_N, spec.friction, face_normal=sc.face_axis,
                           rim_points=spec.n_contact_points, pyramid_edges=8)
        out.update(_over("ring_grip", SuctionTerm(ring, sc.body, sc.gravity_m_s2).columns(state)[:, 0], t[k]))
    return out
