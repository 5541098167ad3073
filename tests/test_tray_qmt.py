"""Fastest tray line: TOPP-RA with the tray limits and Ruckig against the bang-bang closed form
of a level tray on a horizontal line (|a| <= margin mu g, T = 2 sqrt(L / a_max))."""

import math

import numpy as np
import pytest

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2 as GRAVITY_M_S2
from qmt_drake.errors import QmtInputError
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.tray.conditions import contact_wrench, tray_kinematics, tray_ratios
from qmt_drake.tray.waypoints import ruckig_line, toppra_line

BOTTLE = BottleSpec.pet_500ml(friction=0.3)
START, GOAL = (0.04, 0.4), (0.4, 0.4)


def _bang_bang(margin):
    return 2.0 * math.sqrt(0.36 / (margin * BOTTLE.friction * GRAVITY_M_S2))


def test_toppra_matches_the_bang_bang_closed_form_and_keeps_the_limits():
    sched, info = toppra_line(BOTTLE, n=200, margin=0.8)
    assert info["max_speed_ratio"] < 0.99  # the joint speed limits do not bind: the closed form applies
    assert info["feasible"]
    assert info["planned_duration_s"] == pytest.approx(_bang_bang(0.8), rel=0.02)
    assert info["max_slide_ratio"] <= 0.8 * 1.01  # re-checked at 1 ms with the true mu
    assert info["max_off_line_m"] < 1e-4 and info["max_tray_tilt_rad"] < 1e-3
    # independent re-check of the streamed goals: finite differences of the samples
    t = sched.times[1:] - sched.times[1]
    q = sched.goals[1:]
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    r = tray_ratios(contact_wrench(tray_kinematics(q[5:-5], qd[5:-5], qdd[5:-5], [0, 0, BOTTLE.com_height_m]),
                                   BOTTLE), BOTTLE)
    assert np.max(r["slide"]) < 0.85


def test_ruckig_approaches_the_closed_form_as_jerk_grows():
    _, fast = ruckig_line(BOTTLE, margin=0.8, jerk_m_s3=1e5, speed_fraction=50.0)
    _, smooth = ruckig_line(BOTTLE, margin=0.8, jerk_m_s3=5.0, speed_fraction=50.0)
    assert fast["duration_s"] == pytest.approx(_bang_bang(0.8), rel=0.01)
    assert smooth["duration_s"] > fast["duration_s"] * 1.1
    with pytest.raises(QmtInputError):
        ruckig_line(BOTTLE, margin=1.5)


@pytest.mark.parametrize("args", [["--mu", "-0.2"], ["--goal", "0.7", "0.4"], ["--com-height", "0.3"],
                                  ["--mu", "0.01"]])
def test_plan_command_bad_input_is_one_line_exit_2(args, capsys):
    from studies.crane_tray import plan_command
    assert plan_command(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err
