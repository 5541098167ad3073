"""The contact hand's build (sim/spatial_contact_hand.py's ContactHand adds it to the plant): bodies,
geometry, contact material and pull.

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
"""

from __future__ import annotations

import math

import numpy as np
from pydrake import symbolic
from pydrake.geometry import AddContactMaterial, Box, ProximityProperties, SceneGraph, Sphere
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import CoulombFriction
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    QuaternionFloatingJoint,
    RotationalInertia,
    SpatialInertia,
)
from pydrake.systems.primitives import ConstantVectorSource, MatrixGain

from qmt_drake.catalog import THESIS_COILS
from qmt_drake.limits.contact_wrench import face_basis
from qmt_drake.sim.magnet_hand import MAGNET_EFFECTIVE_GAP_M, hold_lever_m
from qmt_drake.systems.electromagnet import MagnetParams, electromagnet_force
from qmt_drake.systems.payload import PayloadSpec
from qmt_drake.systems.scalar_ops import symbolic_law

MAGNET_COIL = "table_3_2"  # the thesis's chapter-3 coil (156 turns): the UR5 magnet task's moment limit is ch.3's
# suction rim (chosen, stated): a cup lip of 1e5 N/m over the whole rim, lightly damped (Hunt-Crossley)
RIM_STIFFNESS_N_PER_M = 1.0e5
RIM_DISSIPATION_S_PER_M = 20.0
RIM_SPHERE_RADIUS_M = 1.0e-3
PART_FACE_HALF_M = 0.05  # the suction part's flat face (a box 100 mm square under the cup)
SEAL_GAP_M = 2.0e-3  # the vacuum holds while the part's face is within this of the cup at its centre


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


def add_pull(builder, plant, joint, spec, grip, current_A: float | None, continuous: bool) -> None:
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
