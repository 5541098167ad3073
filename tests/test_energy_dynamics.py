"""Batched inverse dynamics with gravity (qmt_drake/energy/dynamics.py) against Drake."""

import numpy as np
import pytest

from qmt_drake.energy.dynamics import (
    drake_inverse_dynamics,
    drake_inverse_dynamics_jacobians,
    inverse_dynamics_with_gravity,
    ohsaka_arm,
)
from qmt_drake.energy.kinematics import tip_position


def _states(seed, S=25):
    rng = np.random.default_rng(seed)
    return rng.uniform(-np.pi, np.pi, (S, 3)), rng.uniform(-6, 6, (S, 3)), rng.uniform(-60, 60, (S, 3))


def test_parameters_come_from_the_urdf():
    arm = ohsaka_arm()
    np.testing.assert_allclose(arm.length_m, [0.30, 0.25, 0.15])
    np.testing.assert_allclose(arm.mass_kg, [2.0, 1.0, 0.5])
    np.testing.assert_allclose(arm.com_m, [0.15, 0.125, 0.075])
    np.testing.assert_allclose(arm.izz_com_kgm2, arm.mass_kg * arm.length_m ** 2 / 12)
    assert arm.tip_mass_kg == 5.0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_torque_equals_drake(sign):
    q, qd, qdd = _states(1)
    arm = ohsaka_arm().with_gravity_sign(sign)
    tau = inverse_dynamics_with_gravity(q, qd, qdd, arm, derivatives=False)
    ref = drake_inverse_dynamics(q, qd, qdd, gravity_up_sign=sign)
    assert np.max(np.abs(tau - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_static_torque_is_the_papers_gravity_vector():
    # eq. (1) at rest: tau = g(theta) with the paper's +cos terms (section 3), g = 9.81
    q = np.array([[0.3, -0.7, 1.1]])
    tau = inverse_dynamics_with_gravity(q, 0 * q, 0 * q, derivatives=False)[0]
    m1, m2, m3, m4 = 2.0, 1.0, 0.5, 5.0
    l1, l2, l3 = 0.30, 0.25, 0.15
    c1, c12, c123 = np.cos(q[0, 0]), np.cos(q[0, :2].sum()), np.cos(q[0].sum())
    g3 = 9.81 * (m3 / 2 + m4) * l3 * c123
    g2 = 9.81 * (m2 / 2 + m3 + m4) * l2 * c12 + g3
    g1 = 9.81 * (m1 / 2 + m2 + m3 + m4) * l1 * c1 + g2
    np.testing.assert_allclose(tau, [g1, g2, g3], rtol=1e-12)


def test_derivatives_equal_drake_autodiff():
    q, qd, qdd = _states(2, S=12)
    _, Jq, Jqd, Jqdd = inverse_dynamics_with_gravity(q, qd, qdd)
    for mine, ref in zip((Jq, Jqd, Jqdd), drake_inverse_dynamics_jacobians(q, qd, qdd)):
        assert np.max(np.abs(mine - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_urdf_tip_is_eq4():
    from qmt_drake.energy.dynamics import OHSAKA_URDF, make_plant
    plant = make_plant(str(OHSAKA_URDF))
    ctx = plant.CreateDefaultContext()
    q = np.array([0.4, 1.2, -2.0])
    plant.SetPositions(ctx, q)
    p = plant.GetFrameByName("tip").CalcPoseInWorld(ctx).translation()
    np.testing.assert_allclose([p[0], p[2]], tip_position(ohsaka_arm(), q), atol=1e-12)
    assert abs(p[1]) < 1e-12
