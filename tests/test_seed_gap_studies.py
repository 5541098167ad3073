"""The two gap studies' own pieces: seed 001's variant objectives (studies/ohsaka_gap.py) and seed
002's MoveIt-style return profile (studies/seed002_pair.py)."""

import numpy as np
import pytest

from studies.ohsaka_gap import VariantObjective, _problem, model_vs_printed
from studies.seed002_pair import MOVEIT_ACCEL_RAD_S2, _trapezoid_fraction


def _random_x(P, seed=0):
    rng = np.random.default_rng(seed)
    y = np.concatenate([P.theta0 + rng.normal(size=3), 0.3 * rng.normal(size=P.family.n_reduced - 4), [0.3]])
    return P.family.reduced_to_full(y)[0]


def test_variant_with_the_shipped_choices_is_the_shipped_objective():
    P = _problem("ohsaka-fig3", {})
    x = _random_x(P)
    z0, g0 = P.objective.value_and_gradient(x)
    z1, g1 = VariantObjective(P.family, P.arm, P.c1, P.c2, P.divisions).value_and_gradient(x)
    assert z1 == pytest.approx(z0, rel=1e-14)
    assert np.max(np.abs(g1 - g0)) <= 1e-12 * np.max(np.abs(g0))


@pytest.mark.parametrize("energy,quad", [("power_abs", "simpson"), ("power_pos", "sum_no_dt"),
                                         ("tau2_dyn", "rect"), ("tau2_no_qd", "nodes")])
def test_variant_gradient_equals_central_differences(energy, quad):
    P = _problem("ohsaka-fig3", {})
    V = VariantObjective(P.family, P.arm, P.c1, P.c2, P.divisions, energy, quad)
    x = _random_x(P, 1)
    _, g = V.value_and_gradient(x)
    h = 1e-6
    fd = np.array([(V.value(x + h * e) - V.value(x - h * e)) / (2 * h) for e in np.eye(x.size)])
    assert np.max(np.abs(fd - g)) <= 1e-6 * np.max(np.abs(g))


def test_model_is_the_papers_printed_mass_matrix_and_gravity():
    dM, dg = model_vs_printed(samples=20)
    assert dM < 1e-9 and dg < 1e-9


def test_trapezoid_return_profile():
    T, travel = 2.5, 1.2
    t = np.linspace(0.0, T, 2501)
    u = _trapezoid_fraction(t, T, travel)
    assert u[0] == 0.0 and u[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(u) >= 0)
    acc = np.diff(u, 2) / (t[1] - t[0]) ** 2 * travel     # the furthest joint's acceleration
    assert np.max(np.abs(acc)) == pytest.approx(MOVEIT_ACCEL_RAD_S2, rel=1e-2)
