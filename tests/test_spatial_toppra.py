"""TOPP-RA on a 6-DOF UR5 suction pick-and-place path: Drake's Toppra agrees, the grip holds when sampled,
and the fast path (rows precomputed for all grid points, TOPP-RA's passes over toppra's Seidel LP)
equals toppra's own driver bit for bit and toppra's per-grid-point constraints to rounding."""

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.base import RowOptions
from qmt_drake.limits.contact_wrench import CarriedBody
from qmt_drake.limits.suction import GripModel, SuctionTerm
from qmt_drake.model.spatial_ik import SpatialIK
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant
from qmt_drake.planners.spatial_toppra import (
    joint_path,
    pick_and_place_waypoints,
    plan_drake_toppra,
    plan_toppra,
    recheck,
    toppra_problem,
)

PICK, PLACE, SEED = [0.45, -0.30, 0.10], [0.30, 0.45, 0.10], np.array([-0.6, -1.3, 1.6, -1.9, -1.57, 0.0])
BODY = CarriedBody(2.0, np.array([0.0, 0.0, 0.08]), np.diag([0.006, 0.006, 0.004]))


@pytest.fixture(scope="module")
def ur5():
    try:
        path, hand, lock = example_robot_urdf("ur5")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    plant, H, _ = load_arm_plant(path, hand, lock_joints=lock)
    ik = SpatialIK(plant, H, name="ur5")
    Q = pick_and_place_waypoints(ik, PICK, PLACE, lift_m=0.25, seed=SEED)
    return plant, ik, joint_path(Q), Q


def test_waypoints_reach_the_task_with_the_cup_down(ur5):
    plant, ik, pp, Q = ur5
    ends = [ik.pose(Q[0]), ik.pose(Q[-1])]
    for (p, R), target in zip(ends, (PICK, PLACE)):
        assert np.linalg.norm(p - target) <= 1e-6
        assert np.arccos(np.clip(-R[2, 2], -1, 1)) <= 1e-6  # face normal (hand z) points down


def test_toppra_equals_drake_toppra_on_joint_limits(ur5):
    plant, ik, pp, _ = ur5
    vel, acc = plant.GetVelocityUpperLimits(), np.full(6, 15.0)
    ours = plan_toppra(pp, ik.chain, velocity_limit=vel, acceleration_limit=acc, n_grid=1000)
    drake = plan_drake_toppra(pp, plant, velocity_limit=vel, acceleration_limit=acc, n_grid=1000)
    assert abs(ours["duration_s"] / drake["duration_s"] - 1) < 1e-6
    chk = recheck(ours, pp, ik.chain, [])
    assert np.all(chk["max_joint_speed_rad_s"] <= vel * (1 + 1e-4))  # 7e-6 over between grid points
    assert np.all(chk["max_joint_acceleration_rad_s2"] <= acc * 1.01)  # between grid points: curvature


def test_suction_plan_holds_and_is_needed(ur5):
    plant, ik, pp, _ = ur5
    vel, acc = plant.GetVelocityUpperLimits(), np.full(6, 15.0)
    g = plant.gravity_field().gravity_vector()
    term = SuctionTerm(GripModel(0.015, 40.0, 0.5), BODY, g)
    free = plan_toppra(pp, ik.chain, velocity_limit=vel, acceleration_limit=acc, n_grid=1000)
    held = plan_toppra(pp, ik.chain, velocity_limit=vel, acceleration_limit=acc, terms=[term], n_grid=1000)
    assert recheck(free, pp, ik.chain, [term])["suction"] > 1.5  # the joint limits alone drop the box
    ratio = recheck(held, pp, ik.chain, [term], refine=10)["suction"]
    assert 0.99 < ratio <= 1.0 + 1e-3  # active, and held when sampled 10x between grid points
    assert held["duration_s"] > free["duration_s"]


def test_refusals(ur5):
    plant, ik, pp, _ = ur5
    with pytest.raises(QmtInputError, match="pick-and-place point 0 at \\[2.0, 0.0, 0.1\\] m"):
        pick_and_place_waypoints(ik, [2.0, 0.0, 0.1], PLACE, lift_m=0.25, seed=SEED)
    heavy = SuctionTerm(GripModel(0.015, 10.0, 0.5), BODY, plant.gravity_field().gravity_vector())
    with pytest.raises(QmtInputError, match="no parameterisation"):
        plan_toppra(pp, ik.chain, velocity_limit=plant.GetVelocityUpperLimits(), acceleration_limit=np.full(6, 15.0),
                    terms=[heavy], n_grid=200)


