"""Operability (seed 003 eq. 2-8) against hand computations on a planar 2-link arm, and the
arms' Jacobian against Drake's."""

import numpy as np
import pytest

from qmt_drake.design.operability import direction_ease, fitness_E, joint_rate_cost, operability, task_fitness


def planar_J(l1, l2, q1, q2):
    s1, c1, s12, c12 = np.sin(q1), np.cos(q1), np.sin(q1 + q2), np.cos(q1 + q2)
    return np.array([[-l1 * s1 - l2 * s12, -l2 * s12], [l1 * c1 + l2 * c12, l2 * c12]])


def test_planar_two_link_by_hand():
    # l1 = l2 = 1, q = (0, 90 deg): J = [[-1, -1], [1, 0]], J^-1 = [[0, 1], [-1, -1]]:
    # unit x velocity needs qdot = (0, -1): A_x = (0 + 1) / 2; unit y: qdot = (1, -1): A_y = 2 / 2.
    J = planar_J(1.0, 1.0, 0.0, np.pi / 2)
    np.testing.assert_allclose(J, [[-1, -1], [1, 0]], atol=1e-15)
    A = joint_rate_cost(J[None])[0]
    np.testing.assert_allclose(A, [0.5, 1.0], rtol=1e-12)
    mu = direction_ease(J[None])[0]
    # work x, constrained y, a = 0.5: w = e^-0.5, c = e^-1, mu = w (a w + (1 - a)(1 - c))
    w, c = np.exp(-0.5), np.exp(-1.0)
    got = operability(mu[None], [True, False], [False, True], 0.5)[0]
    assert got == pytest.approx(w * (0.5 * w + 0.5 * (1 - c)), rel=1e-12)


def test_planar_general_closed_form_inverse():
    # closed-form inverse of the 2-link Jacobian: J^-1 = 1/(l1 l2 s2) [[l2 c12, l2 s12],
    # [-l1 c1 - l2 c12, -l1 s1 - l2 s12]]
    rng = np.random.default_rng(3)
    for _ in range(20):
        l1, l2 = rng.uniform(0.2, 1.0, 2)
        q1, q2 = rng.uniform(-3, 3), rng.uniform(0.3, 2.8)
        s1, c1, s12, c12 = np.sin(q1), np.cos(q1), np.sin(q1 + q2), np.cos(q1 + q2)
        Ji = np.array([[l2 * c12, l2 * s12], [-l1 * c1 - l2 * c12, -l1 * s1 - l2 * s12]]) / (l1 * l2 * np.sin(q2))
        A_hand = np.sum(Ji ** 2, axis=0) / 2
        np.testing.assert_allclose(joint_rate_cost(planar_J(l1, l2, q1, q2)[None])[0], A_hand, rtol=1e-9)


def test_singular_direction_cannot_be_produced():
    # stretched arm (q2 = 0) along x: no velocity along the arm -> mu_x = 0; across it finite:
    # J = [[0, 0], [2, 1]], least-norm qdot for unit y = (2, 1)/5 -> A_y = (4 + 1)/25/2 = 0.1
    J = planar_J(1.0, 1.0, 0.0, 0.0)
    A = joint_rate_cost(J[None])[0]
    assert np.isinf(A[0])
    assert A[1] == pytest.approx(0.1, rel=1e-9)
    assert direction_ease(J[None])[0, 0] == 0.0


def test_empty_direction_sets_and_fitness():
    mu = np.array([[0.9, 0.8, 0.7, 0.6, 0.5, 0.4]])
    none = np.zeros(6, bool)
    assert operability(mu, none, none, 0.5)[0] == 0.0            # k_w = 0 -> w = 0 -> mu = 0
    only_w = np.array([1, 1, 0, 0, 0, 0], bool)
    # k_c = 0 -> c = 0: mu = w (a w + 1 - a)
    assert operability(mu, only_w, none, 0.25)[0] == pytest.approx(0.85 * (0.25 * 0.85 + 0.75))
    # eq. 7/8: unreachable units count 0 and scale by P_k / k
    m = np.array([[0.5, 0.7, 0.9, 0.3]])
    r = np.array([[True, False, True, True]])
    assert task_fitness(np.where(r, m, 0))[0] == pytest.approx(1.7 / 4)
    assert fitness_E(m, r, np.array([2.0]))[0] == pytest.approx(1.7 / 4 / 2.0 * 3 / 4)
    assert fitness_E(m, r, np.array([0.0]))[0] == 0.0
