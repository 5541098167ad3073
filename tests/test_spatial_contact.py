"""3-D contact wrench, the magnet's moment limit and the suction grip, against independent references."""

from pathlib import Path

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces
from scipy.optimize import linprog

from qmt_drake.limits.base import RowOptions
from qmt_drake.limits.contact_wrench import CarriedBody, MagnetMomentTerm, contact_wrench
from qmt_drake.limits.payload_moment import PayloadMomentTerm
from qmt_drake.limits.suction import GripModel, SuctionTerm
from qmt_drake.model.arm import ArmModel
from qmt_drake.model.drake_chain import DrakeChain
from qmt_drake.model.hand_state import HandState
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.model.urdf_check import load_arm_plant

MODELS = Path(__file__).resolve().parents[1] / "models"
BODY = CarriedBody(1.3, np.array([0.01, -0.02, 0.05]),
                   np.array([[0.004, 0.0002, 0.0001], [0.0002, 0.005, -0.0003], [0.0001, -0.0003, 0.003]]))


def states(n, S, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2.5, 2.5, (S, n)), rng.uniform(-2, 2, (S, n)), rng.uniform(-4, 4, (S, n))


def test_contact_wrench_is_what_the_arm_feels():
    """Independent of the formula: Drake's joint torques with the body welded minus without equal
    J^T of the wrench (in world) the hand applies to the body; the hand state from DrakeChain."""
    path = MODELS / "spatial" / "arm6.urdf"
    plant0, H0, _ = load_arm_plant(path, "hand")
    plant1, H1, _ = load_arm_plant(path, "hand", carried=BODY.as_dict())
    g = plant0.gravity_field().gravity_vector()
    q, qd, qdd = states(6, 10, 0)
    state = HandState(DrakeChain(plant0, H0), q, qd, qdd)
    w = contact_wrench(state, g, BODY)
    c0, c1 = plant0.CreateDefaultContext(), plant1.CreateDefaultContext()
    f0, f1 = MultibodyForces(plant0), MultibodyForces(plant1)
    W = plant0.world_frame()
    for k in range(len(q)):
        tau = []
        for plant, ctx, f in ((plant0, c0, f0), (plant1, c1, f1)):
            plant.SetPositions(ctx, q[k])
            plant.SetVelocities(ctx, qd[k])
            f.SetZero()
            plant.CalcForceElementsContribution(ctx, f)
            tau.append(plant.CalcInverseDynamics(ctx, qdd[k], f))
        J = plant0.CalcJacobianSpatialVelocity(c0, JacobianWrtVariable.kV, H0, np.zeros(3), W, W)
        R = state.rotation[k]
        F_W = np.r_[R @ w[k, :3], R @ w[k, 3:]]
        np.testing.assert_allclose(tau[1] - tau[0], J.T @ F_W, rtol=1e-9, atol=1e-9 * np.abs(tau[1]).max())


def test_spatial_chain_state_gives_the_same_wrench():
    plant, H, _ = load_arm_plant(MODELS / "spatial" / "arm6.urdf", "hand")
    q, qd, qdd = states(6, 20, 1)
    g = np.array([0.3, -0.2, -9.7])
    a = contact_wrench(SpatialChain(plant, H).evaluate(q, qd, qdd), g, BODY)
    b = contact_wrench(HandState(DrakeChain(plant, H), q, qd, qdd), g, BODY)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * np.abs(b).max())


def test_magnet_moment_is_the_thesis_moment_on_the_horizontal_arm():
    """Chapter 4's arm, part (m_o, r_G) hanging below the face: the 3-D face-plane moment of the full
    contact wrench equals PayloadMomentTerm's m_o r_G |a| (a part inertia about the face normal
    only twists, it does not tip)."""
    arm = ArmModel.from_urdf(MODELS / "two_link_ch4.urdf")
    m_o, r_G, limit = 0.030, 0.028, 0.570e-3
    ref = PayloadMomentTerm(arm, m_o * r_G, limit)
    assert ref.in_plane
    body = CarriedBody(m_o, np.array([0.0, 0.0, -r_G]), np.diag([2e-6, 2e-6, 1e-6]))
    term = MagnetMomentTerm(body, limit, arm.plant.gravity_field().gravity_vector(), face_normal=(0, 0, -1))
    q, qd, qdd = states(2, 200, 2)
    st = arm.hand_state(q, qd, qdd)
    np.testing.assert_allclose(term.moment_Nm(st), ref.moment_Nm(st), rtol=1e-10)
    np.testing.assert_allclose(term.columns(st), ref.columns(st), rtol=1e-10)
    assert term.columns(st).max() > 1  # the random states do exceed the limit: the test can tell


