"""SpatialChain (batched spatial hand state) against Drake and Pinocchio, to 1e-9 relative."""

from pathlib import Path

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces

from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant

pin = pytest.importorskip("pinocchio")

MODELS = Path(__file__).resolve().parents[1] / "models"
RTOL = 1e-9
S = 25


def arm_source(name):
    if name == "arm6":
        return MODELS / "spatial" / "arm6.urdf", "hand", ()
    if name == "two_link_ch4":
        return MODELS / "two_link_ch4.urdf", "hand", ()
    try:
        return example_robot_urdf(name)
    except Exception as exc:  # the package is a test extra
        pytest.skip(str(exc))


def random_states(n, seed=0):
    """Random states; the first rows put joints at and near +-pi and several turns away (where the
    half-angle cos/sin is least accurate)."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-2.5, 2.5, (S, n))
    special = np.array([np.pi, -np.pi, np.pi - 1e-9, 3 * np.pi + 1e-7, 100.3, -np.pi / 2, 0.0])
    q[:4] = rng.choice(special, (4, n))
    return q, rng.uniform(-2, 2, (S, n)), rng.uniform(-4, 4, (S, n))


def assert_close(x, ref, what):
    x, ref = np.asarray(x), np.asarray(ref)
    scale = max(1.0, float(np.abs(ref).max())) if ref.ndim == 1 else np.abs(ref).max()
    err = float(np.abs(x - ref).max())
    assert err <= RTOL * max(scale, 1e-300), f"{what}: error {err:.3e} against scale {scale:.3e}"


def drake_reference(plant, hand, q, qd, qdd):
    """Per sample: tau (force elements: gravity and joint damping; reflected inertia), X_WH, V_WH, A_WH (J qdd + bias) and the hand
    body's spatial acceleration from CalcSpatialAccelerationsFromVdot."""
    ctx = plant.CreateDefaultContext()
    forces = MultibodyForces(plant)
    W = plant.world_frame()
    out = []
    for k in range(len(q)):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, qd[k])
        forces.SetZero()
        plant.CalcForceElementsContribution(ctx, forces)
        tau = plant.CalcInverseDynamics(ctx, qdd[k], forces)
        J = plant.CalcJacobianSpatialVelocity(ctx, JacobianWrtVariable.kV, hand, np.zeros(3), W, W)
        bias = plant.CalcBiasSpatialAcceleration(ctx, JacobianWrtVariable.kV, hand, np.zeros(3), W, W)
        A_bodies = plant.CalcSpatialAccelerationsFromVdot(ctx, qdd[k])
        A_body = A_bodies[int(hand.body().index())].get_coeffs()
        X = hand.CalcPoseInWorld(ctx)
        out.append(dict(tau=tau, p=X.translation(), R=X.rotation().matrix(), V=J @ qd[k],
                        A=J @ qdd[k] + bias.get_coeffs(), A_body=A_body, J=J,
                        hand_is_body_frame=hand.index() == hand.body().body_frame().index()))
    return out


@pytest.mark.parametrize("name", ["ur5", "panda", "arm6", "two_link_ch4", "xarm7", "ur10"])
def test_equal_to_drake(name):
    path, hand, lock = arm_source(name)
    plant, H, _ = load_arm_plant(path, hand, lock_joints=lock)
    chain = SpatialChain(plant, H)
    q, qd, qdd = random_states(chain.n_dof)
    r = chain.evaluate(q, qd, qdd)
    J = chain.spatial_jacobian(q)
    p, R = chain.hand_pose(q)
    for k, d in enumerate(drake_reference(plant, H, q, qd, qdd)):
        assert_close(r["joint_torque_Nm"][k], d["tau"], f"{name} torque sample {k}")
        assert_close(r["position_m"][k], d["p"], f"{name} position")
        assert_close(p[k], d["p"], f"{name} hand_pose position")
        assert_close(r["rotation"][k], d["R"], f"{name} rotation")
        assert_close(R[k], d["R"], f"{name} hand_pose rotation")
        assert_close(r["angular_velocity_rad_s"][k], d["V"][:3], f"{name} angular velocity")
        assert_close(r["linear_velocity_m_s"][k], d["V"][3:], f"{name} linear velocity")
        assert_close(r["angular_acceleration_rad_s2"][k], d["A"][:3], f"{name} angular acceleration")
        assert_close(r["linear_acceleration_m_s2"][k], d["A"][3:], f"{name} linear acceleration")
        assert_close(J[k], d["J"], f"{name} jacobian")
        assert d["hand_is_body_frame"]  # so the body's spatial acceleration is the hand frame's
        assert_close(r["angular_acceleration_rad_s2"][k], d["A_body"][:3], f"{name} body angular acceleration")
        assert_close(r["linear_acceleration_m_s2"][k], d["A_body"][3:], f"{name} body linear acceleration")


