"""ElectromagnetForce: Maxwell pull vs gap, direction, reaction on the hand, covered area."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.tree import BodyIndex

from qmt_drake.systems.electromagnet import (MU0, THESIS_COILS, ElectromagnetForce, MagnetParams,
                                             covered_fraction)

COIL = THESIS_COILS["table_3_2"]


def _forces(params, X_WH, X_WP, current):
    sys = ElectromagnetForce(params, BodyIndex(1), BodyIndex(2))
    ctx = sys.CreateDefaultContext()
    sys.GetInputPort("body_poses").FixValue(ctx, [RigidTransform(), X_WH, X_WP])
    sys.GetInputPort("coil_current").FixValue(ctx, [current])
    forces = sys.GetOutputPort("spatial_forces").Eval(ctx)
    return forces, sys.GetOutputPort("attraction_force").Eval(ctx)[0], sys.GetOutputPort("gap").Eval(ctx)[0]


@pytest.mark.parametrize("gap", [0.0, 0.2e-3, 1.0e-3, 5.0e-3])
def test_pull_follows_maxwell_formula_and_points_to_the_face(gap):
    p = MagnetParams(COIL, 0.5e-3, payload_face_radius_m=5e-3)
    X_WH = RigidTransform(RollPitchYaw(0.3, -0.2, 1.0), [0.1, 0.2, 0.0])
    X_HP = RigidTransform([0.0, 0.0, -gap])
    forces, f, g = _forces(p, X_WH, X_WH.multiply(X_HP), 0.8)
    expected = 4e-7 * math.pi * (math.pi * 0.0078**2 / 4) * (156 * 0.8) ** 2 / (2 * (gap + 0.5e-3) ** 2)
    assert g == pytest.approx(gap, abs=1e-12)
    assert f == pytest.approx(expected, rel=1e-9)
    on_payload, on_hand = forces
    z_W = X_WH.rotation().matrix()[:, 2]
    np.testing.assert_allclose(on_payload.F_Bq_W.translational(), f * z_W, rtol=1e-12, atol=1e-15)
    # Reaction: equal and opposite, applied at the same world point (so no net moment either).
    np.testing.assert_allclose(on_hand.F_Bq_W.translational(), -f * z_W, rtol=1e-12, atol=1e-15)
    p_W_on_hand = X_WH.multiply(on_hand.p_BoBq_B)
    p_W_on_payload = X_WH.multiply(X_HP).multiply(on_payload.p_BoBq_B)
    np.testing.assert_allclose(p_W_on_hand, p_W_on_payload, atol=1e-12)


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
    X_WH = RigidTransform()
    _, f0, _ = _forces(p, X_WH, RigidTransform([0.0005, 0.0, 0.0]), 0.8)  # still covers the core
    _, f1, _ = _forces(p, X_WH, RigidTransform([0.003, 0.0, 0.0]), 0.8)
    assert f0 == pytest.approx(p.force_N(0.8), rel=1e-12)
    assert f1 == pytest.approx(p.force_N(0.8) * covered_fraction(0.003, 3.9e-3, 4.66e-3), rel=1e-12)
    assert f1 < 0.8 * f0
