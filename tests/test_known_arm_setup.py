"""A known arm of example-robot-data set up from the package name alone: its face axis, no seed_rad, no
limits section (a new user's first scenario).

The face axis of each known arm is checked against Drake's kinematics of its URDF: a wrist's last joint
rolls the tool about the axis the tool points along, so the face axis (in the hand frame) must be
parallel to the last chain joint's axis."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from qmt_drake.errors import QmtInputError
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.model.urdf_package import EXAMPLE_ARMS, example_face_axis, example_robot_urdf
from qmt_drake.spatial_task import load_spatial_scenario


@pytest.mark.parametrize("name", sorted(EXAMPLE_ARMS))
def test_face_axis_is_the_last_joint_axis(name):
    try:
        path, hand, lock = example_robot_urdf(name)
    except QmtInputError as exc:
        pytest.skip(str(exc))
    plant, H, names = load_arm_plant(path, hand, lock_joints=lock)
    ctx = plant.CreateDefaultContext()
    last = plant.GetJointByName(names[-1])
    X_WC, X_WH = last.frame_on_child().CalcPoseInWorld(ctx), H.CalcPoseInWorld(ctx)
    axis_W = X_WC.rotation().matrix() @ last.revolute_axis()
    face_W = X_WH.rotation().matrix() @ np.asarray(example_face_axis(f"example-robot-data/{name}"))
    assert np.linalg.norm(np.cross(axis_W, face_W)) < 1e-9, (name, axis_W, face_W)
    # and it points out of the wrist, towards the hand frame (where the hand frame is off the wrist)
    assert face_W @ (X_WH.translation() - X_WC.translation()) >= 0.0


def _first_scenario(tmp_path: Path, arm: str, poses, **task) -> Path:
    """The smallest spatial scenario a user writes for a known arm: no face_axis, seed_rad or limits."""
    data = {
        "kind": "spatial_transfer", "name": f"{arm}-first",
        "arm": {"package": f"example-robot-data/{arm}"},
        "actuators": {"acceleration_limit_rad_s2": [10.0] * 6, "jerk_limit_rad_s3": [200.0] * 6},
        "payload": {"mass_kg": 0.3, "com_m": [0.0, 0.0, 0.04], "inertia_kgm2": [5e-4, 5e-4, 3e-4]},
        "hand": {"kind": "suction", "cup_radius_m": 0.015, "vacuum_force_N": 20.0, "friction": 0.5},
        "task": {"face_normal": [0.0, 0.0, -1.0], "poses_m": poses, **task},
    }
    path = tmp_path / f"{arm}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_z1_from_its_package_name_alone(tmp_path):
    """Unitree Z1: its tool points along gripperStator's x axis; without the known face axis the
    face-down poses below were refused as outside the joint limits."""
    try:
        example_robot_urdf("z1")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    poses = [[0.35, -0.15, 0.10], [0.35, 0.15, 0.10]]
    sc = load_spatial_scenario(_first_scenario(tmp_path, "z1", poses))
    assert sc.check_rate_hz == 200.0
    for q, p in zip(sc.q_poses_rad, poses):
        ep, ea = sc.ik.errors(q, np.array(p), normal=np.array([0.0, 0.0, -1.0]))
        assert ep < 1e-6 and ea < 1e-6
    again = load_spatial_scenario(_first_scenario(tmp_path, "z1", poses))
    assert np.array_equal(sc.q_path_rad, again.q_path_rad)  # the starts are fixed: the same path every run


def test_seedless_path_moves_least_among_the_starts(tmp_path):
    """Without seed_rad the kept path is the one of least joint motion among the starts that reach it."""
    try:
        example_robot_urdf("ur5")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    poses = [[0.45, -0.30, 0.10], [0.45, -0.30, 0.35], [0.30, 0.45, 0.35], [0.30, 0.45, 0.10]]
    sc = load_spatial_scenario(_first_scenario(tmp_path, "ur5", poses, transfer_points=5))
    motion = float(np.abs(np.diff(sc.q_path_rad, axis=0)).sum())
    pts, normals = sc.path_points_m, sc.path_normals
    others = []
    for start in sc.ik.starts():
        try:
            others.append(sc.ik.solve_path(pts, normals=normals, seed=start, max_joint_step_rad=1.0))
        except QmtInputError:
            pass
    assert others
    # the kept path is the least-motion one of the first successes, and no start's path is much shorter
    assert motion <= min(float(np.abs(np.diff(q, axis=0)).sum()) for q in others[:3]) + 1e-12


def test_seedless_branch_jump_says_add_points(tmp_path):
    """The base turns 1.57 rad between the lifts: without inner points every start's path jumps."""
    try:
        example_robot_urdf("ur5")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    poses = [[0.45, -0.30, 0.10], [0.45, -0.30, 0.35], [0.30, 0.45, 0.35], [0.30, 0.45, 0.10]]
    with pytest.raises(QmtInputError, match=r"add points in between \(from each of 12 IK starts\)"):
        load_spatial_scenario(_first_scenario(tmp_path, "ur5", poses))


def test_seedless_unreachable_pose_names_the_starts(tmp_path):
    try:
        example_robot_urdf("z1")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    with pytest.raises(QmtInputError, match="none of 12 IK starts reached it"):
        load_spatial_scenario(_first_scenario(tmp_path, "z1", [[0.35, -0.15, 0.10], [3.0, 0.0, 0.1]]))
