"""urdf_check: every URDF is a serial revolute chain to the hand, or refused in one line naming the fix."""

import numpy as np
import pytest
from pydrake.multibody.tree import MultibodyForces

from qmt_drake.errors import QmtInputError
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.model.urdf_check import EXAMPLE_ARMS, example_robot_urdf, load_arm_plant

INERTIAL = ('<inertial><mass value="1.0"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" '
            'iyz="0"/></inertial>')
LIMIT = '<limit lower="-3" upper="3" effort="50" velocity="2"/>'


def link(name, inertial=True):
    return f'<link name="{name}">{INERTIAL if inertial else ""}</link>'


def joint(name, parent, child, kind="revolute", limit=LIMIT, xyz="0 0 0.2", axis="0 1 0"):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}"/><axis xyz="{axis}"/>{limit}</joint>')


def robot(*parts, world=True):
    head = '<link name="world"/>' + joint("weld", "world", "base", "fixed", "") if world else ""
    return f'<robot name="r">{head}{link("base")}{"".join(parts)}</robot>'


GOOD = [link("l1"), joint("j1", "base", "l1", axis="0 0 1"), link("l2"), joint("j2", "l1", "l2"),
        link("hand", inertial=False), joint("hw", "l2", "hand", "fixed", "")]


def refused(text, hand="hand", **kw) -> str:
    with pytest.raises(QmtInputError) as exc:
        load_arm_plant(text, hand, **kw)
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def test_good_chain_loads_and_matches_drake():
    plant, H, names = load_arm_plant(robot(*GOOD), "hand")
    assert names == ["j1", "j2"]
    chain = SpatialChain(plant, H)
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.uniform(-2, 2, (3, 2)), rng.uniform(-2, 2, (3, 2)), rng.uniform(-2, 2, (3, 2))
    tau = chain.evaluate(q, qd, qdd)["joint_torque_Nm"]
    ctx, f = plant.CreateDefaultContext(), MultibodyForces(plant)
    for k in range(3):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, qd[k])
        f.SetZero()
        plant.CalcForceElementsContribution(ctx, f)
        np.testing.assert_allclose(tau[k], plant.CalcInverseDynamics(ctx, qdd[k], f), rtol=1e-9, atol=1e-12)


def test_root_not_named_world_is_welded_as_a_fixed_base():
    plant, _, names = load_arm_plant(robot(*GOOD, world=False), "hand")
    assert plant.num_positions() == 2 and names == ["j1", "j2"]


def test_floating_base_refused():
    parts = [link("l0"), joint("float", "base", "l0", "floating", "")] + [p.replace('"base"', '"l0"') for p in GOOD]
    msg = refused(robot(*parts))
    assert "floating" in msg and "weld" in msg


def test_prismatic_refused_and_lockable():
    parts = GOOD[:4] + [link("l3"), joint("slide", "l2", "l3", "prismatic"), link("hand", False),
                        joint("hw", "l3", "hand", "fixed", "")]
    msg = refused(robot(*parts))
    assert "'slide'" in msg and "prismatic" in msg and "lock" in msg
    _, _, names = load_arm_plant(robot(*parts), "hand", lock_joints=["slide"])
    assert names == ["j1", "j2"]


def test_closed_chain_refused():
    parts = GOOD + [joint("loop", "l1", "l2", axis="1 0 0")]
    msg = refused(robot(*parts))
    assert "closed chain" in msg and "'l2'" in msg


def test_branch_refused():
    parts = GOOD + [link("side"), joint("jside", "l1", "side")]
    msg = refused(robot(*parts))
    assert "'jside'" in msg and "branch" in msg and "lock" in msg


def test_missing_inertia_refused():
    parts = [link("l1", inertial=False)] + GOOD[1:]
    msg = refused(robot(*parts))
    assert "'l1'" in msg and "<inertial>" in msg


@pytest.mark.parametrize("attr", ["effort", "velocity"])
def test_missing_limits_refused_unless_supplied(attr):
    lim = LIMIT.replace(f' {attr}="50"', "").replace(f' {attr}="2"', "")
    parts = GOOD[:3] + [joint("j2", "l1", "l2", limit=lim)] + GOOD[4:]
    msg = refused(robot(*parts))
    assert "'j2'" in msg and f"{attr} limit" in msg and "actuator section" in msg
    supplied = {"effort_limit_Nm" if attr == "effort" else "velocity_limit_rad_s": [50.0, 50.0]}
    load_arm_plant(robot(*parts), "hand", **supplied)


def test_other_refusals():
    assert "no link named 'tool'" in refused(robot(*GOOD), hand="tool")
    assert "not well-formed" in refused("<robot><link></robot>")
    assert "no such URDF file" in refused("/nonexistent/arm.urdf")
    assert "lock_joints" in refused(robot(*GOOD), lock_joints=["nope"])
    assert "a branch" in refused(robot(*GOOD), hand="base")
    assert "no revolute joint" in refused(robot(link("hand", False), joint("hw", "base", "hand", "fixed", "")))
    bad_mass = robot(GOOD[0].replace('<mass value="1.0"/>', '<mass value="-1.0"/>'), *GOOD[1:])
    assert "'l1' has mass -1.0" in refused(bad_mass)
    bad_inertia = robot(GOOD[0].replace('izz="0.01"', 'izz="0.05"'), *GOOD[1:])
    assert "'l1'" in refused(bad_inertia) and "triangle" in refused(bad_inertia)
    zero_axis = robot(*GOOD).replace('axis xyz="0 0 1"', 'axis xyz="0 0 0"')
    assert "Drake cannot parse" in refused(zero_axis) and "'j1' axis is zero" in refused(zero_axis)
    bad_joint = robot(*GOOD).replace('type="revolute"', 'type="spherical"', 1)
    assert "'j1'" in refused(bad_joint) and "'spherical'" in refused(bad_joint)


