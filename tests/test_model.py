"""The arm model against independent code: Drake's own algorithms on URDF variants (axis signs,
base offsets and yaws, vertical planes with gravity), Pinocchio on every shipped URDF, and plans
on arms nobody here wrote whose tips are checked on every task point by Drake forward kinematics."""

import re

import numpy as np
import pytest
import yaml

from qmt_drake.config.scenario import MODELS_DIR, SCENARIO_DIR
from qmt_drake.errors import QmtInputError
from qmt_drake.model.arm import ArmModel
from qmt_drake.transfer_scenario import load_scenario

CH4 = (MODELS_DIR / "two_link_ch4.urdf").read_text()
BASE_WELD = '<joint name="base_weld" type="fixed">\n    <parent link="world"/>\n    <child link="base"/>'


def _with_base_origin(origin: str) -> str:
    return CH4.replace(BASE_WELD, BASE_WELD + f"\n    {origin}")


# name -> (URDF text, map from the thesis's task points to the variant's plane coordinates)
PLANNED = {
    "axis_minus_z": (CH4.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 -1"/>', 1), lambda p: p),
    "base_offset": (_with_base_origin('<origin xyz="0.05 -0.03 0.2"/>'), lambda p: p + [0.05, -0.03]),
    "base_yaw_pi": (_with_base_origin(f'<origin rpy="0 0 {np.pi!r}"/>'), lambda p: -p),
    "vertical_plane": (_with_base_origin('<origin rpy="1.5707963267948966 0 0"/>'), lambda p: p),
    "world_link_declared": (CH4, lambda p: p),
}
REFUSED = {
    "no_gear_ratio": (CH4.replace('<drake:gear_ratio value="100"/>', ""), "declares no <drake:gear_ratio>"),
    "no_transmission": (re.sub(r"<transmission.*?</transmission>\n", "", CH4, flags=re.S), "have no actuator"),
    "not_xml": (CH4[:300], "not a well-formed URDF"),
    "tilted_plane": (_with_base_origin('<origin rpy="0.3 0 0"/>'), "needs a planar arm"),
}


def _scenario(tmp_path, urdf_text, points=None, **raw_changes):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(urdf_text)
    raw = yaml.safe_load((SCENARIO_DIR / "thesis-ch4.yaml").read_text())
    raw["arm"]["urdf"] = str(urdf)
    if points is not None:
        raw["task"]["points_m"] = np.asarray(points).tolist()
    for k, v in raw_changes.items():
        raw[k] = {**raw.get(k, {}), **v}
    p = tmp_path / "s.yaml"
    p.write_text(yaml.safe_dump(raw))
    return load_scenario(p)


def _tip_on_every_task_point(plan, sc):
    """Drake forward kinematics of the plan at its via times, against the task points."""
    times = np.concatenate([[0.0], np.cumsum(list(plan.genes.values()))])
    q = plan.sample(times)[0]
    arm = sc.arm
    world = arm.drake_chain.hand_pose(q)[0]
    in_plane = world @ arm.planar.plane_axes
    return float(np.max(np.abs(in_plane - sc.task.points_m)))


@pytest.mark.parametrize("name", sorted(PLANNED))
def test_variant_hand_state_equals_drake_with_gravity(tmp_path, name):
    path = tmp_path / "v.urdf"
    path.write_text(PLANNED[name][0])
    arm = ArmModel.from_urdf(path)
    assert arm.planar is not None
    rng = np.random.default_rng(4)
    q, qd, qdd = rng.normal(size=(3, 20, arm.n_dof))
    ours = arm.hand_state(q, qd, qdd)
    lin, ang, tau, _ = arm.drake_chain.hand_acceleration_and_joint_torque(q, qd, qdd)
    p, R = arm.drake_chain.hand_pose(q)
    for a, b in ((ours.joint_torque_Nm, tau), (ours.linear_acceleration_m_s2, lin),
                 (ours.angular_acceleration_rad_s2, ang), (ours.position_m, p), (ours.rotation, R)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * np.max(np.abs(b)))
    if name == "vertical_plane":
        assert np.allclose(arm.planar.gravity_in_plane_m_s2, [0.0, -9.81]) and not arm.gravity_does_no_work


@pytest.mark.parametrize("name", sorted(PLANNED))
def test_variant_plans_put_the_tip_on_every_task_point(tmp_path, name):
    text, to_plane = PLANNED[name]
    thesis_points = np.array(yaml.safe_load((SCENARIO_DIR / "thesis-ch4.yaml").read_text())["task"]["points_m"])
    sc = _scenario(tmp_path, text, to_plane(thesis_points))
    from qmt_drake.planners import plan_with
    plan = plan_with("thesis", sc)
    assert _tip_on_every_task_point(plan, sc) < 1e-9
    # Same arm, same motion relative to its base: the same limits except where gravity acts.
    ref = plan_with("thesis", load_scenario("thesis-ch4"))
    if name != "vertical_plane":
        assert plan.check.peak_moment_ratio == pytest.approx(ref.check.peak_moment_ratio, rel=1e-9)
        assert plan.check.peak_motor_torque_ratio == pytest.approx(ref.check.peak_motor_torque_ratio, rel=1e-9)
    else:  # the face now stands vertical: gravity shears the part and loads the motors
        static = sc.moment_per_accel_kgm * 9.81 / sc.limits.moment_limit_Nm
        assert static < plan.check.peak_moment_ratio < static + 2 * ref.check.peak_moment_ratio
        assert plan.check.peak_motor_torque_ratio > 2 * ref.check.peak_motor_torque_ratio


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_variant_refused_with_one_line(tmp_path, name):
    text, needle = REFUSED[name]
    with pytest.raises(QmtInputError, match=re.escape(needle)) as exc:
        sc = _scenario(tmp_path, text)
        from qmt_drake.planners import plan_with
        plan_with("thesis", sc)
    assert "\n" not in str(exc.value)


def test_user_written_arm_plans_correctly(tmp_path):
    """Other lengths, masses, inertias and gear ratios: plans reach the task points (Drake FK) and
    their motor torques are Drake's inverse dynamics / N."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("gen", MODELS_DIR / "generate_urdf.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    arm_spec = dict(gen.ARMS["two_link_ch4"], length_m=[0.30, 0.22], com_from_joint_m=[0.14, 0.09],
                    mass_kg=[1.2, 0.45], izz_about_com_kgm2=[9e-3, 2.2e-3], rotor_inertia_kgm2=[0.05e-4, 0.02e-4],
                    gear_ratio=[50, 80], effort_limit_Nm=[20.0, 15.0], source="a user's arm (test)")
    pts = [[0.30, 0.25], [0.15, 0.30], [-0.12, 0.28], [-0.30, 0.20]]
    sc = _scenario(tmp_path, gen.make_urdf("user_arm", arm_spec), pts,
                   limits={"motor_torque_limit_Nm": [0.15, 0.06]})
    np.testing.assert_allclose(sc.arm.gear_ratio, [50, 80])
    from qmt_drake.planners import plan_with
    plan = plan_with("ga", sc, seed=0, max_generations=150)
    assert plan.feasible
    assert _tip_on_every_task_point(plan, sc) < 1e-9
    t = np.linspace(0.0, plan.motion_time_s, 40)
    q, qd, qdd = plan.sample(t)
    drake_tau = sc.arm.drake_chain.hand_acceleration_and_joint_torque(q, qd, qdd)[2]
    np.testing.assert_allclose(sc.arm.motor_torque(q, qd, qdd), drake_tau / [50, 80], rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("urdf", sorted(p.name for p in MODELS_DIR.glob("*.urdf")))
def test_shipped_urdfs_against_pinocchio(urdf):
    """A second parser and a second inverse dynamics: Pinocchio's RNEA with gravity and armature
    (= the reflected rotor inertia N^2 J_r) against ours."""
    pin = pytest.importorskip("pinocchio")
    path = MODELS_DIR / urdf
    hand = {"crane_x7_planar.urdf": "tray", "three_link_vertical_ohsaka.urdf": "tip"}.get(urdf, "hand")
    arm = ArmModel.from_urdf(path, hand)
    assert arm.planar is not None  # every shipped arm is planar: the batched backend is what is compared
    model = pin.buildModelFromUrdf(str(path))
    assert model.nq == arm.n_dof
    model.armature[:] = arm.reflected_inertia_kgm2
    data = model.createData()
    rng = np.random.default_rng(11)
    for _ in range(10):
        q, v, a = rng.normal(size=(3, arm.n_dof))
        ref = pin.rnea(model, data, q, v, a)
        np.testing.assert_allclose(arm.joint_torque(q[None], v[None], a[None])[0], ref, rtol=1e-9,
                                   atol=1e-12 * np.max(np.abs(ref)))


def test_spatial_arm_hand_state_against_pinocchio(tmp_path):
    """An arm whose joints are not parallel to a world axis goes to the DrakeChain backend; its
    hand acceleration and joint torques (gravity on) agree with Pinocchio's."""
    pin = pytest.importorskip("pinocchio")
    text = _with_base_origin('<origin rpy="0.3 -0.2 0.1"/>').replace('<axis xyz="0 0 1"/>', '<axis xyz="0 1 0"/>', 1)
    path = tmp_path / "spatial.urdf"
    path.write_text(text)
    arm = ArmModel.from_urdf(path)
    assert arm.planar is None and "needs joint axes along a world axis" in arm.not_planar_reason
    model = pin.buildModelFromUrdf(str(path))
    model.armature[:] = arm.reflected_inertia_kgm2
    data = model.createData()
    fid = model.getFrameId("hand")
    rng = np.random.default_rng(5)
    q, qd, qdd = rng.normal(size=(3, 6, arm.n_dof))
    hs = arm.hand_state(q, qd, qdd)
    for k in range(len(q)):
        tau = pin.rnea(model, data, q[k], qd[k], qdd[k])
        np.testing.assert_allclose(hs.joint_torque_Nm[k], tau, rtol=1e-9, atol=1e-12)
        pin.forwardKinematics(model, data, q[k], qd[k], qdd[k])
        pin.updateFramePlacements(model, data)
        a = pin.getFrameClassicalAcceleration(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        np.testing.assert_allclose(hs.linear_acceleration_m_s2[k], a.linear, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(hs.angular_acceleration_rad_s2[k], a.angular, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(hs.position_m[k], data.oMf[fid].translation, atol=1e-12)


@pytest.mark.parametrize("name", ["axis_minus_z", "vertical_plane", "base_yaw_pi"])
def test_planar_torque_derivatives_equal_drake_autodiff(tmp_path, name):
    """PlanarChain.torque_and_derivatives (the recursion run on tangents) against Drake's
    MultibodyPlant<AutoDiffXd> inverse dynamics with gravity and rotor inertia."""
    from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, InitializeAutoDiff
    from pydrake.multibody.tree import MultibodyForces_
    path = tmp_path / "v.urdf"
    path.write_text(PLANNED[name][0])
    arm = ArmModel.from_urdf(path)
    n = arm.n_dof
    rng = np.random.default_rng(8)
    q, qd, qdd = rng.normal(size=(3, 7, n)) * [[[1.0]], [[3.0]], [[20.0]]]
    tau, Jq, Jqd, Jqdd = arm.planar.torque_and_derivatives(q, qd, qdd)
    np.testing.assert_allclose(tau, arm.joint_torque(q, qd, qdd), rtol=1e-12, atol=1e-12)
    plant = arm.plant.ToAutoDiffXd()
    ctx = plant.CreateDefaultContext()
    forces = MultibodyForces_[AutoDiffXd](plant)
    for k in range(len(q)):
        x = InitializeAutoDiff(np.concatenate([q[k], qd[k], qdd[k]])).ravel()
        plant.SetPositions(ctx, x[:n])
        plant.SetVelocities(ctx, x[n:2 * n])
        forces.SetZero()
        plant.CalcForceElementsContribution(ctx, forces)
        ref = ExtractGradient(plant.CalcInverseDynamics(ctx, x[2 * n:], forces))
        mine = np.concatenate([Jq[k], Jqd[k], Jqdd[k]], axis=1)
        np.testing.assert_allclose(mine, ref, rtol=1e-9, atol=1e-9 * np.max(np.abs(ref)))
