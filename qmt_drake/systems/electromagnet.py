"""Electromagnetic attraction hand: coil current -> pull on the payload, reaction on the hand.

Model (lumped magnetic circuit of an iron-cored coil facing an iron part; Maxwell pull)

    F(I, g, d) = mu0 * A_core * (n_turns * I)^2 / (2 * (g + g0)^2) * overlap(d)        [N]

    A_core   cross-section of the iron core, pi * d_core^2 / 4 [m^2] (core d = coil inner d,
             7.8 mm in both thesis hands, Tables 2.2 and 3.2)
    n_turns  coil turns (420 in Table 2.2, 156 in Table 3.2); I coil current [A]
    g        gap [m]: distance of the payload's attraction-face centre from the hand's face plane,
             measured along the hand's face normal (>= 0; penetration counts as 0)
    g0       equivalent gap [m] lumping the reluctance of the core, the open return path through
             air and the surface roughness, referred to the core area (an assumption, the same for
             both hands; the scenario's hand.effective_gap_m)
    overlap  fraction of the core's end face still covered by the payload's face (a disc of radius
             b >= core radius a) whose centre has slid a distance d along the face: 1 while
             d <= b - a, then the circle-circle intersection area over pi a^2

The pull acts at the payload's attraction-face centre along the hand's face normal (towards the
hand); the equal and opposite force acts on the hand body at the same point.

Needs: body_poses from the same MultibodyPlant that holds the hand and payload bodies whose
indices it was built with, and its spatial_forces connected to that plant's
applied_spatial_force input (`sim.magnet_hand.add_magnet_hand` does both). The plant's default
state should have the payload seated (`sim.plant.finalize_transfer_plant`).

Ports
    inputs
        body_poses       abstract, MultibodyPlant.get_body_poses_output_port()
        coil_current     (1,) [A]
    outputs
        spatial_forces   abstract list[ExternallyAppliedSpatialForce] (payload and hand), to
                         MultibodyPlant.get_applied_spatial_force_input_port()
        attraction_force (1,) [N]   pull magnitude
        gap              (1,) [m]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.framework import BasicVector, LeafSystem

MU0 = 4e-7 * math.pi


@dataclass(frozen=True)
class CoilSpec:
    """A thesis hand's coil (SI)."""

    name: str
    turns: int
    resistance_ohm: float
    core_diameter_m: float
    outer_diameter_m: float
    length_m: float

    @property
    def core_area_m2(self) -> float:
        return math.pi * self.core_diameter_m**2 / 4


THESIS_COILS = {
    "table_2_2": CoilSpec("seed 000 Table 2.2 (ch.2 hand)", 420, 2.7, 7.8e-3, 16.5e-3, 20.0e-3),
    "table_3_2": CoilSpec("seed 000 Table 3.2 (ch.3-4 hand)", 156, 1.7, 7.8e-3, 11.35e-3, 20.0e-3),
}


@dataclass(frozen=True)
class MagnetParams:
    coil: CoilSpec
    effective_gap_m: float
    payload_face_radius_m: float  # radius of the payload's attraction face (>= core radius)

    def force_N(self, current_A, gap_m=0.0, slide_m=0.0):
        """Pull [N] for current [A], gap [m] and sideways slide [m] (scalars)."""
        g = max(float(gap_m), 0.0)
        base = MU0 * self.coil.core_area_m2 * (self.coil.turns * float(current_A)) ** 2 / (
            2.0 * (g + self.effective_gap_m) ** 2)
        return base * covered_fraction(slide_m, self.coil.core_diameter_m / 2, self.payload_face_radius_m)

    def current_for_force_A(self, force_N: float) -> float:
        """Inverse at zero gap and zero slide: the coil current [A] giving pull force_N [N]."""
        return math.sqrt(2.0 * force_N / (MU0 * self.coil.core_area_m2)) * self.effective_gap_m / self.coil.turns


def covered_fraction(d: float, a: float, b: float) -> float:
    """Fraction of a disc of radius a [m] covered by a disc of radius b [m] at centre distance d [m]."""
    d = abs(float(d))
    if d <= abs(b - a):
        return 1.0 if b >= a else (b / a) ** 2
    if d >= a + b:
        return 0.0
    ca = (d * d + a * a - b * b) / (2 * d * a)
    cb = (d * d + b * b - a * a) / (2 * d * b)
    area = (a * a * math.acos(max(-1.0, min(1.0, ca))) + b * b * math.acos(max(-1.0, min(1.0, cb)))
            - 0.5 * math.sqrt(max(0.0, (-d + a + b) * (d + a - b) * (d - a + b) * (d + a + b))))
    return area / (math.pi * a * a)


class ElectromagnetForce(LeafSystem):
    """Pull of the hand's electromagnet on the payload; see module docstring for model and ports."""

    def __init__(self, params: MagnetParams, hand_body_index, payload_body_index):
        super().__init__()
        self.params = params
        self._hand_i = int(hand_body_index)
        self._payload_i = int(payload_body_index)
        coil = params.coil
        self._k = MU0 * coil.core_area_m2 * coil.turns**2 / 2.0  # F = k I^2 / (g + g0)^2 at full overlap
        self._g0 = params.effective_gap_m
        self._a = coil.core_diameter_m / 2
        self._b = params.payload_face_radius_m
        self._zero3 = np.zeros(3)
        self._on_payload = ExternallyAppliedSpatialForce()
        self._on_payload.body_index = payload_body_index
        self._on_payload.p_BoBq_B = np.zeros(3)
        self._on_hand = ExternallyAppliedSpatialForce()
        self._on_hand.body_index = hand_body_index
        self._pair = [self._on_payload, self._on_hand]
        self._poses_in = self.DeclareAbstractInputPort("body_poses", AbstractValue.Make([RigidTransform()]))
        self._i_in = self.DeclareVectorInputPort("coil_current", 1)
        self.DeclareAbstractOutputPort("spatial_forces", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
                                       self._calc_forces)
        self.DeclareVectorOutputPort("attraction_force", 1, self._calc_force_magnitude)
        self.DeclareVectorOutputPort("gap", 1, self._calc_gap)

    def _geometry(self, context):
        """Payload face centre in the hand frame p_HP [m] (3 floats), hand face normal in world
        z_WH (3 floats), pull [N], gap [m]."""
        poses = self._poses_in.Eval(context)
        X_WH = poses[self._hand_i]
        x, y, z = X_WH.InvertAndCompose(poses[self._payload_i]).translation().tolist()
        gap = -z if z < 0.0 else 0.0
        slide = math.hypot(x, y)
        i = float(self._i_in.Eval(context)[0])
        f = self._k * i * i / (gap + self._g0) ** 2
        if slide > self._b - self._a:
            f *= covered_fraction(slide, self._a, self._b)
        return (x, y, z), X_WH.rotation().col(2), f, gap

    def _calc_forces(self, context, output):
        p_HP, z_WH, f, _ = self._geometry(context)
        fz = f * z_WH
        self._on_payload.F_Bq_W = SpatialForce(self._zero3, fz)
        self._on_hand.p_BoBq_B = p_HP
        self._on_hand.F_Bq_W = SpatialForce(self._zero3, -fz)
        output.set_value(self._pair)

    def _calc_force_magnitude(self, context, output: BasicVector):
        output.SetAtIndex(0, self._geometry(context)[2])

    def _calc_gap(self, context, output: BasicVector):
        output.SetAtIndex(0, self._geometry(context)[3])
