"""Say which limit binds (issue 28 item 8): an impossible path names the limit, the joint, the path
point and the ratio at rest; the re-check names the binding term of every plan.

The shoulder's torque limit of the shipped UR5 bin task is set below what gravity alone needs
somewhere on the path (computed here by Drake's own MultibodyPlant with the box welded to the hand,
not by the planner's SpatialChain); TOPP-RA must refuse naming that joint, the ratio and the N m.
"""

import re

import numpy as np
import pytest
import yaml

from qmt_drake.errors import QmtInputError
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.planners.spatial_methods import plan_toppra_spatial
from qmt_drake.spatial_task import SCENARIO_DIR, load_spatial_scenario
from tests.spatial_fixtures import shipped_toppra

JOINT = "shoulder_lift_joint"


def _gravity_torque_Nm(sc, Q) -> np.ndarray:
    """(K,) |torque| the shoulder needs to hold each configuration still, by Drake's plant."""
    plant, _, names = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, carried=sc.body.as_dict())
    ctx = plant.CreateDefaultContext()
    j = plant.GetJointByName(JOINT)
    out = []
    for q in Q:
        for name, qj in zip(sc.joint_names, q):
            plant.GetJointByName(name).set_angle(ctx, qj)
        out.append(abs(plant.CalcGravityGeneralizedForces(ctx)[j.velocity_start()]))
    return np.array(out)


def test_toppra_names_the_joint_gravity_overloads(tmp_path):
    sc = load_spatial_scenario("ur5-suction-bins")
    need = _gravity_torque_Nm(sc, sc.q_path_rad)
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-suction-bins.yaml").read_text())
    raw["arm"]["package"] = "example-robot-data/ur5"
    j = sc.joint_names.index(JOINT)
    limit = round(0.93 * float(need.max()), 3)
    raw["actuators"]["torque_limit_Nm"][j] = limit
    raw["actuators"].pop("motor", None)  # its current limits would not match the lowered torque
    path = tmp_path / "ur5-weak-shoulder.yaml"
    path.write_text(yaml.safe_dump(raw))
    weak = load_spatial_scenario(path)
    with pytest.raises(QmtInputError) as exc:
        plan_toppra_spatial(weak)
    msg = str(exc.value)
    assert "\n" not in msg and f"motor_torque[{JOINT}] needs" in msg and "at rest" in msg and "path point s =" in msg
    ratio, value, lim = (float(x) for x in re.search(r"needs ([\d.]+) of its limit at rest \(([\d.]+) N m of ([\d.]+) N m\)",
                                                     msg).groups())
    assert lim == pytest.approx(limit, rel=1e-3)
    # the path is a spline through q_path; at rest its worst point needs at least the waypoints' worst
    assert ratio >= need.max() / limit * (1 - 1e-3) and ratio < 1.2
    assert value == pytest.approx(ratio * limit, rel=1e-3)


def test_a_toppra_plan_names_its_binding_limit():
    plan = shipped_toppra("ur5-suction-bins")
    rc = plan.recheck
    assert rc["binding"] == "suction" and rc["max"] == rc["suction"] > 0.999  # time-optimal: on the grip
    assert 0.0 <= rc["binding_time_s"] <= plan.duration_s


def test_drakes_toppra_names_the_joint_gravity_overloads():
    from qmt_drake.planners.spatial_toppra import joint_path, plan_drake_toppra

    sc = load_spatial_scenario("ur5-suction-bins")
    plant, _, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints)  # the arm alone
    ctx = plant.CreateDefaultContext()
    j = plant.GetJointByName(JOINT).velocity_start()
    need = []
    for q in sc.q_path_rad:
        plant.SetPositions(ctx, q)
        need.append(abs(plant.CalcGravityGeneralizedForces(ctx)[j]))
    torque = np.array(sc.torque_limit_Nm, float)
    torque[j] = 0.9 * max(need)
    with pytest.raises(QmtInputError) as exc:
        plan_drake_toppra(joint_path(sc.q_path_rad), plant, velocity_limit=sc.velocity_limit_rad_s,
                          acceleration_limit=sc.acceleration_limit_rad_s2, torque_limit=torque, n_grid=200)
    msg = str(exc.value)
    ratio = float(re.search(rf"joint_torque\[{JOINT}\] needs ([\d.]+) of its limit at rest", msg).group(1))
    assert ratio >= 1.0 / 0.9 * (1 - 1e-3)
