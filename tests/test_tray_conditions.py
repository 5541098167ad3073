"""Tray limits: the contact wrench against Drake's inverse dynamics, closed forms at rest and
under a constant acceleration, and the linear form against the ratio columns."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2 as GRAVITY_M_S2
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.tray.conditions import (
    TrayKinematics,
    contact_wrench,
    linear_form,
    tray_kinematics,
    tray_ratios,
)
from qmt_drake.tray.cosim import URDF_PATH

BOTTLE = BottleSpec.pet_500ml(friction=0.3)
G = GRAVITY_M_S2


def test_wrench_matches_drake_inverse_dynamics_of_the_bottle_welded_on_the_tray():
    # Two plants: the arm alone and the arm with the bottle welded on the tray. The torque
    # difference of CalcInverseDynamics is J_O' (wrench on the bottle at O, world frame).
    plants = []
    for with_bottle in (False, True):
        plant = MultibodyPlant(0.0)
        arm = Parser(plant).AddModels(str(URDF_PATH))[0]
        if with_bottle:
            body = plant.AddRigidBody("bottle", arm, BOTTLE.spatial_inertia())
            plant.WeldFrames(plant.GetFrameByName("tray"), body.body_frame(), RigidTransform())
        plant.Finalize()
        plants.append(plant)
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, qd, qdd = rng.uniform(-1, 1, 3), rng.uniform(-2, 2, 3), rng.uniform(-5, 5, 3)
        tau = []
        for plant in plants:
            ctx = plant.CreateDefaultContext()
            plant.SetPositions(ctx, q)
            plant.SetVelocities(ctx, qd)
            from pydrake.multibody.tree import MultibodyForces
            tau.append(plant.CalcInverseDynamics(ctx, qdd, MultibodyForces(plant))
                       - plant.CalcGravityGeneralizedForces(ctx))
        w_T = contact_wrench(tray_kinematics(q, qd, qdd, [0, 0, BOTTLE.com_height_m]), BOTTLE)[0]
        plant = plants[0]
        ctx = plant.CreateDefaultContext()
        plant.SetPositions(ctx, q)
        R = plant.CalcRelativeTransform(ctx, plant.world_frame(), plant.GetFrameByName("tray")).rotation().matrix()
        J = plant.CalcJacobianSpatialVelocity(ctx, JacobianWrtVariable.kV, plant.GetFrameByName("tray"), np.zeros(3),
                                              plant.world_frame(), plant.world_frame())
        wrench_W = np.concatenate([R @ w_T[:3], R @ w_T[3:]])
        np.testing.assert_allclose(tau[1] - tau[0], J.T @ wrench_W, rtol=1e-9, atol=1e-12)


def _static(R, a=None):
    a = np.zeros(3) if a is None else a
    return TrayKinematics(R[None], a[None], np.zeros((1, 3)), np.zeros((1, 3)))


def test_rest_and_constant_acceleration_closed_forms():
    w = contact_wrench(_static(np.eye(3)), BOTTLE)
    assert w[0, 5] == pytest.approx(BOTTLE.mass_kg * G)
    r = tray_ratios(w, BOTTLE)
    assert r["slide"][0] == pytest.approx(0.0, abs=1e-12) and r["tip"][0] == pytest.approx(0.0, abs=1e-12)
    for ratio in (0.5, 1.0, 2.0):
        a = ratio * BOTTLE.friction * G
        r = tray_ratios(contact_wrench(_static(np.eye(3), np.array([a, 0, 0])), BOTTLE), BOTTLE)
        assert r["slide"][0] == pytest.approx(ratio)
        assert r["tip"][0] == pytest.approx(a * BOTTLE.com_height_m / G / BOTTLE.contact_radius_m)
    # tray tilted by beta about y: slide ratio tan(beta) / mu, zmp h tan(beta)
    beta = 0.1
    c, s = math.cos(beta), math.sin(beta)
    r = tray_ratios(contact_wrench(_static(np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])), BOTTLE), BOTTLE)
    assert r["slide"][0] == pytest.approx(math.tan(beta) / BOTTLE.friction)
    assert r["tip"][0] == pytest.approx(BOTTLE.com_height_m * math.tan(beta) / BOTTLE.contact_radius_m)
    # falling tray: lift-off
    r = tray_ratios(contact_wrench(_static(np.eye(3), np.array([0, 0, -1.2 * G])), BOTTLE), BOTTLE)
    assert r["lift"][0] > 1


def test_linear_form_agrees_with_the_ratios():
    F, g = linear_form(BOTTLE, sides=32)
    rng = np.random.default_rng(0)
    for _ in range(300):
        kin = _static(np.eye(3), rng.normal(0, 4, 3))
        w = contact_wrench(kin, BOTTLE)[0]
        r = tray_ratios(w[None], BOTTLE)
        worst = max(r["slide"][0], r["tip"][0])
        linear_ok = bool(np.all(F @ w <= g + 1e-12))
        # the inscribed polygons are conservative by at most 1/cos(pi/32) - 1 = 0.5 %
        if linear_ok:
            assert worst <= 1.0 / math.cos(math.pi / 32) + 1e-9 and r["lift"][0] <= 1
        if worst <= 1.0 and r["lift"][0] <= 1.0 and worst < math.cos(math.pi / 32):
            assert linear_ok
