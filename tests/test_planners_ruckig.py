"""Ruckig planner: the vectorised profile matches Ruckig's own evaluation; on the chapter-2 line the
motion time equals the jerk-limited closed form and approaches 2*sqrt(L/A) as the jerk limit
grows; the tip stays on the line; joint-space moves get the tight limit scale; vias are chained
with stops (and say so); infeasible limits give infeasible plans."""

import numpy as np
import pytest

from qmt_drake.apps.benchmark import tip_jerk_peak
from qmt_drake.planners.baselines.ruckig_plan import VIA_NOTE, plan_ruckig, ruckig_profile
from qmt_drake.transfer_scenario import load_scenario


@pytest.fixture(scope="module")
def sc2():
    return load_scenario("thesis-ch2")


def accel_limit(sc):
    return sc.limits.moment_limit_Nm / sc.moment_per_accel_kgm


def test_profile_evaluation_matches_ruckig():
    from ruckig import InputParameter, Ruckig, Trajectory
    start, goal = [0.1, -0.3, 0.7], [-0.2, 0.4, 0.7 + 1e-3]
    vmax, amax, jmax = [0.5, 0.4, 0.3], [0.2, 0.3, 0.1], [1.0, 2.0, 0.5]
    prof = ruckig_profile(start, goal, vmax, amax, jmax, phase=False)
    inp = InputParameter(3)
    inp.current_position, inp.target_position = start, goal
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = vmax, amax, jmax
    traj = Trajectory(3)
    Ruckig(3).calculate(inp, traj)
    t = np.linspace(0, traj.duration, 37)
    p, v, a = prof.evaluate(t)
    for k, tk in enumerate(t):
        pr, vr, ar = traj.at_time(tk)
        np.testing.assert_allclose(p[k], pr, atol=1e-12)
        np.testing.assert_allclose(v[k], vr, atol=1e-12)
        np.testing.assert_allclose(a[k], ar, atol=1e-12)


def test_jerk_sweep_approaches_bang_bang(sc2):
    A = accel_limit(sc2)
    L = float(np.hypot(*(sc2.task.points_m[1] - sc2.task.points_m[0])))
    bang = 2 * np.sqrt(L / A)
    times = []
    for J in (1.0, 10.0, 100.0, 1000.0):
        plan = plan_ruckig(sc2, jerk_limit=J)
        assert plan.feasible
        # Jerk-limited rest-to-rest closed form (accel plateau reached, no velocity limit):
        # ramp t_j = A/J, T = 2*sqrt(L/A + t_j^2/4) + t_j.
        tj = A / J
        assert plan.motion_time_s == pytest.approx(2 * np.sqrt(L / A + tj**2 / 4) + tj, rel=1e-6)
        assert 0.999 < plan.check.peak_moment_ratio <= 1.0
        # The tip jerk along the line is J itself (resolved by 10 kHz differences while the
        # ramp A/J lasts several samples).
        if A / J > 5e-4:
            jerk = tip_jerk_peak(sc2, plan)
            assert jerk["peak_tip_jerk_m_s3"] == pytest.approx(J, rel=0.02)
            assert not jerk["acceleration_jumps"]
        times.append(plan.motion_time_s)
    assert np.all(np.diff(times) < 0)
    assert times[-1] / bang - 1 < 1e-3
    assert times[0] / bang - 1 > 1e-2


def test_line_stays_straight(sc2):
    plan = plan_ruckig(sc2, jerk_limit=10.0)
    t = np.linspace(0, plan.motion_time_s, 301)
    q, _, _ = plan.sample(t)
    tip = sc2.arm.tip_position(q)
    p0, p1 = sc2.task.points_m
    d = (p1 - p0) / np.hypot(*(p1 - p0))
    np.testing.assert_allclose((tip - p0) @ np.array([-d[1], d[0]]), 0.0, atol=1e-12)
    np.testing.assert_allclose(sc2.arm.tool_angle(q), sc2.task.tool_angle_rad, atol=1e-12)
    np.testing.assert_allclose(tip[-1], p1, atol=1e-12)


def test_joint_mode_scale_is_tight():
    sc = load_scenario("thesis-ch3")
    plan = plan_ruckig(sc, jerk_limit=100.0, mode="joint", bisection_rtol=1e-4)
    assert plan.feasible
    worst = max(plan.check.peak_moment_ratio, plan.check.peak_motor_torque_ratio)
    assert worst > 0.995  # a larger scale would break a limit
    lam = plan.extra["acceleration_scale"][0]
    faster = plan_ruckig(sc, jerk_limit=100.0, mode="joint", bisection_rtol=1e-4,
                         slow_to_limits=False)
    assert faster.extra["acceleration_scale"][0] == pytest.approx(lam)


def test_vias_chained_with_stops():
    sc = load_scenario("thesis-ch4")
    plan = plan_ruckig(sc, jerk_limit=10.0)
    assert plan.feasible
    assert VIA_NOTE in plan.extra["notes"]
    bounds = plan.trajectory.offsets
    assert len(bounds) == len(sc.task.points_m)
    q, qd, _ = plan.sample(bounds[1:-1])
    np.testing.assert_allclose(qd, 0.0, atol=1e-9)
    np.testing.assert_allclose(sc.arm.tip_position(q), sc.task.points_m[1:-1], atol=1e-9)


def test_infeasible_limits_give_infeasible_plans():
    weak = load_scenario("thesis-ch3", overrides={"limits": {"motor_torque_limit_Nm": [1e-7, 1e-7]}})
    for mode in ("cartesian_line", "joint"):
        p = plan_ruckig(weak, jerk_limit=10.0, mode=mode)
        assert not p.feasible and "too tight" in p.extra["infeasible"]
    far = load_scenario("thesis-ch3", overrides={"task": {"points_m": [[0.22, 0.15], [0.5, 0.5]]}})
    p = plan_ruckig(far, jerk_limit=10.0)
    assert not p.feasible and "unreachable" in p.extra["infeasible"]
