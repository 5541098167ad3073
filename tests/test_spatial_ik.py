"""SpatialIK: hand poses reached to 1e-6 m / 1e-6 rad (Drake forward kinematics), branches, paths."""

from pathlib import Path

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.model.spatial_ik import SpatialIK
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant

MODELS = Path(__file__).resolve().parents[1] / "models"


def make_ik(name):
    if name == "arm6":
        path, hand, lock = MODELS / "spatial" / "arm6.urdf", "hand", ()
    else:
        try:
            path, hand, lock = example_robot_urdf(name)
        except QmtInputError as exc:
            pytest.skip(str(exc))
    plant, H, _ = load_arm_plant(path, hand, lock_joints=lock)
    return SpatialIK(plant, H, name=name)


def drake_pose_errors(ik, q, p, R=None, n=None):
    """Independent check: Drake's own frame pose, not the polish's SpatialChain."""
    ik.plant.SetPositions(ik._ctx, q)
    X = ik.hand.CalcPoseInWorld(ik._ctx)
    ep = np.linalg.norm(X.translation() - p)
    if R is not None:
        c = np.clip((np.trace(R.T @ X.rotation().matrix()) - 1) / 2, -1, 1)
        return ep, np.arccos(c)
    m = X.rotation().matrix()[:, 2]
    return ep, np.arctan2(np.linalg.norm(np.cross(m, n)), m @ n)


@pytest.mark.parametrize("name", ["ur5", "panda", "arm6"])
def test_reachable_poses_are_reached(name):
    ik = make_ik(name)
    rng = np.random.default_rng(0)
    for _ in range(6):
        q0 = rng.uniform(np.maximum(ik.lower, -2.5), np.minimum(ik.upper, 2.5))
        p, R = ik.pose(q0)
        seed = q0 + rng.normal(0, 0.3, len(q0))
        q = ik.solve(p, rotation=R, seed=seed)
        ep, ea = drake_pose_errors(ik, q, p, R=R)
        assert ep <= 1e-6 and ea <= 1e-6
        qn = ik.solve(p, normal=R[:, 2], seed=seed)
        ep, ea = drake_pose_errors(ik, qn, p, n=R[:, 2])
        assert ep <= 1e-6 and ea <= 1e-6
        for x in (q, qn):
            assert np.all(x >= ik.lower - 1e-9) and np.all(x <= ik.upper + 1e-9)


def test_seed_selects_the_branch():
    """The UR5 reaches one pose with the elbow bent either way; each seed keeps its own."""
    ik = make_ik("ur5")
    q_up = np.array([0.3, -1.2, 1.4, -1.8, -1.57, 0.2])
    p, R = ik.pose(q_up)
    q_a = ik.solve(p, rotation=R, seed=q_up + 0.1)
    q_b = ik.solve(p, rotation=R, seed=np.array([0.3, -0.2, -1.4, -1.5, -1.57, 0.2]))
    assert np.sign(q_a[2]) > 0 > np.sign(q_b[2])  # elbow joint on opposite sides
    for q in (q_a, q_b):
        ep, ea = drake_pose_errors(ik, q, p, R=R)
        assert ep <= 1e-6 and ea <= 1e-6


def test_path_is_continuous_and_jumps_are_refused():
    ik = make_ik("ur5")
    q_start = np.array([0.0, -1.3, 1.6, -1.9, -1.57, 0.0])
    p0, R0 = ik.pose(q_start)
    line = p0 + np.linspace(0, 1, 25)[:, None] * np.array([0.0, 0.25, -0.1])
    normals = np.repeat(R0[:, 2][None], len(line), axis=0)
    Q = ik.solve_path(line, normals=normals, seed=q_start, max_joint_step_rad=0.3)
    assert np.abs(np.diff(Q, axis=0)).max() < 0.3
    for q, p in zip(Q, line):
        ep, ea = drake_pose_errors(ik, q, p, n=R0[:, 2])
        assert ep <= 1e-6 and ea <= 1e-6
    with pytest.raises(QmtInputError, match="path point 1 at .* jump"):
        ik.solve_path(line, normals=normals, seed=q_start, max_joint_step_rad=1e-4)


def test_unreachable_and_bad_targets_refused_in_one_line():
    ik = make_ik("ur5")
    seed = np.zeros(6)
    with pytest.raises(QmtInputError) as exc:
        ik.solve([3.0, 0.0, 0.0], normal=[0, 0, -1], seed=seed, what="task point 2")
    assert "task point 2 at [3.0, 0.0, 0.0] m" in str(exc.value) and "out of reach" in str(exc.value)
    assert "\n" not in str(exc.value)
    with pytest.raises(QmtInputError, match="not a proper rotation"):
        ik.solve([0.3, 0.1, 0.4], rotation=np.diag([1.0, 1.0, -1.0]), seed=seed)
    with pytest.raises(QmtInputError, match="no direction"):
        ik.solve([0.3, 0.1, 0.4], normal=[0, 0, 0], seed=seed)
    with pytest.raises(QmtInputError, match="not both"):
        ik.solve([0.3, 0.1, 0.4], normal=[0, 0, 1], rotation=np.eye(3), seed=seed)