def test_magnet_moment_with_gravity_and_a_tilted_hand():
    """At rest on the spatial arm (hand tilted every way) the moment is m_o r_G |P_u g|, the 3-D branch
    of PayloadMomentTerm (face normal = hand z)."""
    arm = ArmModel.from_urdf(MODELS / "spatial" / "arm6.urdf")
    assert arm.planar is None
    m_o, r_G, limit = 0.030, 0.028, 0.570e-3
    ref = PayloadMomentTerm(arm, m_o * r_G, limit)
    body = CarriedBody(m_o, np.array([0.0, 0.0, r_G]), np.diag([2e-6, 2e-6, 1e-6]))
    term = MagnetMomentTerm(body, limit, arm.plant.gravity_field().gravity_vector(), face_normal=(0, 0, 1))
    q = states(6, 50, 3)[0]
    st = arm.hand_state(q, np.zeros_like(q), np.zeros_like(q))
    np.testing.assert_allclose(term.moment_Nm(st), ref.moment_Nm(st), rtol=1e-10)
    assert np.ptp(ref.moment_Nm(st)) > 0.5 * m_o * r_G * 9.81  # tilts vary the moment


def member_by_lp(grip, w):
    """Independent membership: l >= 0 with sum l G = w - w_pull (in the grip frame)."""
    G = grip.generators()
    R = grip.basis
    w_C = np.r_[R @ w[:3], R @ w[3:]]
    w_C[5] += grip.pull_force_N
    res = linprog(np.zeros(len(G)), A_eq=G.T, b_eq=w_C, bounds=(0, None), method="highs")
    return res.status == 0


@pytest.mark.parametrize("rim,edges,angle", [(8, 4, 0.0), (6, 4, np.pi / 4), (4, 4, 0.0)])
def test_grip_rows_equal_the_rim_contact_model(rim, edges, angle):
    grip = GripModel(0.02, 30.0, 0.5, face_normal=(0.3, -0.2, 0.9), rim_points=rim, pyramid_edges=edges,
                     pyramid_angle_rad=angle)
    rng = np.random.default_rng(5)
    agree = 0
    for _ in range(300):
        w = rng.normal(0, 1, 6) * np.r_[0.4, 0.4, 0.2, 15, 15, 30]
        ratio = grip.holds(w)[0]
        if abs(ratio - 1) < 1e-6:
            continue
        assert (ratio <= 1) == member_by_lp(grip, w), (w, ratio)
        agree += 1
    assert agree > 250
    # the boundary is where the LP becomes infeasible: scale a wrench to ratio 1 +- 1e-6
    w = np.array([0.1, -0.05, 0.02, 4.0, -3.0, 5.0])
    w1 = w / grip.holds(w)[0]
    assert member_by_lp(grip, w1 * (1 - 1e-6)) and not member_by_lp(grip, w1 * (1 + 1e-6))


def test_grip_closed_form_limits():
    """Pull-off at F, shear mu F along a pyramid edge, tipping r F about a rim point's axis."""
    r, F, mu = 0.02, 30.0, 0.5
    grip = GripModel(r, F, mu)  # face normal = H's z
    t1, t2, u = grip.basis
    np.testing.assert_allclose(grip.holds(np.r_[0, 0, 0, -F * u]), 1.0, rtol=1e-9)
    np.testing.assert_allclose(grip.holds(np.r_[0, 0, 0, mu * F * t1]), 1.0, rtol=1e-9)
    np.testing.assert_allclose(grip.holds(np.r_[r * F * t2, 0, 0, 0]), 1.0, rtol=1e-9)
    assert grip.holds(np.zeros(6))[0] == 0  # the ratio is a gauge: w scaled by k gives k times it


def test_suction_term_columns_and_toppra_rows_agree():
    plant, H, _ = load_arm_plant(MODELS / "spatial" / "arm6.urdf", "hand")
    grip = GripModel(0.02, 30.0, 0.6)
    g = plant.gravity_field().gravity_vector()
    term = SuctionTerm(grip, BODY, g)
    q, qd, qdd = states(6, 50, 6)
    st = SpatialChain(plant, H).evaluate(q, 0.3 * qd, 0.3 * qdd)
    col = term.columns(st)[:, 0]
    F, ones = term.toppra_rows(RowOptions())
    rows = term.toppra_w(st) @ F.T
    np.testing.assert_allclose(rows.max(axis=1), col, rtol=1e-12)
    assert np.all(ones == 1) and col.min() < 1 < col.max()
    with pytest.raises(ValueError):
        GripModel(0.0, 10.0, 0.5)
