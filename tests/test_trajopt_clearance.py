"""A collision-free path round a wall the task's joint box cannot pass (planners/collision_free.py: the RRT
widened to the joint ranges) and the trajopt that keeps the clearance on it (planners/trajopt_clearance.py),
on the two-link planar arm of tests/test_collision_free.py. The wall lies on the x axis from x = 0.6 to 1.1 m;
the tip (its sphere and the carried cube) must cross the x axis going from q = (-1, 0) to (1, 0) (its angle is
j1 + j2 / 2, and j1 cannot go round: |j1| <= 3), so it must pass at a radius cos(j2 / 2) < 0.6 - 0.052 m,
|j2| > 1.97 rad: no path exists in the task box (j2 within +-0.5 rad). Checked independently by Drake's signed
distance sampled densely along the result."""

from dataclasses import replace

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError, QmtNoPlanError
from qmt_drake.limits.clearance import certified_clearance, collision_model
from qmt_drake.model.obstacles import Obstacle
from qmt_drake.planners import collision_free, trajopt_core
from qmt_drake.planners.spatial_methods import plan_trajopt_spatial
from qmt_drake.planners.spatial_trajectory import PolyTrajectory
from qmt_drake.planners.trajopt_clearance import breaks, keep_clear
from qmt_drake.spatial_task import load_spatial_scenario
from tests.test_collision_free import two_link

WALL = Obstacle("wall", "box", (0.85, 0.0, 0.0), size_m=(0.5, 0.1, 0.4))
MARGIN_M = 0.01
FOLD_RAD = 2.0 * np.arccos(0.6 - 0.04 - 0.03 * np.sqrt(2))  # |j2| the tip needs under the wall (1.97 rad)


@pytest.fixture
def quick(monkeypatch):
    """Smaller RRT budgets for a 2-DOF arm (seconds, not tens of seconds); the same algorithm."""
    monkeypatch.setattr(collision_free, "MAX_NODES", 300)
    monkeypatch.setattr(collision_free, "STEP_M", 0.3)
    monkeypatch.setattr(collision_free, "EDGE_STEP_M", 0.02)


def _detour(tmp_path, seed=1):
    sc = two_link(tmp_path, [WALL])
    sc.check_rate_hz = 200.0
    return sc, collision_free.collision_free_path(sc, margin_m=MARGIN_M, seed=seed)


def test_the_rrt_widens_to_the_joint_ranges_when_the_task_box_has_no_path(tmp_path, quick):
    sc = two_link(tmp_path, [WALL])
    with pytest.raises(QmtNoPlanError, match="joined no path within 300 iterations"):
        collision_free.collision_free_path(sc, margin_m=MARGIN_M, seed=1, widen=False)
    r = collision_free.collision_free_path(sc, margin_m=MARGIN_M, seed=1)
    assert r["widened_legs"] == [0]
    q = r["path"].sample(np.linspace(0.0, r["path"].duration_s, 2000))[0]
    assert np.abs(q[:, 1]).max() > FOLD_RAD > 1.9  # the elbow folded under the wall (closed form)
    assert r["certificate"]["certified"] and r["certificate"]["clearance_lower_bound_m"] >= MARGIN_M / 2
    cm = collision_model(sc)
    assert min(cm.distance(qk)[0] for qk in q) >= MARGIN_M / 2  # independent dense sampling
    again = collision_free.collision_free_path(sc, margin_m=MARGIN_M, seed=1)
    assert np.array_equal(again["Q"], r["Q"])  # deterministic given the seed


def test_a_leg_the_task_box_joins_is_not_widened(tmp_path, quick):
    # a post just inside the tip's reach (its near face at x = 1.04 m): passed at a radius below 0.988 m,
    # the elbow folded by 0.31-0.5 rad, inside the task box
    post = Obstacle("post", "box", (1.09, 0.0, 0.0), size_m=(0.1, 0.1, 0.4))
    sc = two_link(tmp_path, [post])
    r = collision_free.collision_free_path(sc, margin_m=MARGIN_M, seed=0)
    assert r["widened_legs"] == [] and len(r["vertices"]) > 2  # a detour, found in the task box
    q = r["path"].sample(np.linspace(0.0, r["path"].duration_s, 2000))[0]
    assert np.abs(q[:, 1]).max() <= 0.5 + 1e-9


def test_trajopt_keeps_the_clearance_the_plain_program_breaks(tmp_path, quick):
    sc, r = _detour(tmp_path)
    Q = r["Q"]
    c = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))]
    s = c / c[-1]
    ncp = 10
    guess = np.array([[np.interp(x, s, Q[:, j]) for j in range(2)] for x in np.linspace(0.0, 1.0, ncp)])
    p = trajopt_core.TrajoptProblem(Q, s, np.array([-3.0, -2.8]), np.array([3.0, 2.8]), ncp, (0.05, 60.0), guess,
                                    rest_derivatives=2, velocity_limit=np.full(2, 2.0),
                                    acceleration_limit=np.full(2, 10.0),
                                    snopt_options={"Major feasibility tolerance": 1e-10})
    first = trajopt_core.solve(p)
    assert first.success
    plain = certified_clearance(sc, PolyTrajectory(first.trajectory), 200.0)
    assert plain["clearance_m"] < -0.05  # between the path's points the plain spline cuts through the wall
    res, facts = keep_clear(sc, p, first, MARGIN_M, 0.02, 20)
    assert facts["used"] and facts["bound_m"] == MARGIN_M
    traj = PolyTrajectory(res.trajectory)
    cert = certified_clearance(sc, traj, 200.0)
    assert cert["certified"] and cert["clearance_lower_bound_m"] >= MARGIN_M / 2
    cm = collision_model(sc)
    dense = min(cm.distance(q)[0] for q in traj.sample(np.linspace(0.0, traj.duration_s, 4000))[0])
    assert dense >= cert["clearance_lower_bound_m"] - 1e-12
    q_at = np.array([res.trajectory.value(x * res.duration_s).ravel() for x in s])
    assert np.abs(q_at - Q).max() < 1e-6  # still through every path point at its fraction
    qd = traj.sample(np.linspace(0.0, traj.duration_s, 2000))[1]
    assert np.abs(qd).max() <= 2.0 + 1e-6  # and within the speed limit


