"""The shipped spatial scenario (UR5, suction cup, two bins): loading and refusals, every planner
re-checked at 10x the check rate and reaching every task pose (Drake FK), and the co-simulation."""

from __future__ import annotations

import importlib.metadata
from pathlib import Path

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.planners.spatial_methods import (
    plan_family_optimum,
)
from qmt_drake.planners.spatial_trajectory import TimeScaled, check
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import SCENARIO_DIR, load_spatial_scenario
from tests.spatial_fixtures import edited_copy, load_or_skip, plans_of_every_method, shipped_toppra

SHIPPED = SCENARIO_DIR / "ur5-suction-bins.yaml"


@pytest.fixture(scope="module")
def sc():
    return load_or_skip("ur5-suction-bins")


@pytest.fixture(scope="module")
def plans(sc):
    return plans_of_every_method(sc)


def _variant(tmp_path: Path, edit) -> Path:
    return edited_copy(SHIPPED, tmp_path, edit)


def test_task_poses_reached_by_drake_fk(sc):
    assert sc.n_dof == 6 and len(sc.q_poses_rad) == 4
    for q, p in zip(sc.q_poses_rad, sc.poses_m):
        ep, ea = sc.ik.errors(q, p, normal=np.array([0.0, 0.0, -1.0]))
        assert ep < 1e-6 and ea < 1e-6
    # the reflected rotor inertia N^2 J_r
    np.testing.assert_allclose(sc.drive["reflected_inertia_kgm2"], 101.0 ** 2 * np.array([6e-5] * 3 + [1.3e-5] * 3))


def test_unreachable_pose_refused_naming_it(sc, tmp_path):
    def far(raw):
        raw["task"]["poses_m"][3] = [1.5, 0.45, 0.10]
    with pytest.raises(QmtInputError, match=r"task path point 8 at \[1.5, 0.45, 0.1\] m .*out of reach"):
        load_spatial_scenario(_variant(tmp_path, far))


@pytest.mark.parametrize("edit, message", [
    (lambda r: r.update(kind="transfer"), "is a transfer scenario: plan it with"),
    (lambda r: r["arm"].update(package="example-robot-data/ur7"), "give example-robot-data/<arm>"),
    (lambda r: r["actuators"].update(gear_ratio=[101.0] * 5), "gear_ratio has 5 entries; give 6"),
    (lambda r: r["hand"].update(kind="gripper"), "hand.kind 'gripper' is not one of suction, magnet"),
    (lambda r: r["hand"].update(moment_limit_Nm=1e-3), "unknown key 'moment_limit_Nm'"),
    (lambda r: r["payload"].update(mass=1.0), "unknown key 'mass'"),
])
def test_bad_sections_refused_in_one_line(sc, tmp_path, edit, message):
    with pytest.raises(QmtInputError, match=message) as e:
        load_spatial_scenario(_variant(tmp_path, edit))
    assert "\n" not in str(e.value)


def test_missing_package_refused(monkeypatch):
    def missing(name):
        raise importlib.metadata.PackageNotFoundError(name)
    monkeypatch.setattr(importlib.metadata, "files", missing)
    with pytest.raises(QmtInputError, match="pip install example-robot-data"):
        load_spatial_scenario("ur5-suction-bins")


def test_trajectory_derivatives_match_finite_differences(sc, plans):
    for name, p in plans.items():
        traj = p.trajectory
        t = np.linspace(0.05, traj.duration_s - 0.05, 23)
        h = 1e-6
        q, qd, qdd = traj.sample(t)
        qp, qdp, _ = traj.sample(t + h)
        qm, qdm, _ = traj.sample(t - h)
        np.testing.assert_allclose((qp - qm) / (2 * h), qd, atol=2e-5, err_msg=name)
        np.testing.assert_allclose((qdp - qdm) / (2 * h), qdd, atol=2e-3 * max(1.0, np.abs(qdd).max()), err_msg=name)


def test_every_plan_holds_at_ten_times_the_check_rate_and_reaches_every_pose(sc, plans):
    for name, p in plans.items():
        r = check(sc, p.trajectory, 10 * sc.check_rate_hz)
        assert r["max"] <= 1.0, (name, r)
        assert r["n_samples"] >= 10 * sc.check_rate_hz * p.duration_s
        q, _, _ = p.trajectory.sample(p.pose_times_s)
        for qk, pk in zip(q, sc.poses_m):
            ep, ea = sc.ik.errors(qk, pk, normal=np.array([0.0, 0.0, -1.0]))
            assert ep < 1e-6 and ea < 1e-6, name
        assert p.pose_times_s[0] == 0.0 and abs(p.pose_times_s[-1] - p.duration_s) < 1e-9


def test_toppra_is_the_fastest_and_binds_a_limit(sc, plans):
    t = {k: p.duration_s for k, p in plans.items()}
    assert t["toppra"] == min(t.values())
    assert plans["toppra"].recheck["max"] > 0.99  # time-optimal: on a limit somewhere
    assert plans["ga"].duration_s >= plans["family_optimum"].duration_s * (1 - 1e-3)


def test_cosim_toppra_carried_and_one_and_a_half_times_faster_detached(sc, plans):
    fast = TimeScaled(plans["toppra"].trajectory, 0.67)
    assert check(sc, fast, sc.recheck_rate_hz)["suction"] > 1.0
    held = simulate_spatial(sc, plans["toppra"].trajectory)
    lost = simulate_spatial(sc, fast)
    assert held["outcome"] == "carried" and held["final_goal_error_rad"] < 1e-3
    assert lost["outcome"] == "detached" and lost["part_distance_from_cup_at_end_m"] > 0.1


def test_magnet_scenario_plans_hold_and_the_smooth_optimum_is_carried(sc):
    mg = load_spatial_scenario("ur5-magnet-part")
    assert mg.hand_kind == "magnet" and mg.hand_term().name == "magnet_moment"
    tp, fo = shipped_toppra("ur5-magnet-part", 400), plan_family_optimum(mg)
    for p in (tp, fo):
        r = check(mg, p.trajectory, 10 * mg.check_rate_hz)
        assert r["max"] <= 1.0 and r["magnet_moment"] > 0.99  # on the moment limit, not beyond
        assert p.pose_error.max() < 1e-6
    assert tp.duration_s < fo.duration_s
    assert simulate_spatial(mg, fo.trajectory)["outcome"] == "carried"
    assert simulate_spatial(mg, TimeScaled(tp.trajectory, 0.67))["outcome"] == "detached"