def pinocchio_model(name, path, lock, chain):
    model = pin.buildModelFromUrdf(str(path))
    if lock:
        ids = [model.getJointId(j) for j in lock]
        model = pin.buildReducedModel(model, ids, pin.neutral(model))
    names = [model.names[i] for i in range(1, model.njoints)]
    assert names == chain.joint_names, (names, chain.joint_names)
    model.armature = chain.reflected_inertia_kgm2.copy()
    return model


@pytest.mark.parametrize("name", ["ur5", "panda", "arm6", "two_link_ch4"])
def test_equal_to_pinocchio(name):
    path, hand, lock = arm_source(name)
    plant, H, _ = load_arm_plant(path, hand, lock_joints=lock)
    chain = SpatialChain(plant, H)
    model = pinocchio_model(name, path, lock, chain)
    if name in ("arm6", "two_link_ch4"):  # the URDF's actuators carry rotor inertias: the term is live
        assert np.all(chain.reflected_inertia_kgm2 > 0)
    if name == "panda":  # the URDF's joint damping: the term is live
        assert np.all(chain.damping_Nms > 0)
    data = model.createData()
    fid = model.getFrameId(hand)
    q, qd, qdd = random_states(chain.n_dof, seed=1)
    r = chain.evaluate(q, qd, qdd)
    for k in range(S):
        tau = pin.rnea(model, data, q[k], qd[k], qdd[k]) + chain.damping_Nms * qd[k]  # rnea has no damping
        assert_close(r["joint_torque_Nm"][k], tau, f"{name} torque vs pinocchio")
        pin.forwardKinematics(model, data, q[k], qd[k], qdd[k])
        pin.updateFramePlacements(model, data)
        X = data.oMf[fid]
        assert_close(r["position_m"][k], X.translation, f"{name} position vs pinocchio")
        assert_close(r["rotation"][k], X.rotation, f"{name} rotation vs pinocchio")
        a = pin.getFrameClassicalAcceleration(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        assert_close(r["linear_acceleration_m_s2"][k], a.linear, f"{name} classical acceleration vs pinocchio")
        assert_close(r["angular_acceleration_rad_s2"][k], a.angular, f"{name} angular acceleration vs pinocchio")


def test_carried_body_gravity_vector_and_reflected_override():
    """The carried body given to SpatialChain equals the same body welded in Drake's plant; a tilted
    gravity argument equals Drake's gravity field; an explicit reflected inertia replaces the plant's."""
    carried = dict(mass_kg=1.3, com_m=[0.01, -0.02, 0.05],
                   inertia_kgm2=[[0.004, 0.0002, 0.0001], [0.0002, 0.005, -0.0003], [0.0001, -0.0003, 0.003]])
    path = MODELS / "spatial" / "arm6.urdf"
    plant0, H0, _ = load_arm_plant(path, "hand")
    plant1, H1, _ = load_arm_plant(path, "hand", carried=carried)
    g = np.array([1.2, -0.7, -9.6])
    plant1.mutable_gravity_field().set_gravity_vector(g)
    q, qd, qdd = random_states(6, seed=2)
    ref = drake_reference(plant1, H1, q, qd, qdd)
    got = SpatialChain(plant0, H0, carried=carried).evaluate(q, qd, qdd, gravity_m_s2=g)
    welded = SpatialChain(plant1, H1, gravity_m_s2=g).evaluate(q, qd, qdd)
    without = SpatialChain(plant0, H0).evaluate(q, qd, qdd, gravity_m_s2=g)
    for k in range(S):
        assert_close(got["joint_torque_Nm"][k], ref[k]["tau"], "carried torque")
        assert_close(welded["joint_torque_Nm"][k], ref[k]["tau"], "welded carried torque")
    assert np.abs(without["joint_torque_Nm"] - got["joint_torque_Nm"]).max() > 1e-2  # the part matters
    refl = np.arange(1.0, 7.0)
    base = SpatialChain(plant0, H0, reflected_inertia_kgm2=np.zeros(6)).evaluate(q, qd, qdd)
    over = SpatialChain(plant0, H0, reflected_inertia_kgm2=refl).evaluate(q, qd, qdd)
    np.testing.assert_allclose(over["joint_torque_Nm"] - base["joint_torque_Nm"], refl * qdd, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("urdf,hand", [("two_link_ch4", "hand"), ("three_link_ch2", "hand"),
                                       ("crane_x7_planar", "tray"), ("three_link_vertical_ohsaka", "tip")])
def test_planar_arms_are_a_special_case(urdf, hand):
    """The project's planar arms (horizontal thesis arms, the vertical arms with gravity in their
    plane) through the spatial chain equal their planar backend (ArmModel's PlanarChain)."""
    from qmt_drake.model.arm import ArmModel

    path = MODELS / f"{urdf}.urdf"
    arm = ArmModel.from_urdf(path, hand)
    assert arm.planar is not None
    plant, H, _ = load_arm_plant(path, hand)
    chain = SpatialChain(plant, H)
    q, qd, qdd = random_states(chain.n_dof, seed=3)
    r = chain.evaluate(q, qd, qdd)
    st = arm.hand_state(q, qd, qdd)
    for k in range(S):
        assert_close(r["joint_torque_Nm"][k], st.joint_torque_Nm[k], "planar torque")
        assert_close(r["linear_acceleration_m_s2"][k], st.linear_acceleration_m_s2[k], "planar acceleration")
        assert_close(r["angular_acceleration_rad_s2"][k], st.angular_acceleration_rad_s2[k], "planar angular acc.")
        assert_close(r["position_m"][k], st.position_m[k], "planar position")
        assert_close(r["rotation"][k], st.rotation[k], "planar rotation")


def test_hand_state_backend():
    """SpatialChain serves HandState (model/hand_state.py) like DrakeChain does, field by field."""
    from qmt_drake.model.drake_chain import DrakeChain
    from qmt_drake.model.hand_state import HandState

    plant, H, _ = load_arm_plant(MODELS / "spatial" / "arm6.urdf", "hand")
    q, qd, qdd = random_states(6, seed=7)
    a, b = HandState(SpatialChain(plant, H), q, qd, qdd), HandState(DrakeChain(plant, H), q, qd, qdd)
    for name in ("position_m", "rotation", "linear_velocity_m_s", "angular_velocity_rad_s",
                 "linear_acceleration_m_s2", "angular_acceleration_rad_s2", "joint_torque_Nm"):
        for k in range(S):
            assert_close(getattr(a, name)[k], getattr(b, name)[k], f"HandState.{name}")


def test_chunks_and_workspace_reuse():
    """More samples than one chunk, then fewer (the scratch arrays are rebuilt): every row equals the
    same sample evaluated alone."""
    from qmt_drake.model.spatial_chain import CHUNK

    plant, H, _ = load_arm_plant(MODELS / "spatial" / "arm6.urdf", "hand")
    chain = SpatialChain(plant, H)
    rng = np.random.default_rng(4)
    big = [rng.uniform(-3, 3, (2 * CHUNK + 3, 6)) for _ in range(3)]
    r = chain.evaluate(*big)
    for k in (0, CHUNK - 1, CHUNK, 2 * CHUNK + 2):
        one = chain.evaluate(*(x[k:k + 1] for x in big))
        for key, val in one.items():
            assert_close(r[key][k], val[0], f"chunked {key} row {k}")


def test_arm_model_serves_a_spatial_arm_through_the_spatial_chain():
    """ArmModel's hand state of a non-planar arm (the generated 6-DOF arm with a carried body) comes
    from SpatialChain and equals Drake's own algorithms (DrakeChain) to 1e-12."""
    from pydrake.multibody.tree import SpatialInertia, UnitInertia

    from qmt_drake.model.arm import ArmModel
    from qmt_drake.model.hand_state import HandState
    from qmt_drake.model.spatial_chain import SpatialChain
    inert = SpatialInertia.MakeFromCentralInertia(0.5, [0.01, 0.0, -0.03],
                                                  0.5 * UnitInertia.SolidCylinder(0.02, 0.05, [0, 0, 1]))
    arm = ArmModel.from_urdf(MODELS / "spatial" / "arm6.urdf", hand_frame="hand", carried_inertia=inert,
                             require_gear_ratio=False)
    assert arm.planar is None and isinstance(arm.backend, SpatialChain)
    rng = np.random.default_rng(0)
    q, qd, qdd = (rng.uniform(-2, 2, (30, arm.n_dof)) for _ in range(3))
    mine, drake = arm.hand_state(q, qd, qdd), HandState(arm.drake_chain, q, qd, qdd)
    for k in ("position_m", "rotation", "linear_acceleration_m_s2", "angular_acceleration_rad_s2", "joint_torque_Nm"):
        x, y = getattr(mine, k), getattr(drake, k)
        assert np.max(np.abs(x - y)) <= 1e-12 * max(1.0, np.max(np.abs(y))), k