def test_a_plain_solve_snopt_cannot_improve_is_a_trajectory_kept_where_it_clears(tmp_path, quick):
    """SNOPT's exit 41 ("the current point cannot be improved") on a point that meets every constraint is a
    trajectory (trajopt_core.TrajoptResult.usable), certified and kept where it clears, without the clearance
    program: on the deep totes' ends-only path (seed 2) such a plain point, certified +6.3 mm, was refused. Here:
    the post's detour in the task box, 14 control points and a jerk bound (SNOPT's 41, deterministic)."""
    post = Obstacle("post", "box", (1.09, 0.0, 0.0), size_m=(0.1, 0.1, 0.4))
    sc = two_link(tmp_path, [post])
    sc.check_rate_hz = 200.0
    Q = collision_free.collision_free_path(sc, margin_m=MARGIN_M, seed=0)["Q"]
    c = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))]
    s, ncp = c / c[-1], 14
    guess = np.array([[np.interp(x, s, Q[:, j]) for j in range(2)] for x in np.linspace(0.0, 1.0, ncp)])
    p = trajopt_core.TrajoptProblem(Q, s, np.array([-3.0, -2.8]), np.array([3.0, 2.8]), ncp, (0.05, 60.0), guess,
                                    rest_derivatives=2, velocity_limit=np.full(2, 2.0),
                                    acceleration_limit=np.full(2, 10.0), jerk_limit=np.full(2, 40.0),
                                    snopt_options={"Major feasibility tolerance": 1e-10})
    first = trajopt_core.solve(p)
    assert not first.success and first.info == 41 and first.infeasible_constraints == []
    res, facts = keep_clear(sc, p, first, MARGIN_M, 0.02, 20)
    assert res is first and not facts["used"] and facts["plain_certified_lower_bound_m"] >= MARGIN_M / 2
    assert first.usable
    traj = PolyTrajectory(res.trajectory)
    q, qd, qdd = traj.sample(np.linspace(0.0, traj.duration_s, 4000))[:3]
    cm = collision_model(sc)
    assert min(cm.distance(qk)[0] for qk in q) >= MARGIN_M / 2  # independent dense signed distances
    q_at = np.array([res.trajectory.value(x * res.duration_s).ravel() for x in s])
    assert np.abs(q_at - Q).max() < 1e-6  # through every path point at its fraction
    assert np.abs(qd).max() <= 2.0 + 1e-6 and np.abs(qdd).max() <= 10.0 + 1e-6  # within the limits between samples
    # a point that breaks a constraint is no trajectory: the same program stopped after 2 major iterations
    capped = trajopt_core.solve(replace(p, snopt_options={**p.snopt_options, "Major iterations limit": 2}))
    assert capped.solution_result.endswith("kIterationLimit") and capped.infeasible_constraints and not capped.usable


def test_a_refusal_names_the_path_point_a_spline_at_rest_cannot_reach():
    """A path point at fraction 0.97, 0.3 rad from the end: at rest at the end (zero speed and acceleration) the
    last three control points are the end, so q(0.97) leaves it only by the weight w of the one before times that
    point's offset; 0.3 / w exceeds the joint range (closed form), so no spline exists, and the refusal's reason
    (trajopt_clearance.breaks, the deep totes' ends-only path of seed 0: 'misses path point 6') names the point."""
    Q = np.array([[-1.0, 0.0], [0.0, 0.3], [0.8, 0.3], [1.0, 0.0]])
    s, ncp = np.array([0.0, 0.5, 0.97, 1.0]), 8
    guess = np.array([[np.interp(x, s, Q[:, j]) for j in range(2)] for x in np.linspace(0.0, 1.0, ncp)])
    p = trajopt_core.TrajoptProblem(Q, s, np.array([-3.0, -2.8]), np.array([3.0, 2.8]), ncp, (0.05, 60.0), guess,
                                    rest_derivatives=2, velocity_limit=np.full(2, 2.0))
    r = trajopt_core.solve(p)
    idx, W = trajopt_core.basis_weights(r.basis, 0.97)
    assert idx[0] == ncp - 4 and Q[3, 1] + (Q[2, 1] - Q[3, 1]) / W[0][0] > 2.8  # the control point needed, out of range
    assert not r.usable
    assert breaks(r, p, None).startswith("misses path point 2 (fraction 0.970) by 0.3 rad")


def test_trajopt_clearance_option_is_checked():
    sc = load_spatial_scenario("ur5-suction-bins")
    for bad in (-0.001, float("nan")):
        with pytest.raises(QmtInputError, match="clearance_m"):
            plan_trajopt_spatial(sc, clearance_m=bad)
