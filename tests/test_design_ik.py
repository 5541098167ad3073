"""Inverse kinematics over every branch, and the numpy collision test against Drake SceneGraph."""

import numpy as np
import pytest

from qmt_drake.design import arm_types as A
from qmt_drake.design import ik


@pytest.mark.parametrize("T", A.TYPES)
def test_every_branch_reproduces_the_pose_and_the_original_is_found(T):
    rng = np.random.default_rng(7)
    at = A.arm_type(T)
    L = rng.integers(1, 16, (150, 6)) * A.LEVEL_STEP_M
    L[:, 4] = 0
    o = at.origins(L)
    q = rng.uniform(-np.pi, np.pi, (150, 6))
    pose = A.forward(at, o, q)
    sol = ik.solve(at, o, pose.tool_position, pose.tool_rotation, both_wrists=True)
    n, B = sol.ok.shape
    idx = np.flatnonzero(sol.ok.ravel())
    p2 = A.forward(at, o[idx // B], sol.q.reshape(-1, 6)[idx])
    np.testing.assert_allclose(p2.tool_position, pose.tool_position[idx // B], atol=1e-6)
    np.testing.assert_allclose(p2.tool_rotation, pose.tool_rotation[idx // B], atol=1e-6)
    # the configuration we started from is among the roots unless it is near-singular
    wc = pose.points[:, 4]
    Jp = np.cross(pose.axes[:, :3], wc[:, None] - pose.points[:, :3])
    regular = np.abs(np.linalg.det(Jp)) > 1e-2
    d = np.abs(ik._wrap(sol.q[:, :, :3] - q[:, None, :3])).max(axis=2)
    found = np.any((d < 1e-4) & sol.ok, axis=1)
    assert found[regular].mean() >= 0.97
    # a 3R positioning chain has at most 4 roots, each with 2 wrist branches
    assert sol.ok[:, :sol.ok.shape[1] // 2].sum(axis=1).max() <= 4
    assert np.all(sol.ok.sum(axis=1) % 2 == 0)


def test_numpy_collision_agrees_with_scenegraph():
    from qmt_drake.design.tasks import load_task
    task = load_task("task2_welding_opening")
    L = np.array([0.3, 0.4, 0.5, 0.2, 0.0, 0.2])
    arm = A.build_plant("BP", L, boxes=task.boxes, link_radius_m=task.link_radius_m,
                        tool_radius_m=task.tool_radius_m)
    at = A.arm_type("BP")
    dctx = arm.diagram.CreateDefaultContext()
    ctx = arm.plant.GetMyMutableContextFromRoot(dctx)
    rng = np.random.default_rng(11)
    q = rng.uniform(-np.pi, np.pi, (150, 6))
    pose = A.forward(at, at.origins(L), q)
    hit = ik.collides(pose.points, task.boxes, task.link_radius_m, task.tool_radius_m)
    dmin = []
    for k in range(q.shape[0]):
        arm.plant.SetPositions(ctx, q[k])
        dmin.append(arm.min_env_distance(ctx))
    dmin = np.array(dmin)
    assert 0.1 < hit.mean() < 0.9   # the sample has both outcomes
    # Drake penetration -> numpy says collision (up to the sampling along a link, < 5 mm)
    assert np.all(hit[dmin < -0.005])
    # numpy collision -> Drake distance below the grown box's corner excess r (sqrt(3) - 1)
    assert np.all(dmin[hit] < task.link_radius_m * (np.sqrt(3) - 1) + 1e-9)


@pytest.mark.parametrize("T", A.TYPES)
def test_branch_labels_separate_roots_and_change_only_at_singularities(T):
    """The four labels name distinct roots at regular points, and along a continuous joint path a
    label changes only where the positioning Jacobian is (near) singular."""
    rng = np.random.default_rng(5)
    at = A.arm_type(T)
    L = rng.integers(1, 16, (120, 6)) * A.LEVEL_STEP_M
    L[:, 4] = 0
    o = at.origins(L)
    q = rng.uniform(-np.pi, np.pi, (120, 6))
    pose = A.forward(at, o, q)
    sol = ik.solve(at, o, pose.tool_position, pose.tool_rotation)
    Jp = np.cross(pose.axes[:, :3], pose.points[:, 4][:, None] - pose.points[:, :3])
    regular = np.abs(np.linalg.det(Jp)) > 1e-2
    distinct = np.array([len(set(sol.label[n, sol.ok[n]])) == sol.ok[n].sum() for n in range(120)])
    assert distinct[regular].mean() >= 0.97
    # the label solve() gives each root is the label of that configuration
    n, b = np.nonzero(sol.ok)
    np.testing.assert_array_equal(ik.labels_of(at, o[n], sol.q[n, b]), sol.label[n, b])
    # paths: 60 arms x 300 steps of a straight joint-space segment
    t = np.linspace(0, 1, 300)
    changes_regular = 0
    for k in range(60):
        qa, qb = q[k], q[k] + rng.uniform(-1.5, 1.5, 6)
        qp = qa + t[:, None] * (qb - qa)
        lab = ik.labels_of(at, o[k], qp)
        P = A.forward(at, np.broadcast_to(o[k], (300, 7, 3)), qp)
        d = np.linalg.det(np.cross(P.axes[:, :3], P.points[:, 4][:, None] - P.points[:, :3]))
        ch = np.flatnonzero(lab[1:] != lab[:-1])
        scale = np.median(np.abs(d))
        changes_regular += sum(1 for i in ch if np.sign(d[i]) == np.sign(d[i + 1])
                               and min(abs(d[i]), abs(d[i + 1])) > 1e-2 * scale)
    assert changes_regular == 0
