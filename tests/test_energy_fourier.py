"""Seed 001's Fourier velocity family: boundary conditions exact, derivatives consistent."""

import numpy as np
import pytest

from qmt_drake.energy.dynamics import ohsaka_arm
from qmt_drake.energy.fourier import FourierVelocityFamily
from qmt_drake.energy.kinematics import (
    cog_height_m,
    lowest_cog_posture,
    self_motion_samples,
    tip_jacobian,
    tip_position,
)
from qmt_drake.errors import QmtInputError


@pytest.fixture
def fam():
    return FourierVelocityFamily([0.1, -0.4, 0.9], 5)


def _y(fam, seed=0):
    y = np.random.default_rng(seed).normal(size=fam.n_reduced)
    y[-1] = 0.7
    return y


def test_reduced_genes_satisfy_eq2_and_eq6_exactly(fam):
    y = _y(fam)
    x, _ = fam.reduced_to_full(y)
    q, qd, qdd = fam.evaluate_s(x, [0.0, 1.0])
    np.testing.assert_allclose(q[0], fam.theta0, atol=1e-14)
    np.testing.assert_allclose(q[1], y[:3], atol=1e-13)
    assert np.max(np.abs(qd)) < 1e-13 and np.max(np.abs(qdd)) < 1e-12
    np.testing.assert_allclose(fam.accel_residual(x), 0, atol=1e-13)
    np.testing.assert_allclose(fam.full_to_reduced(x), y, atol=1e-13)


def test_time_derivatives_are_consistent(fam):
    x, _ = fam.reduced_to_full(_y(fam, 1))
    t = np.linspace(0.05, 0.65, 7)
    h = 1e-6
    qp, qdp, _ = fam.sample(x, t + h)
    qm, qdm, _ = fam.sample(x, t - h)
    _, qd, qdd = fam.sample(x, t)
    np.testing.assert_allclose((qp - qm) / (2 * h), qd, atol=1e-6)
    np.testing.assert_allclose((qdp - qdm) / (2 * h), qdd, atol=1e-4 * np.abs(qdd).max())


def test_reduced_jacobian_matches_finite_differences(fam):
    y = _y(fam, 2)
    _, J = fam.reduced_to_full(y)
    h = 1e-6
    Jn = np.stack([(fam.reduced_to_full(y + h * e)[0] - fam.reduced_to_full(y - h * e)[0]) / (2 * h)
                   for e in np.eye(y.size)], axis=1)
    np.testing.assert_allclose(J, Jn, atol=1e-7)


def test_drake_trajectory_matches(fam):
    x, _ = fam.reduced_to_full(_y(fam, 3))
    pp = fam.trajectory(x).to_piecewise_polynomial(2000.0)
    t = np.linspace(0, 0.7, 23) + 0.0001
    t[-1] = 0.7
    np.testing.assert_allclose(pp.vector_values(t).T, fam.sample(x, t)[0], atol=1e-8)


def test_m_below_one_is_an_input_error():
    with pytest.raises(QmtInputError, match="m = 0"):
        FourierVelocityFamily([0, 0, 0], 0)


def test_tip_jacobian_and_start_rule():
    arm = ohsaka_arm()
    q = np.array([0.3, -1.0, 0.7])
    h = 1e-7
    Jn = np.stack([(tip_position(arm, q + h * e) - tip_position(arm, q - h * e)) / (2 * h) for e in np.eye(3)], 1)
    np.testing.assert_allclose(tip_jacobian(arm, q), Jn, atol=1e-8)
    X = np.array([0.68, 0.075])
    q0 = lowest_cog_posture(arm, X)
    np.testing.assert_allclose(tip_position(arm, q0), X, atol=1e-9)
    others = self_motion_samples(arm, X, step_deg=0.1)
    assert cog_height_m(arm, q0) <= cog_height_m(arm, others).min() + 1e-12
    np.testing.assert_allclose(lowest_cog_posture(arm, [0.7, 0.0]), 0, atol=1e-12)


def test_batched_evaluate_matches_single(fam):
    X = np.stack([fam.reduced_to_full(_y(fam, k))[0] for k in range(3)])
    X[1, -1] = 0.5
    cand = np.array([0, 1, 2, 1, 0])
    t = np.array([0.1, 0.2, 0.3, 0.6, 0.7])
    q, qd, qdd = fam.evaluate(X, cand, t)
    for k in range(5):
        ref = fam.sample(X[cand[k]], t[k:k + 1])
        for mine, r in zip((q, qd, qdd), ref):
            np.testing.assert_allclose(mine[k], r[0], atol=1e-12)
    np.testing.assert_allclose(fam.motion_time_s(X), [0.7, 0.5, 0.7])
