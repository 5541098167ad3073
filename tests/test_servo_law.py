"""The compiled servo law and motors (Drake primitives, no Python per step) run the same transfer as the
Python DynamixelPositionServo and DcMotorWithGear: the same arm state to 1e-9 rad, the same verdict."""

import numpy as np

import qmt_drake.tray.cosim as cosim
from qmt_drake import load_scenario, plan_with
from qmt_drake.tray.execute import plan_schedule


def test_compiled_and_python_servo_laws_give_the_same_run(monkeypatch):
    sc = load_scenario("crane-tray")
    act = sc.actuator
    plan = plan_with("toppra", sc)
    sched = plan_schedule(plan, time_scale=1.1, period_s=act.control_period_s, shaped_for=sc)
    runs = {}
    build = cosim.build_tray_diagram
    for compiled in (False, True):
        monkeypatch.setattr(cosim, "build_tray_diagram",
                            lambda *a, c=compiled, **k: build(*a, **{**k, "compiled_servo": c}))
        runs[compiled] = cosim.simulate_tray(sched, act.gains(), sc.bottle, servo_period_s=act.control_period_s)
    py, comp = runs[False], runs[True]
    assert py.outcome == comp.outcome and py.slipped == comp.slipped
    np.testing.assert_allclose(comp.series["arm_state"], py.series["arm_state"], atol=1e-9, rtol=0)
    assert "DynamixelPositionServo" not in type(cosim.build_tray_diagram(sched, act.gains(), sc.bottle).servo).__name__
