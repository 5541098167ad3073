"""The unfixed object on the tray (seed 002): a PET bottle resting on a tray under friction only.

Not a LeafSystem except the monitor: `add_tray_contact` and `add_bottle` add to a MultibodyPlant
(before Finalize)
  * on the tray body: a box whose upper face is the tray surface (tray frame z = 0, normal +z);
  * the bottle: a free rigid body, frame B at the centre of its base, z_B along its axis; centre
    of mass at (0, 0, h_G) in B;
  * contact: a ring of `n_contact_points` small spheres on the bottle's base at radius
    `contact_radius_m`, their bottoms in the base plane, against the tray box; point contact with
    Hunt-Crossley dissipation and Coulomb friction mu (Drake's discrete SAP solver, lagged).

Why point contacts on a ring, not hydroelastic: a PET bottle stands on the ring of its petaloid
feet, not on a flat face, so a ring is the real support; a ring makes the tipping edge exact (the
bottle rocks about the ring's edge, the zero-moment point leaves the base at the ring radius) and
Coulomb sliding exact per contact; and it is cheap (16 point pairs vs a hydroelastic
pressure-field surface every step). Hydroelastic would add a distributed pressure that a nearly
rigid PET foot does not have.

The bottle (seed 002 section 7: "a PET bottle with water adjusted to 50 g in all"; no size
given). ASSUMED: a 500 mL PET bottle, 65 mm diameter, 205 mm tall, 20 g empty (shell, treated as
a thin-walled cylinder) with 30 g water (a 9 mm layer at the bottom); the feet ring at 29 mm
radius. Centre of mass 43.7 mm above the base (`BottleSpec.pet_500ml`). PET on a plastic tray,
dry: mu = 0.3 (assumed; swept in the study).

TrayBottleMonitor (a LeafSystem, no state) reads body poses and contact results and reports in
the tray frame T:
    outputs
        slide          (2,) [m]   base centre's displacement in the tray plane from its seat
        tilt           (1,) [rad] angle between z_B and z_T
        base_height    (1,) [m]   base centre's height above the tray surface (lift-off)
        contact_force  (3,) [N]   total force of the tray on the bottle in T (x, y tangential, z normal)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from pydrake.geometry import AddContactMaterial, Box, Cylinder, ProximityProperties, Sphere
from pydrake.math import RigidTransform
from pydrake.multibody.plant import CoulombFriction
from pydrake.multibody.tree import QuaternionFloatingJoint, RotationalInertia, SpatialInertia
from pydrake.systems.framework import LeafSystem

from qmt_drake.errors import QmtInputError

WATER_DENSITY_KG_M3 = 1000.0
TRAY_SIZE_M = (0.24, 0.16, 0.005)  # same as models/generate_crane_x7.py (visual); assumption


@dataclass(frozen=True)
class BottleSpec:
    """Bottle and contact parameters (SI)."""

    name: str
    mass_kg: float
    radius_m: float
    height_m: float
    com_height_m: float
    shell_mass_kg: float
    contact_radius_m: float
    friction: float = 0.3
    n_contact_points: int = 16
    sphere_radius_m: float = 1.0e-3
    # Per point, in series with the tray's (same value): 1e5 N/m per pair; the bottle's weight
    # sinks the ring by 0.49 N / (16 x 1e5 N/m) = 0.3 um.
    point_stiffness_N_per_m: float = 2.0e5
    hunt_crossley_dissipation_s_per_m: float = 20.0

    def __post_init__(self) -> None:
        if not self.friction >= 0:
            raise QmtInputError(f"bottle friction coefficient {self.friction} must be >= 0 "
                                "(dry PET on plastic: ~0.2-0.5)")
        if not (self.mass_kg > 0 and self.radius_m > 0 and self.height_m > 0):
            raise QmtInputError("bottle mass, radius and height must be positive")
        if not 0 < self.contact_radius_m <= self.radius_m:
            raise QmtInputError(f"bottle contact ring radius {self.contact_radius_m} m must be in (0, radius "
                                f"{self.radius_m} m]")
        if not 0 < self.com_height_m < self.height_m:
            raise QmtInputError(f"bottle centre of mass height {self.com_height_m} m must lie inside the bottle "
                                f"(0, {self.height_m}) m")

    @classmethod
    def pet_500ml(cls, mass_kg: float = 0.050, shell_mass_kg: float = 0.020, **kw) -> BottleSpec:
        """The assumed bottle; the water is what remains of mass_kg after the shell."""
        r, height = 0.0325, 0.205
        water = mass_kg - shell_mass_kg
        if water < 0:
            raise QmtInputError(f"bottle mass {mass_kg} kg is less than its empty shell {shell_mass_kg} kg")
        fill = water / (WATER_DENSITY_KG_M3 * math.pi * r * r)
        com = (shell_mass_kg * height / 2 + water * fill / 2) / mass_kg
        return cls("PET bottle 500 mL", mass_kg, r, height, com, shell_mass_kg, 0.029, **kw)

    def with_com_height(self, com_height_m: float) -> BottleSpec:
        return replace(self, com_height_m=com_height_m)

    @property
    def tip_ratio(self) -> float:
        """r_c / h_G: the tray acceleration over g (quasi-static, level tray) at which it tips."""
        return self.contact_radius_m / self.com_height_m

    def check_rests(self, tray_tilt_rad: float) -> None:
        """One-line QmtInputError if the bottle tips or slides at rest on a tray tilted by tray_tilt_rad."""
        t = abs(math.tan(tray_tilt_rad))
        if t >= self.tip_ratio:
            raise QmtInputError(f"bottle centre of mass {self.com_height_m:.3g} m above its base tips over at rest "
                                f"on a tray tilted {math.degrees(tray_tilt_rad):.2f} deg (limit "
                                f"{self.contact_radius_m / t:.3g} m); lower it or level the tray")
        if t >= self.friction:
            raise QmtInputError(f"bottle friction {self.friction} slides at rest on a tray tilted "
                                f"{math.degrees(tray_tilt_rad):.2f} deg; use mu > {t:.3g}")

    def spatial_inertia(self) -> SpatialInertia:
        """Thin-walled cylindrical shell + a water disc at the bottom, about B's origin."""
        r, H, m_s = self.radius_m, self.height_m, self.shell_mass_kg
        m_w = self.mass_kg - m_s
        fill = m_w / (WATER_DENSITY_KG_M3 * math.pi * r * r) if m_w > 0 else 0.0
        hg = self.com_height_m
        # about the combined COM (this com_height may be overridden for sweeps: inertia stays the shell's)
        ixx = (m_s * (r * r / 2 + H * H / 12) + m_s * (H / 2 - hg) ** 2
               + m_w * (3 * r * r + fill * fill) / 12 + m_w * (fill / 2 - hg) ** 2)
        izz = m_s * r * r + m_w * r * r / 2
        return SpatialInertia.MakeFromCentralInertia(self.mass_kg, np.array([0.0, 0.0, hg]),
                                                     RotationalInertia(ixx, ixx, izz))


