"""Ruckig's refusal names the limit that binds (issue 28 item 8): the shoulder's torque limit of the shipped
UR5 bin task set below what gravity alone needs at a task pose (by Drake's own MultibodyPlant with the
box welded to the hand, not by the planner's SpatialChain); no reduction of Ruckig's acceleration and jerk
limits can help there, and the refusal says which joint, the ratio at rest, the N m and the segment."""

import re

import numpy as np
import pytest
import yaml

from qmt_drake.errors import QmtInputError
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.planners.spatial_methods import plan_ruckig_spatial
from qmt_drake.spatial_task import SCENARIO_DIR, load_spatial_scenario

JOINT = "shoulder_lift_joint"


def _gravity_torque_Nm(sc, Q) -> np.ndarray:
    """(K,) |torque| the shoulder needs to hold each configuration still, by Drake's plant."""
    plant, _, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, carried=sc.body.as_dict())
    ctx = plant.CreateDefaultContext()
    j = plant.GetJointByName(JOINT)
    out = []
    for q in Q:
        for name, qj in zip(sc.joint_names, q):
            plant.GetJointByName(name).set_angle(ctx, qj)
        out.append(abs(plant.CalcGravityGeneralizedForces(ctx)[j.velocity_start()]))
    return np.array(out)


def test_ruckig_names_the_joint_gravity_overloads(tmp_path):
    sc = load_spatial_scenario("ur5-suction-bins")
    need = _gravity_torque_Nm(sc, sc.q_poses_rad)
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-suction-bins.yaml").read_text())
    raw["arm"]["package"] = "example-robot-data/ur5"
    limit = round(0.93 * float(need.max()), 3)
    raw["actuators"]["torque_limit_Nm"][sc.joint_names.index(JOINT)] = limit
    raw["actuators"].pop("motor", None)  # its current limits would not match the lowered torque
    path = tmp_path / "ur5-weak-shoulder.yaml"
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(QmtInputError) as exc:
        plan_ruckig_spatial(load_spatial_scenario(path))
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("Ruckig: ") and "segment " in msg
    assert f"motor_torque[{JOINT}] needs" in msg and "at rest" in msg and "gravity alone" in msg
    ratio, value, lim = (float(x) for x in re.search(r"needs ([\d.]+) of its limit at rest \(([\d.]+) N m of ([\d.]+) N m\)",
                                                     msg).groups())
    assert lim == pytest.approx(limit, rel=1e-3)
    # a segment ends at a task pose: at rest it needs at least what Drake says the worst pose of that segment needs
    k = int(re.search(r"segment (\d+) \(task pose", msg).group(1))
    assert ratio >= max(need[k - 1], need[k]) / limit * (1 - 1e-3)
    assert value == pytest.approx(ratio * limit, rel=1e-3)


@pytest.mark.parametrize("weak_joint", [0, 1])
def test_planar_ruckig_names_the_weak_joint(weak_joint):
    """The thesis's ch.3 arm with one motor's torque limit made a billion times smaller: no acceleration scale
    holds it within the time budget, and the refusal names that motor's column (not the other's)."""
    from qmt_drake.planners.baselines.ruckig_plan import plan_ruckig
    from qmt_drake.transfer_scenario import load_scenario

    base = load_scenario("thesis-ch3")
    lim = [float(x) for x in base.limits.motor_torque_limit_Nm]
    lim[weak_joint] *= 1e-9
    weak = load_scenario("thesis-ch3", overrides={"limits": {"motor_torque_limit_Nm": lim}})
    names = [c for c in weak.limit_set.column_names if c.startswith("motor_torque[")]
    for mode in ("cartesian_line", "joint"):
        p = plan_ruckig(weak, jerk_limit=10.0, mode=mode)
        msg = p.extra["infeasible"]
        assert not p.feasible and "too tight" in msg and "\n" not in msg
        ratio = float(re.search(rf"{re.escape(names[weak_joint])} is still at ([\d.e+]+) of its limit", msg).group(1))
        assert ratio > 1.0
