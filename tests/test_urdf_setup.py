"""Any URDF as a user has it (issue 28, item 2): a mobile manipulator from example-robot-data (PAL's
TIAGo: a prismatic torso, a head, wheels, a hand, a differential wrist, antennas whose inertia no
body has) set up with `package:`, `lock_joints` values and `lock: off_chain`, the URDF's own limits as
defaults and no gear data, planned and carried; each piece checked against Drake's own model of the
whole URDF."""

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from qmt_drake.errors import QmtInputError
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant, off_chain_locks
from qmt_drake.model.urdf_package import package_urdf
from qmt_drake.planners.spatial_methods import plan_family_optimum
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario

EXAMPLE = Path(__file__).resolve().parents[1] / "docs" / "examples" / "tiago-suction.yaml"
ARM = [f"arm_{k}_joint" for k in range(1, 8)]
HAND = "arm_tool_link"


def tiago():
    try:
        return package_urdf("example-robot-data/tiago")[0]
    except QmtInputError as exc:
        if "example-robot-data" not in str(exc):
            raise
        pytest.skip(str(exc))


def full_drake_plant(urdf):
    """Drake's own plant of the whole URDF, nothing locked (the independent reference)."""
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(urdf))
    plant.Finalize()
    return plant


def hand_pose_in_full_plant(urdf, hand, values: dict):
    plant = full_drake_plant(urdf)
    ctx = plant.CreateDefaultContext()
    q = plant.GetPositions(ctx)
    for name, v in values.items():
        q[plant.GetJointByName(name).position_start()] = v
    plant.SetPositions(ctx, q)
    return plant.GetFrameByName(hand).CalcPoseInWorld(ctx)


def edited(tmp_path, edit):
    raw = yaml.safe_load(EXAMPLE.read_text())
    edit(raw)
    p = tmp_path / "tiago-variant.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


@pytest.fixture(scope="module")
def sc():
    tiago()
    return load_spatial_scenario(EXAMPLE)


def test_joints_locked_at_values_put_the_hand_where_drake_puts_it_moving_them():
    """A prismatic torso locked at 0.25 m (TIAGo) and a revolute base locked at 0.7 rad (UR5): the hand
    pose equals Drake's on the whole URDF with those joints set to those values."""
    q_arm = np.array([1.2, -0.2, -1.5, 1.8, 1.2, 1.0, 0.3])
    urdf = tiago()
    lock = off_chain_locks(urdf, HAND, {"torso_lift_joint": 0.25})
    plant, H, names = load_arm_plant(urdf, HAND, lock_joints=lock)
    assert names == ARM
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, q_arm)
    X = H.CalcPoseInWorld(ctx)
    X_ref = hand_pose_in_full_plant(urdf, HAND, {"torso_lift_joint": 0.25, **dict(zip(ARM, q_arm))})
    assert np.allclose(X.GetAsMatrix4(), X_ref.GetAsMatrix4(), atol=1e-12)
    X_low = hand_pose_in_full_plant(urdf, HAND, dict(zip(ARM, q_arm)))  # torso at 0: 25 cm lower
    assert X_ref.translation()[2] - X_low.translation()[2] == pytest.approx(0.25, abs=1e-12)

    ur5, hand, _ = example_robot_urdf("ur5")
    plant, H, names = load_arm_plant(ur5, hand, lock_joints={"shoulder_pan_joint": 0.7})
    q = np.array([-1.3, 1.6, -1.9, -1.57, 0.4])
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, q)
    X_ref = hand_pose_in_full_plant(ur5, hand, {"shoulder_pan_joint": 0.7, **dict(zip(names, q))})
    assert np.allclose(H.CalcPoseInWorld(ctx).GetAsMatrix4(), X_ref.GetAsMatrix4(), atol=1e-12)


def test_a_lock_value_outside_the_joint_range_is_refused_naming_it():
    with pytest.raises(QmtInputError, match=r"torso_lift_joint: 0.5 is outside the joint's range \[0, 0.35\]"):
        load_arm_plant(tiago(), HAND, lock_joints=off_chain_locks(tiago(), HAND, {"torso_lift_joint": 0.5}))


