"""The executed limit ratio and tracking error of a tray run (tray/executed.py): exact on a motion whose
central differences are exact, equal to the plan's independently refined peaks on an ideal-tracking
replay of the TOPP-RA plan, and equal to the bottle's own contact force ratio in a co-simulation in
which it sticks."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from qmt_drake import load_scenario, plan_with
from qmt_drake.errors import QmtInputError
from qmt_drake.tray import cosim
from qmt_drake.tray.execute import plan_schedule
from qmt_drake.tray.executed import (
    ACCEL_WINDOW_S,
    central_acceleration,
    execute_and_measure,
    executed_against_plan,
)

H = 1e-3


@pytest.fixture(scope="module")
def tray():
    sc = load_scenario("crane-tray")
    return sc, plan_with("toppra", sc)


class CubicMotion:
    """q(t) = q0 + c1 t + c2 t^2 + c3 t^3 per joint: its velocity is quadratic, so every central
    difference of it is its acceleration exactly, at any window."""

    def __init__(self, q0, c1, c2, c3):
        self.c = [np.asarray(x, float) for x in (q0, c1, c2, c3)]

    def sample(self, t):
        t = np.asarray(t, float)[:, None]
        q0, c1, c2, c3 = self.c
        return q0 + c1 * t + c2 * t**2 + c3 * t**3, c1 + 2 * c2 * t + 3 * c3 * t**2, 2 * c2 + 6 * c3 * t


def replay_series(motion, t, start_s=0.0, time_scale=1.0):
    """The series an ideally tracking arm would log: the motion's own state at every step."""
    q, qd, _ = motion.sample((t - start_s) / time_scale)
    return {"t_step": t, "arm_state_step": np.vstack([q.T, qd.T / time_scale])}


@pytest.mark.parametrize("window_s", [2 * H, ACCEL_WINDOW_S, 0.02])
def test_exact_on_a_motion_with_exact_central_differences(tray, window_s):
    sc, plan = tray
    q0 = plan.sample(np.zeros(1))[0][0]
    motion = CubicMotion(q0, [0.3, -0.5, 0.2], [4.0, -7.0, 3.0], [-3.0, 5.0, -2.0])
    t = np.arange(0.0, 0.6, H)
    r = executed_against_plan(sc, motion, replay_series(motion, t), move_start_s=0.0, window_s=window_s)
    # reference: the LimitSet on the exact states at the samples the window leaves (m steps from each end)
    m = max(1, round(window_s / (2 * H)))
    q, qd, qdd = motion.sample(t[m:-m])
    cols = sc.limit_set.columns(q, qd, qdd)
    for k, v in r["executed_peak_ratio"].items():
        exact = cols[:, sc.limit_set.slices[k]].max()
        assert abs(v - exact) <= 1e-9 * max(1.0, abs(exact)), k
        assert abs(r["planned_peak_ratio"][k] - exact) <= 1e-12 * max(1.0, abs(exact)), k
    assert r["tracking_error_max_rad"] == 0.0
    assert r["executed_peak_ratio"]["tray_slide"] > 0.2  # the motion loads the cone: not a vacuous case


@pytest.mark.parametrize("window_s", [2 * H, ACCEL_WINDOW_S])
def test_ideal_replay_of_the_plan_gives_the_plans_refined_peaks(tray, window_s):
    """plan.check is LimitSet.report: sampled at the check rate with every near-peak local maximum
    refined by golden section on the trajectory itself, a different path from 1 ms samples and
    differentiated velocities. 1e-3 of the limit: the table prints two decimals."""
    sc, plan = tray
    t = np.arange(0.0, 0.2 + plan.motion_time_s + 0.2, H)
    r = executed_against_plan(sc, plan, replay_series(plan, t, 0.2), move_start_s=0.2, window_s=window_s)
    for k in ("tray_slide", "tray_tip"):
        assert abs(r["executed_peak_ratio"][k] - plan.check.peak_ratios[k]) < 1e-3, k
        assert abs(r["planned_peak_ratio"][k] - plan.check.peak_ratios[k]) < 1e-3, k
    assert plan.check.peak_ratios["tray_slide"] > 0.99  # TOPP-RA runs on the cone: the peak is the limit
    assert r["tracking_error_max_rad"] < 1e-12


