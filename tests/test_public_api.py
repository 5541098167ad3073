"""The public surface: `from qmt_drake import load_scenario, plan_with, simulate, build_diagram, Plan`,
documented, and a diagram composed in user code that reproduces the library's (the CLI's) numbers."""

import inspect

import numpy as np
import pytest

import qmt_drake
from qmt_drake import Plan, build_diagram, load_scenario, plan_with, simulate


def test_every_public_name_is_documented_with_units():
    for name in ("load_scenario", "plan_with", "simulate", "build_diagram"):
        doc = inspect.getdoc(getattr(qmt_drake, name)) or ""
        assert len(doc) > 200, name
    assert "[s]" in inspect.getdoc(plan_with) and "[rad]" in inspect.getdoc(plan_with)
    assert inspect.getdoc(Plan) and "qmt_drake/apps/cli.py" in qmt_drake.__doc__


def test_a_diagram_composed_in_user_code_gets_the_clis_numbers():
    # --- user code (13 lines): build, run with Drake's own Simulator, read the monitor ---
    from pydrake.systems.analysis import Simulator

    from qmt_drake.systems.transfer_monitor import TransferMonitor
    sc = load_scenario("thesis-ch4")
    plan = plan_with("thesis", sc)
    td = build_diagram(sc, plan, step_logs=True)
    sim = Simulator(td.diagram)
    sim.Initialize()
    sim.AdvanceTo(td.t_final_s)
    mine = TransferMonitor.unpack(td.summary(sim.get_context()))
    # --- the library's answer, as `qmt-drake simulate thesis-ch4 --method thesis --json -` gives it ---
    lib = simulate(sc, plan)
    assert lib["outcome"] == "carried" and lib["held"]
    assert mine["max_slip_m"] == pytest.approx(lib["max_slip_m"], rel=1e-9, abs=1e-12)
    assert mine["max_tracking_error_rad"] == pytest.approx(lib["max_tracking_error_rad"], rel=1e-9)
    np.testing.assert_allclose(mine["peak_motor_torque_Nm"], lib["peak_motor_torque_Nm"], rtol=1e-9)