def _proximity(spec: BottleSpec) -> ProximityProperties:
    props = ProximityProperties()
    AddContactMaterial(dissipation=spec.hunt_crossley_dissipation_s_per_m, point_stiffness=spec.point_stiffness_N_per_m,
                       friction=CoulombFriction(spec.friction, spec.friction), properties=props)
    return props


def add_tray_contact(plant, tray_body, spec: BottleSpec, size_m=TRAY_SIZE_M, *, visual: bool = False) -> None:
    """The tray's collision box: upper face at tray frame z = 0; with visual, the same box drawn (a
    tray body with no visual of its own, e.g. the spatial tray hand's; the CRANE-X7's URDF has one)."""
    a, b, c = size_m
    X = RigidTransform([0.0, 0.0, -c / 2])
    plant.RegisterCollisionGeometry(tray_body, X, Box(a, b, c), "tray_surface", _proximity(spec))
    if visual:
        plant.RegisterVisualGeometry(tray_body, X, Box(a, b, c), "tray_visual", np.array([0.55, 0.55, 0.6, 1.0]))


def add_bottle(plant, spec: BottleSpec, name: str = "bottle", *, tray_body=None):
    """The bottle, free to move, with its contact ring and a visual; returns the RigidBody. With
    tray_body its six degrees of freedom are a QuaternionFloatingJoint from the tray frame T
    ("<name>_on_tray"): its coordinates are its pose on the tray, so a bottle at rest on a moving
    tray is at rest in them and the first-order discrete step adds no drift to its slide (see
    systems/payload.py, which measured it for the magnet hand's part); without, it floats in the
    world frame (a tray welded to the world, as in tests/test_tray_object.py, is the same)."""
    instance = plant.AddModelInstance(name)
    body = plant.AddRigidBody(name, instance, spec.spatial_inertia())
    if tray_body is not None:
        plant.AddJoint(QuaternionFloatingJoint(f"{name}_on_tray", tray_body.body_frame(), body.body_frame()))
    props = _proximity(spec)
    for k in range(spec.n_contact_points):
        a = 2.0 * math.pi * k / spec.n_contact_points
        p = [spec.contact_radius_m * math.cos(a), spec.contact_radius_m * math.sin(a), spec.sphere_radius_m]
        plant.RegisterCollisionGeometry(body, RigidTransform(p), Sphere(spec.sphere_radius_m), f"{name}_foot_{k}",
                                        props)
    plant.RegisterVisualGeometry(body, RigidTransform([0, 0, spec.height_m / 2]),
                                 Cylinder(spec.radius_m, spec.height_m), f"{name}_visual",
                                 np.array([0.6, 0.8, 0.95, 0.6]))
    return body


