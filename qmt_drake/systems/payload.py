"""The carried part: a rigid body free to move against the hand's attraction face, in friction contact.

Not a LeafSystem: `add_payload` adds to a MultibodyPlant (before Finalize)
  * on the hand body: a thin box whose lower face is the hand's attraction face (hand frame z = 0,
    face normal -z), the contact partner;
  * the payload: a rigid body whose frame P has its origin at the centre of the payload's
    attraction face, z_P pointing out of the face (towards the hand when seated); its centre of mass
    sits r_G below the face, at (0, 0, -r_G) in P;
  * its six degrees of freedom: a QuaternionFloatingJoint from the hand frame H to P (named
    "<name>_on_hand", `payload_joint`), so the part's generalized coordinates are its pose in the
    hand frame (quaternion, then p_HP [m]) and its velocities w_HP, v_HP expressed in H. Nothing
    constrains it: it slides, tips and falls away as a free body would. Two reasons for relative
    coordinates: a seated part is at rest in them, so the first-order discrete step no longer
    shows as a slip drift (with the part floating in the world frame the held ch.4 move "slipped"
    0.67 mm at 2 ms and 0.35 mm at 1 ms, in proportion to the step; relative: 0.035 mm at every
    step from 2 to 0.25 ms, which is the part's real creep); and the magnet's pull becomes a
    generalized force on the joint computed by Drake primitives (`electromagnet.electromagnet_force`).
    The hand and the part still collide: Drake filters collisions between the bodies of a joint,
    but not across a floating joint, and `allow_contact` declares the pair explicitly after
    Finalize (tests/test_systems_payload.py checks it). attach_to_hand=False adds a body floating
    in the world instead (the benchmark's floor of the previous plant; no magnet system for it);
  * contact: `n_contact_points` small spheres whose tops lie in the payload's face plane, on a ring
    of radius `contact_radius_m` (the core end's radius: the part touches the core only), so the part
    can slide along the face and tip about the ring's edge. Point contact with per-geometry stiffness
    and Hunt-Crossley dissipation (NOTES.md: discrete plant, kLagged, spheres at the face corners).

Needs: a plant with point contact and the lagged discrete approximation
(`sim.plant.transfer_plant_config`; the contact stiffness below was chosen for it), and the payload
seated at the start (`sim.plant.finalize_transfer_plant` makes that the plant's default state).

Payload shapes come from the scenario (payload.body; hand for the contact data), never from
its mass. Those of the built-in scenarios (seed 000): chapter 2 carries a steel M8 bolt, 40 mm long, 22 g, head on the face
(Fig. 2.5); chapters 3-4 a 30 g steel part (Fig. 3.4, no dimensions printed), modelled as a steel
cylinder whose length is 2 r_G (r_G = 28 mm, Table 4.1) and whose radius follows from its mass.
The mass and r_G always come from the scenario; the shape only sets the rotational inertia and
the visual.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (
    AddContactMaterial,
    Box,
    CollisionFilterDeclaration,
    Cylinder,
    GeometrySet,
    ProximityProperties,
    Sphere,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import CoulombFriction
from pydrake.multibody.tree import QuaternionFloatingJoint, SpatialInertia, UnitInertia

from qmt_drake.catalog import STEEL_DENSITY_KG_M3
from qmt_drake.errors import QmtInputError


@dataclass(frozen=True)
class PayloadSpec:
    """Payload and contact parameters (SI)."""

    name: str
    mass_kg: float
    com_offset_m: float  # r_G: attraction face -> centre of mass
    length_m: float  # along z_P, for inertia and visual
    radius_m: float  # body radius, for inertia and visual
    face_radius_m: float  # radius of the payload's attraction face (bolt head / part end)
    contact_radius_m: float = 3.9e-3  # ring of contact points: the core end (d = 7.8 mm)
    n_contact_points: int = 8
    sphere_radius_m: float = 0.5e-3
    friction: float = 0.3  # steel on iron, dry, dynamic (handbook range 0.3-0.6; lower end)
    # Per sphere; the hand face has the same, in series (5e5 N/m per contact). Stiff on purpose: the
    # net normal force is only a few percent of the pull (ch.2: 8 mN of 224 mN), so a compliant ring
    # rocks, opens the gap at the face centre by micrometres and loses the pull. In the bench test
    # (tests/test_systems_payload.py) 2e4 N/m held only to 0.6-0.9 of the rigid-body hold limit;
    # 2e5 and 1e6 hold to within 5% of it.
    point_stiffness_N_per_m: float = 1.0e6
    hunt_crossley_dissipation_s_per_m: float = 5.0

    @classmethod
    def m8_bolt(cls, mass_kg: float = 0.022, com_offset_m: float = 0.0151, **kw) -> PayloadSpec:
        # M8 x 40 hexagon bolt, head (13 mm across flats, 5.3 mm) against the face.
        return cls("M8x40 bolt", mass_kg, com_offset_m, length_m=0.0453, radius_m=0.004, face_radius_m=6.5e-3,
                   **kw)

    @classmethod
    def steel_cylinder(cls, mass_kg: float = 0.030, com_offset_m: float = 0.028, **kw) -> PayloadSpec:
        length = 2.0 * com_offset_m
        radius = math.sqrt(mass_kg / (STEEL_DENSITY_KG_M3 * math.pi * length))
        return cls("steel part", mass_kg, com_offset_m, length_m=length, radius_m=radius, face_radius_m=radius,
                   **kw)

    @classmethod
    def for_scenario(cls, scenario, **kw) -> PayloadSpec:
        """From the scenario's typed data: mass, r_G and body (payload section), friction and the
        contact ring (hand section, if any; else this class's defaults). kw overrides any field."""
        p = scenario.payload
        body = p.body
        if body is None:
            raise QmtInputError(f"scenario '{scenario.name}' payload has no body; load it with load_scenario")
        contact = {}
        hand = getattr(scenario, "hand", None)
        if hand is not None:
            contact = {k: getattr(hand, k) for k in (
                "contact_radius_m", "n_contact_points", "sphere_radius_m", "friction",
                "point_stiffness_N_per_m", "hunt_crossley_dissipation_s_per_m")}
        contact.update(kw)
        return cls(body.name, float(p.mass_kg), float(p.com_offset_m), length_m=body.length_m,
                   radius_m=body.radius_m, face_radius_m=body.face_radius_m, **contact)

    def spatial_inertia_about_origin(self) -> SpatialInertia:
        """Solid cylinder of the spec's length and radius, centred on the COM at (0,0,-r_G) in P."""
        unit = UnitInertia.SolidCylinder(self.radius_m, self.length_m, [0.0, 0.0, 1.0])
        return SpatialInertia.MakeFromCentralInertia(
            self.mass_kg, np.array([0.0, 0.0, -self.com_offset_m]), unit * self.mass_kg)


def _proximity(spec: PayloadSpec) -> ProximityProperties:
    props = ProximityProperties()
    AddContactMaterial(dissipation=spec.hunt_crossley_dissipation_s_per_m,
                       point_stiffness=spec.point_stiffness_N_per_m,
                       friction=CoulombFriction(spec.friction, spec.friction), properties=props)
    return props


def add_payload(plant, spec: PayloadSpec, hand_body, *, name: str = "payload", model_instance=None,
                attach_to_hand: bool = True):
    """Add the hand's face geometry and the payload body on its 6-DOF joint to the hand (module
    docstring; attach_to_hand=False: floating in the world); returns the payload RigidBody.

    The seated pose of the payload in the hand frame is the identity (`seated_pose_in_hand`), the
    joint's default pose."""
    if model_instance is None:
        model_instance = plant.AddModelInstance(name)
    props = _proximity(spec)
    face_half = 8.0e-3
    face_h = 4.0e-3
    plant.RegisterCollisionGeometry(hand_body, RigidTransform([0.0, 0.0, face_h / 2]),
                                    Box(2 * face_half, 2 * face_half, face_h), "hand_face", props)
    body = plant.AddRigidBody(name, model_instance, spec.spatial_inertia_about_origin())
    for k in range(spec.n_contact_points):
        a = 2.0 * math.pi * k / spec.n_contact_points
        p = [spec.contact_radius_m * math.cos(a), spec.contact_radius_m * math.sin(a), -spec.sphere_radius_m]
        plant.RegisterCollisionGeometry(body, RigidTransform(p), Sphere(spec.sphere_radius_m),
                                        f"{name}_contact_{k}", props)
    plant.RegisterVisualGeometry(body, RigidTransform([0.0, 0.0, -spec.length_m / 2]),
                                 Cylinder(spec.radius_m, spec.length_m), f"{name}_visual",
                                 np.array([0.55, 0.55, 0.6, 1.0]))
    if attach_to_hand:
        plant.AddJoint(QuaternionFloatingJoint(f"{name}_on_hand", hand_body.body_frame(), body.body_frame()))
    return body


def six_dof_joint_of(plant, body):
    """The QuaternionFloatingJoint that connects `body` to another body (not the world); ValueError if none."""
    for index in plant.GetJointIndices(body.model_instance()):
        joint = plant.get_joint(index)
        if joint.child_body().index() == body.index() and joint.type_name() == "quaternion_floating" \
                and joint.parent_body().index() != plant.world_body().index():
            return joint
    raise QmtInputError(f"body '{body.name()}' has no 6-DOF joint to a carrying body; add it with "
                     "add_payload(..., attach_to_hand=True) (add_bottle(..., tray_body=tray))")


def payload_joint(plant, payload_body):
    """The payload's 6-DOF joint to the hand (`add_payload`); ValueError if it has none."""
    return six_dof_joint_of(plant, payload_body)


def allow_contact(plant, scene_graph, body_a, body_b) -> None:
    """After Finalize: make sure the two bodies' collision geometries may collide (Drake's filter
    between a joint's bodies must not hide the contact of a carried part with its carrier)."""
    a = GeometrySet(plant.GetCollisionGeometriesForBody(body_a))
    b = GeometrySet(plant.GetCollisionGeometriesForBody(body_b))
    scene_graph.collision_filter_manager().Apply(CollisionFilterDeclaration().AllowBetween(a, b))


def seated_pose_in_hand() -> RigidTransform:
    """X_HP of a payload seated centred on the face (sphere tops in the face plane)."""
    return RigidTransform()
