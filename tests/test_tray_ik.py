"""Seed 002 IK, URDF and waypoints: IK against Drake's forward kinematics of the URDF, the seed's
printed joints, bad input, the waypoint spacing laws."""


import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from qmt_drake.errors import QmtInputError
from qmt_drake.tray import crane_ik
from qmt_drake.tray.cosim import URDF_PATH
from qmt_drake.tray.waypoints import line_waypoints, seed_motion, spacing


@pytest.fixture(scope="module")
def fk():
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(URDF_PATH))
    plant.Finalize()
    ctx = plant.CreateDefaultContext()

    def tray_pose(theta):
        plant.SetPositions(ctx, theta)
        X = plant.CalcRelativeTransform(ctx, plant.world_frame(), plant.GetFrameByName("tray"))
        return X.translation(), X.rotation().matrix()
    return tray_pose


@pytest.mark.parametrize("xy", [(0.04, 0.4), (0.4, 0.4), (0.25, 0.45), (0.35, 0.5)])
def test_ik_puts_the_urdf_tray_level_at_the_point(fk, xy):
    theta = crane_ik.tray_ik(*xy)
    p, R = fk(theta)
    np.testing.assert_allclose([p[0], p[2]], xy, atol=1e-12)
    np.testing.assert_allclose(R[:, 2], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(crane_ik.tray_fk(theta), [xy[0], xy[1], 0.0], atol=1e-12)


def test_the_seeds_printed_joints_fit_a_tool_frame_at_the_makers_joint_7():
    # Table 1 geometry misses the printed joints by up to 0.2 rad ...
    assert np.max(np.abs(crane_ik.seed_joint_residual())) > 0.1
    # ... a tool offset near L0 + 0.019 m (the maker's wrist-pitch -> joint-7 distance) fits them
    h, res = crane_ik.fit_tool_offset()
    assert abs(h - (crane_ik.TABLE1.L0 + 0.019)) < 0.003
    assert res < 0.015
    # the printed start is not level by exactly the printed phi
    assert crane_ik.tray_fk(crane_ik.SEED_START_THETA_RAD)[2] == pytest.approx(-0.0168, abs=1e-4)


@pytest.mark.parametrize("xy", [(0.7, 0.4), (0.0, 1.0), (-0.3, 0.2), (float("nan"), 0.4)])
def test_bad_tray_points_are_one_line_errors(xy):
    with pytest.raises(QmtInputError) as e:
        crane_ik.tray_ik(*xy)
    assert "\n" not in str(e.value)


def test_spacing_laws_and_the_line():
    s1, s15 = spacing(1000, 1.0), spacing(1000, 1.5)
    assert s1[0] == 0 and s1[-1] == 1 and np.allclose(np.diff(s1), 1e-3)
    assert np.all(np.diff(s15) > 0) and np.diff(s15)[0] < np.diff(s15)[-1]
    assert np.diff(s15)[-1] == pytest.approx(1.5e-3, rel=1e-2)  # ends at 1.5x the mean speed
    xy, theta = line_waypoints((0.04, 0.4), (0.4, 0.4), 100, 1.5)
    fkp = np.array([crane_ik.tray_fk(t) for t in theta])
    np.testing.assert_allclose(fkp[:, :2], xy, atol=1e-12)
    np.testing.assert_allclose(fkp[:, 2], 0, atol=1e-12)
    sched = seed_motion(1.5, n=100)
    assert sched.phases["move"][1] - sched.phases["move"][0] == pytest.approx(5.0)
    np.testing.assert_allclose(sched.goal_at(sched.phases["return"][1] + 0.1), 0, atol=1e-12)
    with pytest.raises(QmtInputError):
        spacing(10, -1.0)