def seated_pose_on_tray(offset_xy=(0.0, 0.0)) -> RigidTransform:
    """X_TB of the bottle standing at offset_xy [m] on the tray surface (feet touching)."""
    return RigidTransform([float(offset_xy[0]), float(offset_xy[1]), 0.0])


class TrayBottleMonitor(LeafSystem):
    """Slide, tilt, lift-off and contact force of the bottle in the tray frame; see the module docstring."""

    def __init__(self, plant, tray_body, bottle_body, X_TB0: RigidTransform):
        super().__init__()
        self._tray_index = int(tray_body.index())
        self._bottle_index = int(bottle_body.index())
        self._p_T_seat = np.asarray(X_TB0.translation())
        self._tray_body, self._bottle_body = tray_body.index(), bottle_body.index()
        self._poses = self.DeclareAbstractInputPort("body_poses", plant.get_body_poses_output_port().Allocate())
        self._contacts = self.DeclareAbstractInputPort("contact_results",
                                                       plant.get_contact_results_output_port().Allocate())
        self.DeclareVectorOutputPort("slide", 2, lambda c, o: o.SetFromVector(self._X_TB(c).translation()[:2]
                                                                             - self._p_T_seat[:2]))
        self.DeclareVectorOutputPort("tilt", 1, lambda c, o: o.SetFromVector([self._tilt(c)]))
        self.DeclareVectorOutputPort("base_height", 1, lambda c, o: o.SetFromVector([self._X_TB(c).translation()[2]]))
        self.DeclareVectorOutputPort("contact_force", 3, self._force)

    def _X_TB(self, context) -> RigidTransform:
        poses = self._poses.Eval(context)
        return poses[self._tray_index].InvertAndCompose(poses[self._bottle_index])

    def _tilt(self, context) -> float:
        z = self._X_TB(context).rotation().matrix()[:, 2]
        return math.atan2(math.hypot(z[0], z[1]), z[2])  # acos(z[2]) loses half the digits near 0

    def _force(self, context, output) -> None:
        results = self._contacts.Eval(context)
        f_W = np.zeros(3)
        for k in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(k)
            # contact_force() acts on body B of the pair
            if info.bodyB_index() == self._bottle_body and info.bodyA_index() == self._tray_body:
                f_W += info.contact_force()
            elif info.bodyA_index() == self._bottle_body and info.bodyB_index() == self._tray_body:
                f_W -= info.contact_force()
        R_WT = self._poses.Eval(context)[self._tray_index].rotation()
        output.SetFromVector(R_WT.inverse().multiply(f_W))
