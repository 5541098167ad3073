"""The quasi-static armature (default) against the motor model with inductance in the closed loop:
with L/R ~ 0.2 ms far below the loop's ~2.5 ms time constant the two agree."""

import numpy as np
import pytest

from qmt_drake.sim import GenesPlan, build_transfer_diagram, run_diagram
from qmt_drake.systems.transfer_monitor import TransferMonitor
from qmt_drake.transfer_scenario import load_scenario


def test_inductance_changes_little():
    sc = load_scenario("thesis-ch4")
    plan = GenesPlan(sc, (0.622, 0.532, 0.562))
    out = []
    for with_l in (False, True):
        # Both stepped explicitly at 1 ms: the implicit scheme needs the quasi-static armature.
        td = build_transfer_diagram(sc, plan, motor_inductance=with_l, implicit_loop_damping=False,
                                    time_step_s=1e-3, log_period_s=0)
        td.t_final_s = 0.45  # lead 0.2 s and the first 0.25 s of the move (its first moment peak)
        summary, _ = run_diagram(td)
        out.append(TransferMonitor.unpack(summary))
    quasi, full = out
    assert full["max_tracking_error_rad"] == pytest.approx(quasi["max_tracking_error_rad"], rel=0.1)
    np.testing.assert_allclose(full["peak_motor_torque_Nm"], quasi["peak_motor_torque_Nm"], rtol=0.05)
    assert full["max_slip_m"] == pytest.approx(quasi["max_slip_m"], rel=0.1, abs=2e-5)
