"""Limits as terms: the moment's planar fast path equals its general 3-D form, gravity switches off
the time-scaling shortcut, the toppra rows bound what the columns bound."""

import numpy as np
import pytest

from qmt_drake.limits import PayloadMomentTerm
from qmt_drake.limits.base import RowOptions


def test_moment_planar_path_equals_general_form(scenarios):
    sc = scenarios["thesis-ch2"]
    term = sc.limit_set.term("payload_moment")
    assert term.in_plane and term.scaling == "inverse_square"
    rng = np.random.default_rng(2)
    q, qd, qdd = rng.normal(size=(3, 50, sc.arm.n_dof))
    state = sc.arm.hand_state(q, qd, qdd)
    general = PayloadMomentTerm(sc.arm, sc.moment_per_accel_kgm, sc.limits.moment_limit_Nm)
    general.in_plane = False  # force P_face (a - g) in 3-D from the hand's orientation
    np.testing.assert_allclose(general.columns(state), term.columns(state), rtol=1e-12)
    # m_o r_G |a_tip| (the thesis's eq. 2-24) on these horizontal arms
    a = sc.arm.drake_chain.hand_acceleration_and_joint_torque(q, qd, qdd)[0]
    np.testing.assert_allclose(term.moment_Nm(state), sc.moment_per_accel_kgm * np.linalg.norm(a[:, :2], axis=1),
                               rtol=1e-12)


def test_gravity_switches_off_the_time_scaling_shortcut(tmp_path, scenarios):
    assert all(s.limit_set.time_scaling_is_exact for s in scenarios.values())
    from tests.test_model import PLANNED, _scenario
    thesis_points = scenarios["thesis-ch4"].task.points_m
    sc = _scenario(tmp_path, PLANNED["vertical_plane"][0], thesis_points)
    ls = sc.limit_set
    assert not ls.time_scaling_is_exact
    assert {t.name: t.scaling for t in ls.terms} == {"payload_moment": "none", "motor_torque": "none",
                                                    "joint_range": "invariant"}


def test_toppra_rows_are_inside_the_columns(scenarios):
    """Any w with F w <= g (the inscribed polygon and the motor rows) keeps every column <= 1."""
    sc = scenarios["thesis-ch4"]
    term = sc.limit_set.term("payload_moment")
    F, g = term.toppra_rows(RowOptions(polygon_sides=32, angle0_rad=0.3, inscribed=True))
    theta = np.linspace(0, 2 * np.pi, 721)
    for th in theta:  # the largest |w| along each direction that the polygon allows
        d = np.array([np.cos(th), np.sin(th)])
        r = np.min(g / np.maximum(F @ d, 1e-300))
        assert r <= 1.0 + 1e-12
    F, g = term.toppra_rows(RowOptions(polygon_sides=32, angle0_rad=0.3, inscribed=False))
    assert min(np.min(g / np.maximum(F @ np.array([np.cos(t), np.sin(t)]), 1e-300)) for t in theta) >= 1.0 - 1e-12


def test_joint_range_columns(scenarios):
    sc = scenarios["thesis-ch4"]
    jr = sc.limit_set.term("joint_range")
    q = np.array([[0.0, 3.5], [-3.2, 0.0]])
    cols = jr.columns(sc.arm.hand_state(q, 0 * q, 0 * q))
    np.testing.assert_allclose(cols[:, :2], q - sc.arm.joint_upper_rad)
    np.testing.assert_allclose(cols[:, 2:], sc.arm.joint_lower_rad - q)
    assert cols[0, 1] > 0 and cols[1, 2] > 0 and cols[0, 0] < 0


def test_refined_peak_on_a_plateau_bounds_a_ten_times_finer_sampling():
    """A jerk-limited line on the tray holds the slide ratio on a plateau (constant acceleration):
    hundreds of sampled 'local maxima' there; only the highest REFINE_MAX_PER_COLUMN are refined,
    and the refined peak still bounds a 10x finer sampling of the trajectory."""
    from qmt_drake.limits.limit_set import REFINE_MAX_PER_COLUMN
    from qmt_drake.planners import plan_with
    from qmt_drake.transfer_scenario import load_scenario
    sc = load_scenario("crane-tray")
    plan = plan_with("ruckig", sc, jerk_limit=50.0)
    ls = sc.limit_set
    rep = ls.report(plan.trajectory, 1000.0)
    t = np.linspace(0.0, plan.motion_time_s, int(plan.motion_time_s * 10000) + 1)
    q, qd, qdd = plan.sample(t)
    cols = ls.columns(q, qd, qdd)
    slide = cols[::10, ls.slices["tray_slide"]][:, 0]  # the 1 kHz samples
    assert np.sum(slide >= 0.98 * slide.max()) > 2 * REFINE_MAX_PER_COLUMN  # a plateau: the cap acts
    dense = cols.max(axis=0)
    for name in ("tray_slide", "tray_tip", "joint_speed"):
        s = ls.slices[name]
        assert np.max(dense[s]) <= rep.peak_ratios[name] + 1e-9
    assert rep.peak_ratios["tray_slide"] > 0.99  # the plateau is at the limit


def test_an_unknown_row_option_is_refused_not_swallowed():
    from qmt_drake.errors import QmtInputError
    from qmt_drake.transfer_scenario import load_scenario
    with pytest.raises(QmtInputError, match="'polygon_side' is not one of"):
        load_scenario("thesis-ch4").limit_set.toppra_rows(polygon_side=16)
