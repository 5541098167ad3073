"""Trajectory families against the thesis's closed forms and their own derivatives."""

import numpy as np
import pytest


def thesis_via_coefficients(T1, T2, T3, ts, tk1, tk2, tf):
    """Seed 000 eq. 4-15..4-30, typed in independently of the numerical 4N+4 solve."""
    mu1 = (tk1 - ts) / T1**2
    mu2 = (tk2 - tk1 - mu1 * T2 * (2 * T1 + T2)) / T2**3
    mu3 = -T1 * (T1 + 2 * T2) / T2**2
    mu4 = 2 * mu1 * (T1 + T2) + 3 * mu2 * T2**2
    mu5 = T1**2 + 4 * T1 * T2 + 3 * mu3 * T2**2
    mu6, mu7 = mu1 + 3 * mu2 * T2, 2 * T1 + 3 * mu3 * T2
    mu8 = (-mu4 - 2 * mu6 * T3) / (3 * T3**2)
    mu9 = (-mu5 - 2 * mu7 * T3) / (3 * T3**2)
    mu10 = (tf - tk2 - mu4 * T3 - mu6 * T3**2 - mu8 * T3**3) / (mu5 * T3 + mu7 * T3**2 + mu9 * T3**3)
    a13 = mu10
    a12 = mu1 - a13 * T1
    a21 = 2 * a12 * T1 + 3 * a13 * T1**2
    a22 = a12 + 3 * a13 * T1
    a23 = (tk2 - tk1 - a21 * T2 - a22 * T2**2) / T2**3
    a31 = a21 + 2 * a22 * T2 + 3 * a23 * T2**2
    a32 = a22 + 3 * a23 * T2
    a33 = (tf - tk2 - a31 * T3 - a32 * T3**2) / T3**3
    return np.array([[ts, 0.0, a12, a13], [tk1, a21, a22, a23], [tk2, a31, a32, a33]])


def test_via_cubic_matches_thesis_closed_form(problems):
    fam = problems["thesis-ch4"].family
    rng = np.random.default_rng(1)
    for T in rng.uniform(0.5, 3.0, (20, 3)):
        coef = fam.coefficients(T[None])[0]  # (3 segments, 4, 2 joints)
        for j in range(2):
            ts, tk1, tk2, tf = fam.joint_points[:, j]
            np.testing.assert_allclose(coef[:, :, j],
                                       thesis_via_coefficients(*T, ts, tk1, tk2, tf),
                                       rtol=1e-8, atol=1e-10)


def test_via_cubic_any_number_of_vias(scenarios):
    from qmt_drake.families import make_family
    from qmt_drake.transfer_scenario import load_scenario
    base = scenarios["thesis-ch4"]
    for pts in ([[0.17, 0.20], [-0.18, 0.10]],
                [[0.17, 0.20], [0.12, 0.19], [0.08, 0.16], [0.0, 0.15], [-0.10, 0.12],
                 [-0.18, 0.10]]):
        genes = {f"T{i + 1}": [0.5, 3.0] for i in range(len(pts) - 1)}
        sc = load_scenario(base.source_path, overrides={"task": {"points_m": pts},
                                                        "family": {"genes": genes}})
        fam = make_family(sc)
        T = np.full((1, len(pts) - 1), 0.8)
        knots = np.concatenate([[0], np.cumsum(T[0])])
        q, qd, qdd = fam.sample(T[0], knots[:-1])
        np.testing.assert_allclose(q, fam.joint_points[:-1], atol=1e-12)
        # Velocity and acceleration continuous at every knot (left vs right limits).
        for tk in knots[1:-1]:
            left = fam.evaluate(T, np.zeros(1, int), np.array([tk]), np.array([tk - 1e-6]))
            right = fam.evaluate(T, np.zeros(1, int), np.array([tk]), np.array([tk + 1e-6]))
            for a, b in zip(left, right):
                np.testing.assert_allclose(a, b, atol=1e-9)
        assert np.allclose(fam.sample(T[0], [0.0])[1], 0) and np.allclose(
            fam.sample(T[0], [knots[-1] - 1e-12])[1], 0, atol=1e-9)


@pytest.mark.parametrize("name", ["thesis-ch2", "thesis-ch3", "thesis-ch4"])
def test_velocity_and_acceleration_are_derivatives(problems, name):
    """qd and qdd equal central differences of q and qd inside every piece."""
    P = problems[name]
    g = P.genes_vector(P.scenario.reported["genes"])
    bp = P.family.breakpoints_s(g[None])[0]
    h = 1e-6
    for a, b in zip(bp[:-1], bp[1:]):
        if b - a < 1e-3:
            continue
        t = np.linspace(a + 1e-3, b - 1e-3, 7)
        q, qd, qdd = P.family.sample(g, t)
        qp, qdp, _ = P.family.sample(g, t + h)
        qm, qdm, _ = P.family.sample(g, t - h)
        np.testing.assert_allclose(qd, (qp - qm) / (2 * h), atol=1e-6)
        np.testing.assert_allclose(qdd, (qdp - qdm) / (2 * h), atol=1e-5)


def test_line_keeps_path_and_tool_angle_and_eq_2_25(problems, scenarios):
    P = problems["thesis-ch2"]
    sc = scenarios["thesis-ch2"]
    T1, T2 = 1.3, 0.7
    t = np.linspace(0, 2 * T1 + T2, 2001)
    q, qd, qdd = P.family.sample([T1, T2], t)
    xy = P.arm.tip_position(q)
    np.testing.assert_allclose(xy[:, 1], 0.16, atol=1e-12)
    np.testing.assert_allclose(P.arm.tool_angle(q), np.pi / 2, atol=1e-12)
    np.testing.assert_allclose(xy[[0, -1], 0], [0.10, -0.10], atol=1e-12)
    a = P.arm.tip_acceleration(q, qd, qdd)
    np.testing.assert_allclose(a[:, 1], 0.0, atol=1e-12)
    peak = np.abs(a[:, 0]).max() * sc.moment_per_accel_kgm
    L = 0.2
    closed = 3 * sc.moment_per_accel_kgm * L / (2 * T1 * (T1 + T2))  # eq. 2-25
    assert peak == pytest.approx(closed, rel=1e-5)


def test_trapezoid_motion_time_and_rates(problems):
    P = problems["thesis-ch3"]
    fam = P.family
    g = np.array([0.686, 0.565, 1.296])
    d1 = fam.delta[0]
    assert fam.motion_time_s(g[None])[0] == pytest.approx(0.686 + d1 / 1.296)
    w = fam.cruise_rates(g[None])[0]
    assert w[0] == pytest.approx(np.sign(d1) * 1.296)
    T0 = fam.motion_time_s(g[None])[0]
    q_end = fam.sample(g, [T0 - 1e-12])[0][0]
    np.testing.assert_allclose(q_end, fam.joint_points[1], atol=1e-9)
    assert not fam.valid(np.array([[3.0, 0.5, 3.0]]))[0]  # T0 < 2*T11: no cruise phase
