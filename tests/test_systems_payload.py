"""The payload in friction contact with the magnet face: its inertia, and a bench test of the hold
limit against the rigid-body closed form (F - m g) * min(rho, mu r_G) under a slowly ramped
sideways load, with the hand welded to the world."""

import math

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import AddMultibodyPlant, ExternallyAppliedSpatialForce, MultibodyPlantConfig
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2 as GRAVITY_M_S2
from qmt_drake.sim import hold_lever_m
from qmt_drake.systems.electromagnet import THESIS_COILS, MagnetParams, electromagnet_force
from qmt_drake.systems.payload import (
    STEEL_DENSITY_KG_M3,
    PayloadSpec,
    add_payload,
    allow_contact,
    payload_joint,
)
from qmt_drake.systems.transfer_monitor import motion_from_joint, relative_payload_motion


def test_inertia_and_shape():
    p = PayloadSpec.steel_cylinder(0.030, 0.028)
    assert p.length_m == pytest.approx(0.056)
    assert STEEL_DENSITY_KG_M3 * math.pi * p.radius_m**2 * p.length_m == pytest.approx(0.030)
    M = p.spatial_inertia_about_origin()
    assert M.get_mass() == pytest.approx(0.030)
    np.testing.assert_allclose(M.get_com(), [0, 0, -0.028])
    bolt = PayloadSpec.m8_bolt(0.022, 0.016)
    assert bolt.face_radius_m > bolt.contact_radius_m  # the head covers the 7.8 mm core


class _SidewaysRamp(LeafSystem):
    """A force -m*a(t) x_W at the payload's COM, a(t) ramping to a_max over ramp_s."""

    def __init__(self, body_index, mass, com_offset, a_max, ramp_s):
        super().__init__()
        self.DeclareAbstractOutputPort("out", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]),
                                       self._calc)
        self._f = ExternallyAppliedSpatialForce()
        self._f.body_index = body_index
        self._f.p_BoBq_B = np.array([0.0, 0.0, -com_offset])
        self._m, self._a, self._T = mass, a_max, ramp_s

    def _calc(self, context, output):
        a = self._a * min(1.0, context.get_time() / self._T)
        self._f.F_Bq_W = SpatialForce(np.zeros(3), np.array([-self._m * a, 0.0, 0.0]))
        output.set_value([self._f])


def _bench(spec, coil, current, a_max, g0=0.5e-3):
    b = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(
        time_step=1e-3, discrete_contact_approximation="lagged", contact_model="point",
        use_sampled_output_ports=False), b)
    hand = plant.AddRigidBody("hand", plant.AddModelInstance("bench"), SpatialInertia.SolidSphereWithMass(1.0, 0.01))
    plant.WeldFrames(plant.world_frame(), hand.body_frame())
    payload = add_payload(plant, spec, hand)
    plant.Finalize()
    allow_contact(plant, scene_graph, hand, payload)
    magnet = b.AddSystem(electromagnet_force(MagnetParams(coil, g0, spec.face_radius_m), plant,
                                            payload_joint(plant, payload)))
    src = b.AddSystem(ConstantVectorSource([current]))
    ramp = b.AddSystem(_SidewaysRamp(payload.index(), spec.mass_kg, spec.com_offset_m, a_max, 1.0))
    b.Connect(src.get_output_port(), magnet.GetInputPort("coil_current"))
    b.Connect(plant.get_state_output_port(), magnet.GetInputPort("plant_state"))
    b.Connect(magnet.GetOutputPort("generalized_force"), plant.get_applied_generalized_force_input_port())
    b.Connect(ramp.get_output_port(), plant.get_applied_spatial_force_input_port())
    sim = Simulator(b.Build())  # the joint's default pose: seated
    pc = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
    sim.AdvanceTo(1.5)
    X_WP = plant.EvalBodyPoseInWorld(pc, payload)
    slip, tilt, gap = relative_payload_motion(RigidTransform(), X_WP, RigidTransform())
    return slip < 1e-3 and gap < 1e-3


def test_the_payload_hangs_on_the_hand_by_a_joint_and_still_touches_it():
    """Its coordinates are its pose in the hand frame, and the face contact is not filtered out."""
    b = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlant(MultibodyPlantConfig(time_step=1e-3, contact_model="point"), b)
    hand = plant.AddRigidBody("hand", plant.AddModelInstance("bench"), SpatialInertia.SolidSphereWithMass(1.0, 0.01))
    plant.WeldFrames(plant.world_frame(), hand.body_frame(), RigidTransform([0.1, 0.2, 0.3]))
    payload = add_payload(plant, PayloadSpec.m8_bolt(), hand)
    plant.Finalize()
    allow_contact(plant, scene_graph, hand, payload)
    joint = payload_joint(plant, payload)
    assert joint.parent_body().index() == hand.index() and joint.num_velocities() == 6
    ctx = plant.CreateDefaultContext()
    X_HP = RigidTransform([1e-3, -2e-3, -3e-3])
    joint.SetPose(ctx, X_HP)
    X_WP = plant.EvalBodyPoseInWorld(ctx, payload)
    np.testing.assert_allclose(X_WP.translation(), [0.101, 0.198, 0.297], atol=1e-15)
    X_HP = RigidTransform(RollPitchYaw(0.02, -0.01, 0.3), [1e-3, -2e-3, -3e-3])
    joint.SetPose(ctx, X_HP)
    slip, tilt, gap = motion_from_joint(plant.GetPositions(ctx, payload.model_instance()))
    expected = relative_payload_motion(plant.EvalBodyPoseInWorld(ctx, hand), plant.EvalBodyPoseInWorld(ctx, payload),
                                       RigidTransform())
    np.testing.assert_allclose([slip, tilt, gap], expected, rtol=1e-12, atol=1e-17)
    inspector = scene_graph.model_inspector()
    for g_hand in plant.GetCollisionGeometriesForBody(hand):
        for g_part in plant.GetCollisionGeometriesForBody(payload):
            assert not inspector.CollisionFiltered(g_hand, g_part)


@pytest.mark.parametrize("spec, coil, hold_moment_Nm", [
    (PayloadSpec.m8_bolt(0.022, 0.016), THESIS_COILS["table_2_2"], 3.25e-5),
    (PayloadSpec.steel_cylinder(0.030, 0.028), THESIS_COILS["table_3_2"], 0.68e-3),
])
def test_hold_limit_matches_rigid_closed_form(spec, coil, hold_moment_Nm):
    lever = hold_lever_m(spec)
    force = spec.mass_kg * GRAVITY_M_S2 + hold_moment_Nm / lever
    current = MagnetParams(coil, 0.5e-3, spec.face_radius_m).current_for_force_A(force)
    a_limit = hold_moment_Nm / (spec.mass_kg * spec.com_offset_m)
    assert _bench(spec, coil, current, 0.9 * a_limit)
    assert not _bench(spec, coil, current, 1.1 * a_limit)