def test_torque_limits_equal_drake_toppra(ur5):
    """Joint torque limits through SpatialChain (the existing MotorTorqueTerm, gear ratio 1) give the
    same duration as Drake's Toppra with its own inverse dynamics, the carried box welded in both."""
    from types import SimpleNamespace

    from qmt_drake.limits.motor_torque import MotorTorqueTerm
    from qmt_drake.model.spatial_chain import SpatialChain

    _, ik, pp, _ = ur5
    path, hand, lock = example_robot_urdf("ur5")
    plant, H, names = load_arm_plant(path, hand, lock_joints=lock, carried=BODY.as_dict())
    chain = SpatialChain(plant, H)
    vel, acc = plant.GetVelocityUpperLimits(), np.full(6, 15.0)
    torque = np.array([50.0, 50.0, 25.0, 6.0, 6.0, 6.0])
    arm = SimpleNamespace(gear_ratio=np.ones(6), joint_names=names, gravity_does_no_work=False)
    term = MotorTorqueTerm(arm, torque)
    ours = plan_toppra(pp, chain, velocity_limit=vel, acceleration_limit=acc, terms=[term], n_grid=1000)
    free = plan_toppra(pp, chain, velocity_limit=vel, acceleration_limit=acc, n_grid=1000)
    drake = plan_drake_toppra(pp, plant, velocity_limit=vel, acceleration_limit=acc, torque_limit=torque, n_grid=1000)
    assert ours["duration_s"] > free["duration_s"] * 1.05  # the torque limits bind
    assert abs(ours["duration_s"] / drake["duration_s"] - 1) < 1e-4
    assert recheck(ours, pp, chain, [term])["motor_torque"] <= 1.0 + 1e-3


def test_fast_path_equals_toppras_driver_and_its_per_gridpoint_constraints(ur5):
    """plan_toppra against (1) toppra's TOPPRA driver on the same constraints (the same LPs: equal bit
    for bit) and (2) the problem as toppra states it itself: its joint velocity and acceleration
    constraints and a SecondOrderConstraint that evaluates the grip's wrench one grid point at a time
    (rows neither multiplied out nor scaled): the same parameterisation to rounding."""
    import toppra
    from toppra.constraint import (
        DiscretizationType,
        JointAccelerationConstraint,
        JointVelocityConstraint,
        SecondOrderConstraint,
    )

    plant, ik, pp, _ = ur5
    vel, acc = plant.GetVelocityUpperLimits(), np.full(6, 15.0)
    term = SuctionTerm(GripModel(0.015, 40.0, 0.5), BODY, plant.gravity_field().gravity_vector())
    kw = dict(velocity_limit=vel, acceleration_limit=acc, terms=[term], n_grid=1000)
    ours = plan_toppra(pp, ik.chain, **kw)
    path, cons, grid = toppra_problem(pp, ik.chain, **kw)
    sdd, sd, _ = toppra.algorithm.TOPPRA(cons, path, gridpoints=grid, solver_wrapper="seidel") \
        .compute_parameterization(0.0, 0.0)
    assert np.array_equal(ours["sd"], sd) and np.array_equal(ours["sdd"], sdd)

    F, g = term.toppra_rows(RowOptions())
    calls = []

    def w_one(q, qd, qdd):
        calls.append(1)
        return term.toppra_w(ik.chain.evaluate(q[None], qd[None], qdd[None]))[0]

    interp = DiscretizationType.Interpolation
    plain = [JointVelocityConstraint(np.stack([-vel, vel], axis=1)),
             JointAccelerationConstraint(np.stack([-acc, acc], axis=1), discretization_scheme=interp),
             SecondOrderConstraint(w_one, lambda q: F, lambda q: g, 6, discretization_scheme=interp)]
    _, sd_plain, _ = toppra.algorithm.TOPPRA(plain, path, gridpoints=grid, solver_wrapper="seidel") \
        .compute_parameterization(0.0, 0.0)
    assert len(calls) >= 3 * len(grid)  # toppra evaluated the wrench point by point
    np.testing.assert_allclose(ours["sd"], sd_plain, rtol=1e-9, atol=1e-12)
    assert ours["duration_s"] > plan_toppra(pp, ik.chain, velocity_limit=vel, acceleration_limit=acc)["duration_s"]
