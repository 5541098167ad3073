"""Arm types: kinematics against Drake (plant built in code and from the written URDF), lengths
changed per context, the equivalences the seed's tables imply, bad inputs."""

import numpy as np
import pytest

from qmt_drake.design import arm_types as A
from qmt_drake.errors import QmtInputError


def _drake_pose_and_J(arm, ctx, q):
    from pydrake.multibody.tree import JacobianWrtVariable
    pl = arm.plant
    pl.SetPositions(ctx, q)
    X = arm.tool_frame.CalcPoseInWorld(ctx)
    Jd = pl.CalcJacobianSpatialVelocity(ctx, JacobianWrtVariable.kQDot, arm.tool_frame, np.zeros(3),
                                        pl.world_frame(), pl.world_frame())
    return X, np.vstack([Jd[3:], Jd[:3]])


@pytest.mark.parametrize("T", A.TYPES)
def test_kinematics_matches_drake_and_lengths_change_per_context(T):
    rng = np.random.default_rng(hash(T) % 1000)
    L = rng.integers(1, 16, 6) * A.LEVEL_STEP_M
    L[4] = 0
    at = A.arm_type(T)
    arm = A.build_plant(T, L)
    ctx = arm.plant.CreateDefaultContext()
    L2 = rng.integers(0, 16, 6) * A.LEVEL_STEP_M
    for lengths, setl in ((L, False), (L2, True)):
        if setl:
            arm.set_lengths(ctx, lengths)   # same plant, new lengths
        q = rng.uniform(-np.pi, np.pi, (3, 6))
        pose = A.forward(at, at.origins(lengths), q)
        Jn = A.jacobian(pose)
        for k in range(3):
            X, Jd = _drake_pose_and_J(arm, ctx, q[k])
            np.testing.assert_allclose(X.translation(), pose.tool_position[k], atol=1e-12)
            np.testing.assert_allclose(X.rotation().matrix(), pose.tool_rotation[k], atol=1e-12)
            np.testing.assert_allclose(Jd, Jn[k], atol=1e-12)


def test_urdf_parses_and_agrees():
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant
    T, L = "BF", np.array([0.2, 0.1, 0.3, 0.15, 0.0, 0.1])
    pl = MultibodyPlant(0.0)
    Parser(pl).AddModelsFromString(A.urdf_text(T, L), "urdf")
    pl.Finalize()
    ctx = pl.CreateDefaultContext()
    at = A.arm_type(T)
    q = np.array([0.3, -1.1, 0.7, 0.2, 1.3, -0.4])
    pl.SetPositions(ctx, q)
    X = pl.GetFrameByName("tool").CalcPoseInWorld(ctx)
    pose = A.forward(at, at.origins(L), q[None])
    np.testing.assert_allclose(X.translation(), pose.tool_position[0], atol=1e-9)
    np.testing.assert_allclose(X.rotation().matrix(), pose.tool_rotation[0], atol=1e-9)


def _E(T, levels6, task):
    from qmt_drake.design.problem import DesignProblem, genes_from_levels
    return DesignProblem(task, T).fitness_E(genes_from_levels(np.array(levels6))[None])[0]


def test_equivalences_implied_by_the_seed_tables():
    from qmt_drake.design.tasks import load_task
    task = load_task("task1_welding_plate").without_obstacles()
    # second link 0: PB, PF, PT are one arm (Table 1: b05500, b08200, b00a00 tie)
    e = [_E(T, [5, 0, 3, 2, 0, 1], task) for T in ("PB", "PF", "PT")]
    assert e[0] > 0 and e[0] == e[1] == e[2]
    # L3 and L4 are collinear: only their sum matters
    assert _E("PB", [5, 0, 5, 0, 0, 1], task) == pytest.approx(_E("PB", [5, 0, 1, 4, 0, 1], task), rel=1e-12)
    # first link 0: BP and FP are one arm (Table 1: 0db000, 0d4700 tie)
    assert _E("BP", [0, 4, 3, 2, 0, 1], task) == _E("FP", [0, 4, 3, 2, 0, 1], task) > 0
    # with a nonzero second link they differ (the test can fail)
    assert _E("PB", [5, 2, 3, 2, 0, 1], task) != _E("PT", [5, 2, 3, 2, 0, 1], task)


def test_excluded_FB_is_a_spherical_joint():
    # reconstruction check: FB (not among the seed's 10) puts axes 1, 2, 3 through one point
    at = A.arm_type("FB")
    o = at.origins([0.3, 0.2, 0.2, 0.2, 0.0, 0.1])
    p = o[1]
    for i in range(3):
        d = p - o[i]
        assert np.linalg.norm(np.cross(d, at.axes[i])) < 1e-12
    # BF (kept) does not
    at = A.arm_type("BF")
    o = at.origins([0.3, 0.2, 0.2, 0.2, 0.0, 0.1])
    assert np.linalg.norm(np.cross(o[1] - o[2], at.axes[2])) > 1e-3 or \
        np.linalg.norm(np.cross(o[0] - o[2], at.axes[2])) > 1e-3


def test_genes_and_bad_inputs():
    np.testing.assert_array_equal(A.levels_from_gene("0db000"), [0, 13, 11, 0, 0, 0])
    assert A.gene_from_levels([11, 0, 5, 5, 0, 0]) == "b05500"
    with pytest.raises(QmtInputError, match="unknown"):
        A.arm_type("XP")
    with pytest.raises(QmtInputError, match="0-15"):
        A.lengths_from_levels([0, 16, 3, 0, 0, 0])
    with pytest.raises(QmtInputError, match="hex"):
        A.levels_from_gene("0db00g")
