"""The spatial family optimum keeps every joint inside its URDF range along the whole path: with the
UR5's wrist_1 range tightened below where the unguarded optimum's via cubic swings (-1.24 rad; the task
poses stay below -1.77 rad), the optimum still returns a plan the shared re-check finds within every
limit, and no sample of it, 10x finer than that re-check, leaves the range."""

import numpy as np
import pytest

from qmt_drake import load_scenario
from qmt_drake.limits.spatial_columns import joint_range_by_name
from qmt_drake.planners.spatial_families import spatial_family
from qmt_drake.planners.spatial_search import plan_family_optimum, range_excess_rad

WRIST_1_UPPER_RAD = -1.6


@pytest.fixture(scope="module")
def tight_ur5():
    sc = load_scenario("ur5-suction-bins")
    joint = sc.plant.GetJointByName("wrist_1_joint")
    joint.set_position_limits(joint.position_lower_limits(), np.array([WRIST_1_UPPER_RAD]))
    return sc


def test_range_excess_is_exact_between_samples(tight_ur5):
    """range_excess_rad (breaks and stationary points) against 200001 samples of the same cubic: the
    unguarded optimum's starting shape (shares ~ sqrt of the joint distances) leaves the range."""
    sc = tight_ur5
    lower, upper = joint_range_by_name(sc.plant, sc.joint_names)
    assert np.all(sc.q_poses_rad <= upper) and np.all(sc.q_poses_rad >= lower)
    d = np.sqrt(np.linalg.norm(np.diff(sc.q_poses_rad, axis=0), ord=np.inf, axis=1))
    pp = spatial_family(sc, "via_cubic").trajectory(d / d.sum()).pp
    q = pp.vector_values(np.linspace(pp.start_time(), pp.end_time(), 200001)).T
    dense = max(0.0, (q - upper).max(), (lower - q).max())
    exact = range_excess_rad(pp, lower, upper)
    assert dense > 0.1  # the range binds here
    assert dense - 1e-12 <= exact <= dense + 1e-9  # the samples never exceed it (but for rounding)


def test_family_optimum_stays_inside_a_binding_range(tight_ur5):
    sc = tight_ur5
    plan = plan_family_optimum(sc)
    assert plan.feasible, plan.info.get("least_violating")
    lower, upper = joint_range_by_name(sc.plant, sc.joint_names)
    tr = plan.trajectory
    q = tr.sample(np.linspace(0.0, tr.duration_s, int(tr.duration_s * 10 * sc.recheck_rate_hz) + 1))[0]
    assert np.all(q <= upper) and np.all(q >= lower)
    assert q[:, sc.joint_names.index("wrist_1_joint")].max() > WRIST_1_UPPER_RAD - 0.01  # it binds
