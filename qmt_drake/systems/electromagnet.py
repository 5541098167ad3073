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

How it enters the plant. `payload.add_payload` hangs the payload on the hand by a 6-DOF joint
(a QuaternionFloatingJoint from the hand frame H to the payload's face frame P), so the joint's
translation coordinates ARE p_HP [m], the face centre in the hand frame: gap = max(-z, 0),
slide d = |(x, y)|. A force along z_H on P at its origin, with the opposite force on H at the same
point, is exactly the generalized force of the joint's translational z velocity. The magnet is
therefore a function of three state coordinates and the current, giving one generalized-force
entry, and runs as Drake primitives (no Python per step):

    plant state --MatrixGain (picks x, y, z)--+
                                               Multiplexer -> SymbolicVectorSystem (pull, gap) -> ...
    coil_current -----------------------------+
        ... -> Demultiplexer -> attraction_force, gap; MatrixGain (pull -> joint z entry) -> generalized_force

`pull_N` is the one implementation of the formula: MagnetParams.force_N evaluates it on floats,
electromagnet_force on drake symbolic Expressions (compiled once, evaluated in C++).

Ports of electromagnet_force's Diagram
    inputs
        plant_state       (nq + nv,) MultibodyPlant.get_state_output_port() of the plant holding the joint
        coil_current      (1,) [A]
    outputs
        generalized_force (nv,) [N, N*m] to MultibodyPlant.get_applied_generalized_force_input_port()
        attraction_force  (1,) [N]   pull magnitude
        gap               (1,) [m]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake import symbolic
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, MatrixGain, Multiplexer

from qmt_drake.catalog import THESIS_COILS, CoilSpec  # noqa: F401 (re-exported)
from qmt_drake.errors import QmtInputError
from qmt_drake.systems.scalar_ops import FLOAT, SYMBOLIC, symbolic_law

MU0 = 4e-7 * math.pi




@dataclass(frozen=True)
class MagnetParams:
    coil: CoilSpec
    effective_gap_m: float
    payload_face_radius_m: float  # radius of the payload's attraction face (>= core radius)

    def force_N(self, current_A, gap_m=0.0, slide_m=0.0):
        """Pull [N] for current [A], gap [m] (negative: penetration, counts as 0) and sideways slide [m]."""
        return pull_N(self, float(current_A), max(float(gap_m), 0.0), abs(float(slide_m)))

    def current_for_force_A(self, force_N: float) -> float:
        """Inverse at zero gap and zero slide: the coil current [A] giving pull force_N [N]."""
        return math.sqrt(2.0 * force_N / (MU0 * self.coil.core_area_m2)) * self.effective_gap_m / self.coil.turns


def pull_N(params: MagnetParams, current_A, gap_m, slide_m, ops=FLOAT):
    """F(I, g, d) of the module docstring [N]: current [A], gap g >= 0 [m], slide d >= 0 [m], as
    floats or (ops=SYMBOLIC) drake symbolic Expressions (systems.scalar_ops)."""
    coil = params.coil
    full = MU0 * coil.core_area_m2 * (coil.turns * current_A) ** 2 / (2.0 * (gap_m + params.effective_gap_m) ** 2)
    return full * covered_fraction(slide_m, coil.core_diameter_m / 2, params.payload_face_radius_m, ops)


def covered_fraction(d, a: float, b: float, ops=FLOAT):
    """Fraction of a disc of radius a [m] covered by a disc of radius b [m] at centre distance d >= 0 [m]."""
    inside = 1.0 if b >= a else (b / a) ** 2

    def lens():  # circle-circle intersection area over pi a^2, for |b - a| < d < a + b
        ca = (d * d + a * a - b * b) / (2 * d * a)
        cb = (d * d + b * b - a * a) / (2 * d * b)
        area = (a * a * ops.acos(ops.clip(ca, -1.0, 1.0)) + b * b * ops.acos(ops.clip(cb, -1.0, 1.0))
                - 0.5 * ops.sqrt(ops.clip((-d + a + b) * (d + a - b) * (d - a + b) * (d + a + b), 0.0, math.inf)))
        return area / (math.pi * a * a)

    return ops.where(d <= abs(b - a), lambda: inside, lambda: ops.where(d >= a + b, lambda: 0.0, lens))


def payload_translation_indices(payload_joint) -> list[int]:
    """Indices of the joint's translation coordinates (x, y, z of p_HP [m]) in the plant's state."""
    if payload_joint.type_name() != "quaternion_floating":
        raise QmtInputError(f"the magnet needs the payload's 6-DOF joint to the hand (payload.add_payload); "
                         f"joint '{payload_joint.name()}' is a {payload_joint.type_name()} joint")
    start = payload_joint.position_start()
    return [start + 4, start + 5, start + 6]  # positions: quaternion (w, x, y, z), then translation


def electromagnet_force(params: MagnetParams, plant, payload_joint, *, host_has_continuous_state: bool = False):
    """The pull of the hand's electromagnet on the payload hanging on the hand by `payload_joint`, as
    a Diagram of Drake primitives (a plain Diagram, not a Python subclass: pydrake 1.51 never frees a
    diagram holding a Python-derived system); see the module docstring for the model, the wiring and
    the ports. Needs a finalised plant.

    host_has_continuous_state: pass True when the diagram this goes into has continuous state
    (see scalar_ops.symbolic_law: Drake 1.51 aborts otherwise)."""

    nq, nv = plant.num_positions(), plant.num_velocities()
    pick = np.zeros((3, nq + nv))
    pick[[0, 1, 2], payload_translation_indices(payload_joint)] = 1.0
    x, y, z, current = (symbolic.Variable(v) for v in ("x", "y", "z", "current"))
    gap = symbolic.if_then_else(z < 0.0, -z, 0.0)
    pull = pull_N(params, current, gap, symbolic.sqrt(x * x + y * y), SYMBOLIC)
    on_joint = np.zeros((nv, 1))
    on_joint[payload_joint.velocity_start() + 5, 0] = 1.0  # velocities: angular (3), then translational

    b = DiagramBuilder()
    select = b.AddNamedSystem("payload_translation", MatrixGain(pick))
    inputs = b.AddNamedSystem("inputs", Multiplexer([3, 1]))
    law = b.AddNamedSystem("pull_law", symbolic_law([x, y, z, current], [pull, gap],
                                                     host_has_continuous_state=host_has_continuous_state))
    split = b.AddNamedSystem("pull_and_gap", Demultiplexer(2, 1))
    to_joint = b.AddNamedSystem("on_joint", MatrixGain(on_joint))
    b.Connect(select.get_output_port(), inputs.get_input_port(0))
    b.Connect(inputs.get_output_port(), law.get_input_port())
    b.Connect(law.get_output_port(), split.get_input_port())
    b.Connect(split.get_output_port(0), to_joint.get_input_port())
    b.ExportInput(select.get_input_port(), "plant_state")
    b.ExportInput(inputs.get_input_port(1), "coil_current")
    b.ExportOutput(to_joint.get_output_port(), "generalized_force")
    b.ExportOutput(split.get_output_port(0), "attraction_force")
    b.ExportOutput(split.get_output_port(1), "gap")
    diagram = b.Build()
    diagram.set_name("magnet")
    return diagram