def test_off_chain_locks_every_joint_off_the_base_to_hand_chain():
    urdf = tiago()
    with pytest.raises(QmtInputError, match="are not on the chain from the base") as e:
        load_arm_plant(urdf, HAND, lock_joints={"torso_lift_joint": 0.25})
    assert "head_1_joint" in str(e.value) and "\n" not in str(e.value)
    lock = off_chain_locks(urdf, HAND, {"torso_lift_joint": 0.25})
    movable = {j.get("name") for j in ET.parse(urdf).getroot().findall("joint") if j.get("type") != "fixed"}
    assert set(lock) == movable - set(ARM)  # everything but the arm, the torso at its value, the rest at 0
    assert lock["torso_lift_joint"] == 0.25 and lock["head_1_joint"] == 0.0 and lock["wheel_left_joint"] == 0.0


def test_a_bad_inertia_warns_off_the_moving_chain_and_is_refused_on_it():
    urdf = tiago()
    lock = off_chain_locks(urdf, HAND, {"torso_lift_joint": 0.25})
    with pytest.warns(UserWarning, match="'base_antenna_left_link' has a rotational inertia.*does not move"):
        load_arm_plant(urdf, HAND, lock_joints=lock)
    root = ET.parse(urdf).getroot()  # the antenna's inertia moved onto the wrist: refused
    bad = next(lk for lk in root.findall("link") if lk.get("name") == "base_antenna_left_link").find("inertial")
    wrist = next(lk for lk in root.findall("link") if lk.get("name") == "arm_6_link")
    wrist.remove(wrist.find("inertial"))
    wrist.append(bad)
    with pytest.raises(QmtInputError, match="'arm_6_link' has a rotational inertia that no body has"):
        load_arm_plant(ET.tostring(root, encoding="unicode"), HAND, lock_joints=lock)


def test_the_urdf_limits_are_the_defaults_and_the_scenario_overrides_them(sc, tmp_path):
    full = full_drake_plant(tiago())
    starts = [full.GetJointByName(j).velocity_start() for j in ARM]
    np.testing.assert_array_equal(sc.velocity_limit_rad_s, full.GetVelocityUpperLimits()[starts])
    effort = {full.get_joint_actuator(i).joint().name(): full.get_joint_actuator(i).effort_limit()
              for i in full.GetJointActuatorIndices()}
    np.testing.assert_array_equal(sc.torque_limit_Nm[:5], [effort[j] for j in ARM[:5]])  # 6, 7: a differential
    assert sc.torque_limit_Nm[5:].tolist() == [6.6, 6.6]  # ... which Drake skips; the URDF's <limit effort>
    mine = load_spatial_scenario(edited(tmp_path, lambda r: r["actuators"].update(torque_limit_Nm=[20.0] * 7)))
    assert mine.torque_limit_Nm.tolist() == [20.0] * 7


def test_gear_ratio_and_rotor_inertia_are_optional_for_the_ideal_actuator(sc, tmp_path):
    assert sc.drive["gear_ratio"].tolist() == [1.0] * 7 and not sc.drive["reflected_inertia_kgm2"].any()
    assert not sc.drive["given"]
    motor = {"torque_constant_Nm_per_A": 0.1, "resistance_ohm": 1.0, "voltage_limit_V": 48.0}
    with pytest.raises(QmtInputError, match="declare no drake:gear_ratio.*actuator section's gear_ratio"):
        load_spatial_scenario(edited(tmp_path, lambda r: r["actuators"].update(motor=motor)))


def test_package_takes_any_urdf_of_an_installed_package_and_points_to_urdf_otherwise(tmp_path):
    urdf = tiago()
    assert package_urdf("example-robot-data/tiago_description/robots/tiago.urdf")[0] == urdf
    assert package_urdf("example-robot-data/tiago.urdf")[0] == urdf
    for ref in ("example-robot-data/no_such_robot", "no-such-description-package/arm"):
        with pytest.raises(QmtInputError, match="for a URDF file of your own.*urdf: <path>|urdf: <path> for a URDF file of your own"):
            package_urdf(ref)
    with pytest.raises(QmtInputError, match="give hand_frame"):
        load_spatial_scenario(edited(tmp_path, lambda r: r["arm"].pop("hand_frame")))


def test_tiago_plans_and_is_carried(sc):
    """The worked example of docs/arms.md: the arm planned within every limit and carried to the goal."""
    plan = plan_family_optimum(sc, family="line_cubic_velocity")
    assert plan.recheck["max"] <= 1.0
    res = simulate_spatial(sc, plan.trajectory)
    assert res["outcome"] == "carried" and res["final_goal_error_rad"] < 1e-6
