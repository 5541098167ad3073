"""One re-check for every plan, refined between samples, with the joint ranges (issues 27 item 3, 28 item 7).

A trajectory built to break a limit between the re-check's samples (its acceleration corner sits
between two samples) is caught by the refined spatial re-check, as by the planar one (the same
limits/refine.py), and the refined peak is confirmed by brute force: the plain maximum over a grid
100x denser. A motion that leaves a joint's URDF range between two in-range poses is reported, named
and flagged infeasible, and no time scaling is pretended to fix it.
"""

import numpy as np
import pytest
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.limits.spatial_columns import SpatialColumns, joint_range_by_name
from qmt_drake.planners.spatial_plan_io import finish_plan
from qmt_drake.planners.spatial_trajectory import PolyTrajectory, TimeScaled, check, scale_to_hold
from qmt_drake.spatial_task import load_spatial_scenario

KNOT_S = 0.30037  # an interior knot off every sample of the re-check grid


@pytest.fixture(scope="module")
def ur5():
    return load_spatial_scenario("ur5-suction-bins")


def _corner(sc, joint: str, amplitude_rad: float, knot_speed_rad_s: float):
    """A C1 cubic moving one joint out and on with its acceleration's largest jump at the knot."""
    j = sc.joint_names.index(joint)
    q0 = sc.q_poses_rad[1]
    t = np.array([0.0, KNOT_S, 0.6])
    Q = np.repeat(q0[:, None], 3, axis=1)
    Q[j] += amplitude_rad * np.array([0.0, 0.5, 1.0])
    V = np.zeros_like(Q)
    V[j, 1] = knot_speed_rad_s
    return PolyTrajectory(PiecewisePolynomial.CubicHermite(t, Q, V))


def test_a_limit_broken_between_samples_is_found_and_confirmed_by_100x_sampling(ur5):
    rate = ur5.recheck_rate_hz
    raw = _corner(ur5, "wrist_3_joint", 0.2, 1.0)
    k = np.sqrt(check(ur5, raw, rate)["joint_acceleration"] / 0.9999)  # sampled peak 0.9999 ...
    traj = TimeScaled(raw, k)
    sampled = check(ur5, traj, rate)
    refined = check(ur5, traj, rate, refine=True)
    dense = check(ur5, traj, 100 * rate)  # the independent check: a plain maximum 100x denser
    assert sampled["joint_acceleration"] <= 1.0 < dense["joint_acceleration"]  # ... but not between
    assert dense["joint_acceleration"] <= refined["joint_acceleration"] <= dense["joint_acceleration"] * (1 + 1e-4)
    assert refined["binding"] == "joint_acceleration[wrist_3_joint]"
    assert refined["binding_time_s"] == pytest.approx(k * KNOT_S, abs=1e-9)
    # held with the refinement, the motion holds on the dense grid too; held on the samples, it did not
    held, k_held = scale_to_hold(ur5, traj, rate, refine=True)
    assert k_held > 1.0 and check(ur5, held, 100 * rate)["max_timed"] <= 1.0
    assert scale_to_hold(ur5, traj, rate)[1] == 1.0


def test_every_plan_names_its_binding_limit_where_it_binds(ur5):
    raw = _corner(ur5, "shoulder_lift_joint", 0.15, 0.6)
    plan = finish_plan(ur5, "corner", raw, [0.0, 0.6], 0.0, {})
    rc = plan.recheck
    ratios = {k: v for k, v in rc.items() if k in plan.check.peak_ratios}
    assert rc["binding"].split("[")[0] == max(ratios, key=ratios.get)
    cols = SpatialColumns(ur5)
    q, qd, qdd = plan.trajectory.sample(np.array([rc["binding_time_s"]]))
    at = cols.columns(q, qd, qdd)[0]
    assert at[[lab[1] for lab in cols.column_labels].index(rc["binding"])] == pytest.approx(rc["max"], rel=1e-12)
    assert plan.check.feasible and rc["max"] <= 1.0


def test_a_joint_leaving_its_range_between_poses_is_reported_and_flagged(ur5):
    """The UR5's wrist 3 (the spin about the cup's axis, which the grip does not feel at rest) goes from
    0.01 rad inside its upper limit back there over a hump past that limit between the two poses."""
    sc = ur5
    j = sc.joint_names.index("wrist_3_joint")
    lower, upper = joint_range_by_name(sc.plant, sc.joint_names)
    q0 = sc.q_poses_rad[1].copy()
    q0[j] = upper[j] - 0.01
    Q = np.repeat(q0[:, None], 2, axis=1)
    V = np.zeros_like(Q)
    V[j] = [0.1, -0.1]
    traj = PolyTrajectory(PiecewisePolynomial.CubicHermite(np.array([0.0, 2.0]), Q, V))
    dense = traj.sample(np.linspace(0.0, 2.0, 200001))[0][:, j]
    assert dense.max() > upper[j] + 0.03  # the hump, by brute force
    plan = finish_plan(sc, "hump", traj, [0.0, 2.0], 0.0, {})
    rc = plan.recheck
    assert rc["binding"] == "joint_range[wrist_3_joint]"
    half = 0.5 * (upper[j] - lower[j])
    assert rc["joint_range"] == pytest.approx(abs(dense.max() - 0.5 * (upper[j] + lower[j])) / half, rel=1e-6)
    assert not plan.check.feasible and rc["max"] > 1.0 and rc["max_timed"] <= 1.0
    assert plan.hold_scale == 1.0  # slowing down cannot bring a joint back into its range


def test_toppra_path_kept_inside_the_ranges_where_the_spline_would_overshoot():
    """Waypoints along a joint's upper limit: the C2 spline overshoots it between them (seen by brute
    force), the path joint_path gives with the ranges does not."""
    from qmt_drake.planners.spatial_toppra import joint_path

    Q = np.array([[0.0, 0.5], [0.8, 0.6], [1.0, 0.7], [0.3, 0.8], [0.0, 0.9]])
    lower, upper = np.array([-1.0, -1.0]), np.array([1.0, 1.0])
    free, kept = joint_path(Q), joint_path(Q, lower, upper)
    s = np.linspace(free.start_time(), free.end_time(), 100001)
    assert free.vector_values(s)[0].max() > upper[0] + 1e-3
    q = kept.vector_values(s)
    assert np.all(q <= upper[:, None]) and np.all(q >= lower[:, None])
    assert np.allclose(kept.vector_values(free.get_segment_times()).T, Q, atol=1e-12)