@pytest.mark.parametrize("name", sorted(EXAMPLE_ARMS))
def test_arms_of_example_robot_data(name):
    """Every shipped arm description either loads as a serial chain (torques equal to Drake's) or
    is refused; those listed here load."""
    try:
        path, hand, lock = example_robot_urdf(name)
    except QmtInputError as exc:
        pytest.skip(str(exc))
    plant, H, names = load_arm_plant(path, hand, lock_joints=lock)
    assert len(names) in (6, 7)
    chain = SpatialChain(plant, H)
    rng = np.random.default_rng(1)
    n = chain.n_dof
    q, qd, qdd = rng.uniform(-2, 2, (4, n)), rng.uniform(-2, 2, (4, n)), rng.uniform(-2, 2, (4, n))
    tau = chain.evaluate(q, qd, qdd)["joint_torque_Nm"]
    ctx, f = plant.CreateDefaultContext(), MultibodyForces(plant)
    for k in range(4):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, qd[k])
        f.SetZero()
        plant.CalcForceElementsContribution(ctx, f)
        ref = plant.CalcInverseDynamics(ctx, qdd[k], f)
        assert np.abs(tau[k] - ref).max() <= 1e-9 * max(1.0, np.abs(ref).max())


def test_panda_fingers_must_be_locked():
    try:
        path, hand, lock = example_robot_urdf("panda")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    msg = refused(str(path), hand=hand)
    assert "panda_finger_joint" in msg and "lock" in msg


def test_generated_arm6_is_up_to_date_and_loads():
    import importlib.util
    from pathlib import Path

    models = Path(__file__).resolve().parents[1] / "models"
    spec = importlib.util.spec_from_file_location("gen_arm6", models / "generate_arm6.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    path = models / "spatial" / "arm6.urdf"
    assert path.read_text() == gen.urdf(), "run python models/generate_arm6.py"
    plant, _, names = load_arm_plant(path, "hand")
    assert names == [f"joint{k}" for k in range(1, 7)]
    acts = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
    np.testing.assert_allclose([a.default_gear_ratio() for a in acts], gen.GEAR_RATIO)
    np.testing.assert_allclose([a.default_rotor_inertia() for a in acts], gen.ROTOR_INERTIA_KGM2)


def test_drive_parameters_from_the_urdf_or_the_actuator_section():
    from pathlib import Path

    from qmt_drake.model.urdf_check import drive_parameters

    arm6 = Path(__file__).resolve().parents[1] / "models" / "spatial" / "arm6.urdf"
    plant, _, names = load_arm_plant(arm6, "hand")
    d = drive_parameters(arm6, names)
    acts = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
    np.testing.assert_allclose(d["gear_ratio"], [a.default_gear_ratio() for a in acts])
    np.testing.assert_allclose(d["reflected_inertia_kgm2"],
                               [a.default_gear_ratio() ** 2 * a.default_rotor_inertia() for a in acts])
    try:
        path, hand, lock = example_robot_urdf("ur5")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    plant, H, names = load_arm_plant(path, hand)
    with pytest.raises(QmtInputError, match="shoulder_pan_joint.*drake:gear_ratio.*actuator section"):
        drive_parameters(path, names)
    with pytest.raises(QmtInputError, match="give 6 finite values"):
        drive_parameters(path, names, gear_ratio=[100] * 5, rotor_inertia_kgm2=[1e-5] * 6)
    N, J = np.array([100, 100, 100, 80, 80, 80.0]), np.array([3e-5, 3e-5, 2e-5, 6e-6, 6e-6, 6e-6])
    d = drive_parameters(path, names, gear_ratio=N, rotor_inertia_kgm2=J)
    # the supplied drive in SpatialChain equals Drake with the same actuator parameters in its context
    ctx = plant.CreateDefaultContext()
    acts = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
    assert [a.joint().name() for a in acts] == names
    for a, n, j in zip(acts, N, J):
        a.SetGearRatio(ctx, n)
        a.SetRotorInertia(ctx, j)
    chain = SpatialChain(plant, H, reflected_inertia_kgm2=d["reflected_inertia_kgm2"])
    rng = np.random.default_rng(2)
    q, qd, qdd = rng.uniform(-2, 2, (3, 6)), rng.uniform(-2, 2, (3, 6)), rng.uniform(-2, 2, (3, 6))
    tau = chain.evaluate(q, qd, qdd)["joint_torque_Nm"]
    f = MultibodyForces(plant)
    for k in range(3):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, qd[k])
        f.SetZero()
        plant.CalcForceElementsContribution(ctx, f)
        ref = plant.CalcInverseDynamics(ctx, qdd[k], f)
        np.testing.assert_allclose(tau[k], ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    assert np.abs(d["reflected_inertia_kgm2"] * qdd).max() > 0.1  # the term is live