def test_cosimulation_accelerations_and_the_bottles_contact_force(tray):
    """Shaped goals at x1.1: the bottle sticks. The plant's logged acceleration is the forward
    difference of its logged velocities (the module's claim), and the executed slide ratio equals
    the ratio of the contact force Drake's contact solver applied to the bottle, both over 10 ms
    (the bottle is not welded: it rocks on its compliant feet, hence 5 %)."""
    sc, plan = tray
    act = sc.actuator
    s, start = 1.1, 0.5
    sched = plan_schedule(plan, time_scale=s, period_s=act.control_period_s, shaped_for=sc, settle_s=start, tail_s=0.3)
    td = cosim.build_tray_diagram(sched, act.gains(), sc.bottle, servo_period_s=act.control_period_s,
                                  log_period_s=H, step_log=True)
    sim = Simulator(td.diagram)
    cosim.set_initial_state(td, sim.get_mutable_context())
    sim.AdvanceTo(sched.t_end_s)
    S = cosim.logged_series(td, sim.get_context())
    v, a = S["arm_state_step"][3:], S["arm_accel_step"]
    assert np.max(np.abs(a[:, :-1] - np.diff(v, axis=1) / H)) <= 1e-9 * np.max(np.abs(a))
    assert np.allclose(S["arm_state_step"][:3, 0], sched.q_start)  # sample k: the state before step k
    assert np.max(np.hypot(*S["slide"])) < 1e-3
    r = executed_against_plan(sc, plan, S, move_start_s=start, time_scale=s)
    f = S["contact_force"]
    k = np.ones(10) / 10
    smooth = lambda x: np.convolve(x, k, mode="same")  # noqa: E731
    ratio = np.hypot(smooth(f[0]), smooth(f[1])) / (sc.hand.plan_margin * sc.hand.friction * smooth(f[2]))
    m = (S["t"] >= start) & (S["t"] < S["t"][-1] - 0.01)
    measured = float(ratio[m].max())
    assert measured > 1.05 * r["planned_peak_ratio"]["tray_slide"]  # the executed motion is not the plan's
    assert abs(r["executed_peak_ratio"]["tray_slide"] - measured) < 0.05 * measured
    assert 0 < r["tracking_error_rms_rad"] < r["tracking_error_max_rad"] < 0.05


def test_refuses_a_run_not_logged_every_step(tray):
    sc, plan = tray
    with pytest.raises(QmtInputError, match="every plant step"):
        executed_against_plan(sc, plan, {"t": np.arange(3.0)}, move_start_s=0.0)
    with pytest.raises(QmtInputError, match="uniformly"):
        central_acceleration(np.array([0.0, 1e-3, 3e-3, 4e-3]), np.zeros((4, 3)))


def test_shaped_goals_track_the_plan_closer_than_the_plan_streamed(tray):
    """execute_and_measure runs the scenario's reference: the shaped stream (the default) follows the
    plan several times closer than the plan streamed as goals, at the same scale."""
    sc, plan = tray
    plain_sc = load_scenario("crane-tray", overrides={"actuator": {"reference": "plain"}})
    shaped = execute_and_measure(sc, plan, 1.2)
    plain = execute_and_measure(plain_sc, plan, 1.2)
    assert (shaped["reference"], plain["reference"]) == ("shaped", "plain")
    assert 3 * shaped["tracking_error_rms_rad"] < plain["tracking_error_rms_rad"]
    assert shaped["planned_peak_ratio"] == plain["planned_peak_ratio"]  # the same plan at the same scale
