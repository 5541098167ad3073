"""Tray co-simulation, short runs: the equilibrium start is quiet, a slow line carries the bottle,
and the contact force agrees with the numpy tray conditions evaluated on the executed motion."""

import numpy as np
import pytest

from qmt_drake.systems.dynamixel_servo import SEED_GAINS_AFTER
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.tray.conditions import contact_wrench, tray_kinematics
from qmt_drake.tray.cosim import SEATING_S, simulate_tray
from qmt_drake.tray.waypoints import seed_motion


@pytest.fixture(scope="module")
def short_run():
    # a 0.08 m piece of the seed line in 1.5 s (mean 0.053 m/s; the seed: 0.072 m/s)
    sched = seed_motion(1.5, goal_xy=(0.12, 0.4), n=200, settle_s=0.5, move_s=1.5, with_return=False, tail_s=0.5)
    return simulate_tray(sched, SEED_GAINS_AFTER, BottleSpec.pet_500ml(friction=0.3))


def test_equilibrium_start_and_carry(short_run):
    r = short_run
    s, t = r.series, r.series["t"]
    still = (t > SEATING_S) & (t < 0.5)
    assert np.max(np.abs(s["arm_state"][3:, still])) < 0.02  # rad/s: no jolt of a loop taking up the load
    assert r.outcome == "on_tray" and not r.slipped
    assert r.min_normal_force_N > 0.2
    # the arm got to the goal (PID: the integral removes the sag)
    assert np.max(np.abs(s["goal"][:, -1] - s["arm_state"][:3, -1])) < 0.02


def test_contact_force_matches_the_tray_conditions_on_the_executed_motion(short_run):
    s, t = short_run.series, short_run.series["t"]
    q, qd = s["arm_state"][:3].T, s["arm_state"][3:].T
    dt = t[1] - t[0]
    qdd = np.gradient(qd, dt, axis=0)
    # low-pass both sides over 50 ms: the contact force carries the 1 kHz servo ripple
    k = np.ones(10) / 10
    smooth = lambda x: np.convolve(x, k, mode="same")  # noqa: E731
    bottle = BottleSpec.pet_500ml(friction=0.3)
    w = contact_wrench(tray_kinematics(q, qd, qdd, [0, 0, bottle.com_height_m]), bottle)
    m = (t > SEATING_S + 0.1) & (t < t[-1] - 0.1)
    f_sim = s["contact_force"]
    for axis in (0, 2):  # tangential along the line, normal
        pred, meas = smooth(w[:, 3 + axis])[m], smooth(f_sim[axis])[m]
        assert np.max(np.abs(pred - meas)) < 0.1 * bottle.mass_kg * 9.81


def test_logged_bottle_motion_is_the_python_monitors_and_the_diagram_is_freed():
    """The default diagram derives slide, tilt, height and contact force from the bottle joint's
    logged state and generalized contact forces (no Python system): equal to the Python
    TrayBottleMonitor's (poses and contact results) on a transfer where the bottle slides, and the
    diagram is freed after the run (pydrake never frees one that holds a Python system)."""
    import gc
    import weakref

    from pydrake.systems.analysis import Simulator

    from qmt_drake import load_scenario, plan_with
    from qmt_drake.tray import cosim
    from qmt_drake.tray.execute import plan_schedule
    sc = load_scenario("crane-tray")
    act = sc.actuator
    # x0.8: faster than the plan, the bottle slides some 60 mm
    sched = plan_schedule(plan_with("toppra", sc), time_scale=0.8, period_s=act.control_period_s, shaped_for=sc,
                          settle_s=0.3, tail_s=0.3)
    td = cosim.build_tray_diagram(sched, act.gains(), sc.bottle, servo_period_s=act.control_period_s,
                                  python_monitor=True)
    sim = Simulator(td.diagram)
    cosim.set_initial_state(td, sim.get_mutable_context())
    sim.AdvanceTo(sched.t_end_s)
    s = cosim.logged_series(td, sim.get_context())
    assert np.max(np.hypot(*s["slide"])) > 0.01
    for k, tol in (("slide", 1e-12), ("tilt", 1e-12), ("base_height", 1e-12), ("contact_force", 1e-9)):
        assert np.max(np.abs(s[k] - s["monitor_" + k])) < tol, k
    td = cosim.build_tray_diagram(sched, act.gains(), sc.bottle, servo_period_s=act.control_period_s)
    sim = Simulator(td.diagram)
    cosim.set_initial_state(td, sim.get_mutable_context())
    sim.AdvanceTo(0.05)
    refs = [weakref.ref(td.diagram), weakref.ref(td.plant)]
    del td, sim
    gc.collect()
    assert all(r() is None for r in refs)
