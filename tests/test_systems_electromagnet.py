"""electromagnet_force: Maxwell pull vs gap, along the hand's normal with the reaction on the hand
(as the generalized force of the payload's joint), covered area; the float and symbolic forms of
the one formula agree; the continuous-state guard."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Integrator

from qmt_drake.systems.electromagnet import (
    MU0,
    THESIS_COILS,
    MagnetParams,
    covered_fraction,
    electromagnet_force,
)
from qmt_drake.systems.payload import PayloadSpec, add_payload, payload_joint

COIL = THESIS_COILS["table_3_2"]


def _hand_and_part(face_radius_m=5e-3):
    """A plant with a free-floating hand and the payload on its joint; (builder, plant, hand, payload, joint)."""
    b = DiagramBuilder()
    plant, _ = AddMultibodyPlant(MultibodyPlantConfig(time_step=1e-3, contact_model="point"), b)
    hand = plant.AddRigidBody("hand", SpatialInertia.SolidSphereWithMass(1.0, 0.01))
    spec = PayloadSpec("part", 0.03, 0.02, 0.04, face_radius_m, face_radius_m)
    payload = add_payload(plant, spec, hand)
    plant.Finalize()
    return b, plant, hand, payload, payload_joint(plant, payload)


def _magnet_outputs(params, X_WH, X_HP, current):
    """(generalized force vector, pull, gap, plant, context) for the hand at X_WH and the part at X_HP."""
    _, plant, hand, payload, joint = _hand_and_part(params.payload_face_radius_m)
    magnet = electromagnet_force(params, plant, joint)
    pc = plant.CreateDefaultContext()
    plant.SetFreeBodyPose(pc, hand, X_WH)
    joint.SetPose(pc, X_HP)
    mc = magnet.CreateDefaultContext()
    magnet.GetInputPort("plant_state").FixValue(mc, plant.GetPositionsAndVelocities(pc))
    magnet.GetInputPort("coil_current").FixValue(mc, [current])
    tau = magnet.GetOutputPort("generalized_force").Eval(mc)
    return tau, magnet.GetOutputPort("attraction_force").Eval(mc)[0], magnet.GetOutputPort("gap").Eval(mc)[0], plant, pc


@pytest.mark.parametrize("gap", [0.0, 0.2e-3, 1.0e-3, 5.0e-3])
def test_pull_follows_maxwell_formula_along_the_hand_normal_with_reaction_on_the_hand(gap):
    p = MagnetParams(COIL, 0.5e-3, payload_face_radius_m=5e-3)
    X_WH = RigidTransform(RollPitchYaw(0.3, -0.2, 1.0), [0.1, 0.2, 0.0])
    X_HP = RigidTransform(RollPitchYaw(0.05, 0.0, 0.1), [0.3e-3, -0.2e-3, -gap])
    tau, f, g, plant, pc = _magnet_outputs(p, X_WH, X_HP, 0.8)
    expected = 4e-7 * math.pi * (math.pi * 0.0078**2 / 4) * (156 * 0.8) ** 2 / (2 * (gap + 0.5e-3) ** 2)
    assert g == pytest.approx(gap, abs=1e-15)
    assert f == pytest.approx(expected, rel=1e-12)
    # Independent check through Drake's Jacobians: the generalized force of +f z_H on the payload at
    # its face centre and -f z_H on the hand at the same point, J_P^T F - J_H^T F, is tau.
    from pydrake.multibody.tree import JacobianWrtVariable
    W = plant.world_frame()
    hand, payload = plant.GetBodyByName("hand"), plant.GetBodyByName("payload")
    F = f * X_WH.rotation().matrix()[:, 2]
    J_P = plant.CalcJacobianTranslationalVelocity(pc, JacobianWrtVariable.kV, payload.body_frame(), np.zeros(3), W, W)
    J_H = plant.CalcJacobianTranslationalVelocity(pc, JacobianWrtVariable.kV, hand.body_frame(), X_HP.translation(),
                                                  W, W)
    np.testing.assert_allclose(tau, J_P.T @ F - J_H.T @ F, rtol=0, atol=1e-12 * f)
    assert tau[-1] == pytest.approx(f, rel=1e-15)  # all of it on the joint's z translation


def test_float_and_symbolic_forms_agree_including_sliding_off():
    p = MagnetParams(COIL, 0.5e-3, payload_face_radius_m=4.66e-3)
    for x, z in [(0.0, 0.0), (0.5e-3, -0.1e-3), (1.0e-3, 0.0), (3e-3, -0.4e-3), (8.0e-3, 0.0), (9e-3, -1e-3),
                 (0.2e-3, 0.3e-3)]:
        _, f, g, _, _ = _magnet_outputs(p, RigidTransform(), RigidTransform([x, 0.0, z]), 0.8)
        assert f == pytest.approx(p.force_N(0.8, -z, x), rel=1e-12, abs=1e-300)
        assert g == max(-z, 0.0)


def test_current_for_force_inverts_the_law():
    p = MagnetParams(COIL, 0.5e-3, payload_face_radius_m=5e-3)
    i = p.current_for_force_A(0.47)
    assert p.force_N(i) == pytest.approx(0.47, rel=1e-12)
    assert MU0 == pytest.approx(1.25663706e-6, rel=1e-8)


def test_covered_fraction_against_monte_carlo():
    rng = np.random.default_rng(0)
    a, b = 3.9e-3, 4.66e-3
    r = a * np.sqrt(rng.random(400_000))
    th = 2 * np.pi * rng.random(400_000)
    x, y = r * np.cos(th), r * np.sin(th)
    for d in (0.0, 0.5e-3, 0.9e-3, 2e-3, 5e-3, 8e-3, 9e-3):
        mc = np.mean((x - d) ** 2 + y**2 <= b**2)
        assert covered_fraction(d, a, b) == pytest.approx(mc, abs=3e-3)
    assert covered_fraction(b - a, a, b) == 1.0
    assert covered_fraction(a + b, a, b) == 0.0


def test_sliding_off_the_core_weakens_the_pull():
    p = MagnetParams(COIL, 0.5e-3, payload_face_radius_m=4.66e-3)
    _, f0, _, _, _ = _magnet_outputs(p, RigidTransform(), RigidTransform([0.0005, 0.0, 0.0]), 0.8)
    _, f1, _, _, _ = _magnet_outputs(p, RigidTransform(), RigidTransform([0.003, 0.0, 0.0]), 0.8)
    assert f0 == pytest.approx(p.force_N(0.8), rel=1e-12)
    assert f1 == pytest.approx(p.force_N(0.8) * covered_fraction(0.003, 3.9e-3, 4.66e-3), rel=1e-12)
    assert f1 < 0.8 * f0


def test_in_a_diagram_with_continuous_state_needs_the_guard():
    """With host_has_continuous_state=True the magnet runs beside an Integrator (Drake 1.51's
    stateless SymbolicVectorSystem would abort the simulation)."""
    b, plant, hand, payload, joint = _hand_and_part()
    magnet = b.AddSystem(electromagnet_force(MagnetParams(COIL, 0.5e-3, 5e-3), plant, joint,
                                            host_has_continuous_state=True))
    b.Connect(plant.get_state_output_port(), magnet.GetInputPort("plant_state"))
    b.Connect(b.AddSystem(ConstantVectorSource([0.5])).get_output_port(), magnet.GetInputPort("coil_current"))
    b.Connect(magnet.GetOutputPort("generalized_force"), plant.get_applied_generalized_force_input_port())
    integ = b.AddSystem(Integrator(1))
    b.Connect(b.AddSystem(ConstantVectorSource([1.0])).get_output_port(), integ.get_input_port())
    sim = Simulator(b.Build())
    sim.AdvanceTo(0.01)
    assert np.isfinite(magnet.GetOutputPort("attraction_force").Eval(magnet.GetMyContextFromRoot(sim.get_context()))[0])
