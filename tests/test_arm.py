"""ArmModel: the batched planar evaluator against Drake's own multibody computations."""

import numpy as np
import pytest

from qmt_drake.config.scenario import MODELS_DIR
from qmt_drake.errors import QmtInputError
from qmt_drake.model.arm import ArmModel

URDFS = ["two_link_ch4.urdf", "three_link_ch2.urdf"]


@pytest.mark.parametrize("urdf", URDFS)
def test_batched_dynamics_match_drake(urdf):
    arm = ArmModel.from_urdf(MODELS_DIR / urdf)
    rng = np.random.default_rng(42)
    q = rng.uniform(-3, 3, (200, arm.n_dof))
    qd = rng.normal(0, 2, (200, arm.n_dof))
    qdd = rng.normal(0, 5, (200, arm.n_dof))
    a_b, tau_b = arm.tip_acceleration_and_joint_torque(q, qd, qdd)
    for k in range(200):
        tau_d = arm.drake_inverse_dynamics(q[k], qd[k], qdd[k])
        a_d = arm.drake_tip_acceleration(q[k], qd[k], qdd[k])
        np.testing.assert_allclose(tau_b[k], tau_d, rtol=1e-9, atol=1e-12 * np.abs(tau_d).max())
        np.testing.assert_allclose(a_b[k], a_d, rtol=1e-9, atol=1e-12 * np.abs(a_d).max())
        np.testing.assert_allclose(arm.tip_position(q[k]), arm.drake_tip_position(q[k]),
                                   atol=1e-14)


def test_reflected_rotor_inertia_enters_torque():
    arm = ArmModel.from_urdf(MODELS_DIR / "two_link_ch4.urdf")
    # Table 4.1: 0.031e-4 and 0.012e-4 kg m^2 on the motor side, N = 100.
    np.testing.assert_allclose(arm.reflected_inertia_kgm2, [0.031, 0.012], rtol=1e-12)
    # Closed-form mass matrix of a two-link arm (eq. 4-44 with the rotor terms).
    m1, m2, l1, lc1, lc2, J1, J2 = 0.547, 0.146, 0.16, 0.1184, 0.0803, 2.44e-3, 0.361e-3
    q2 = 0.7
    M11 = J1 + J2 + m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * np.cos(q2)) + 0.031
    tau = arm.joint_torque(np.array([0.3, q2]), np.zeros(2), np.array([1.0, 0.0]))
    assert tau[0] == pytest.approx(M11, rel=1e-12)


@pytest.mark.parametrize("branch", ["elbow_positive", "elbow_negative"])
def test_ik_round_trip(branch):
    arm = ArmModel.from_urdf(MODELS_DIR / "three_link_ch2.urdf")
    xy = np.array([[0.10, 0.16], [-0.05, 0.12], [0.0, 0.18]])
    q = arm.inverse_kinematics(xy, np.pi / 2, branch, check_range=False)
    np.testing.assert_allclose(arm.tip_position(q), xy, atol=1e-12)
    np.testing.assert_allclose(np.cos(arm.tool_angle(q) - np.pi / 2), 1.0, atol=1e-12)
    assert np.all(q[:, 1] > 0) == (branch == "elbow_positive")


def test_unreachable_point_names_point_and_reach():
    arm = ArmModel.from_urdf(MODELS_DIR / "two_link_ch4.urdf")
    with pytest.raises(QmtInputError, match=r"\(0\.3000, 0\.2000\).*reach is \[0\.0400, 0\.2800\]"):
        arm.inverse_kinematics(np.array([0.30, 0.20]))


def test_missing_urdf_is_named():
    with pytest.raises(QmtInputError, match="nope.urdf"):
        ArmModel.from_urdf("nope.urdf")
