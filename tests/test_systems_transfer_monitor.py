"""TransferMonitor: slip/tilt/gap geometry, detachment time, running maxima and energy."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.analysis import Simulator

from qmt_drake.systems.transfer_monitor import TransferMonitor, relative_payload_motion


def test_relative_motion_geometry():
    X_WH = RigidTransform(RollPitchYaw(0.0, 0.0, 0.7), [0.2, 0.1, -0.03])
    # In the hand frame: slid 3 mm along x and 4 mm along y, 1 mm below the face, tilted 0.1 rad about y.
    X_HP = RigidTransform(RotationMatrix.MakeYRotation(0.1), [0.003, 0.004, -0.001])
    slip, tilt, gap = relative_payload_motion(X_WH, X_WH.multiply(X_HP), RigidTransform())
    assert slip == pytest.approx(0.005, rel=1e-12)
    assert tilt == pytest.approx(0.1, rel=1e-9)
    assert gap == pytest.approx(0.001, rel=1e-12)


def _run(gap_m, slip_m, t_end, power, check_seated_at_start=False):
    # Fixed poses that are off the seat from t = 0: the start check is off unless asked for.
    mon = TransferMonitor(2, BodyIndex(1), BodyIndex(2), period_s=1e-3,
                          check_seated_at_start=check_seated_at_start)
    sim = Simulator(mon)
    ctx = sim.get_mutable_context()
    X_WH = RigidTransform([0.3, 0.0, 0.0])
    mon.GetInputPort("body_poses").FixValue(ctx, [RigidTransform(), X_WH,
                                                  X_WH.multiply(RigidTransform([slip_m, 0.0, -gap_m]))])
    mon.GetInputPort("arm_state").FixValue(ctx, [0.1, 0.2, 0.0, 0.0])
    mon.GetInputPort("desired_state").FixValue(ctx, [0.1, 0.23, 0.0, 0.0])
    mon.GetInputPort("motor_torque").FixValue(ctx, [0.01, -0.02])
    mon.GetInputPort("electrical_power").FixValue(ctx, power)
    sim.AdvanceTo(t_end)
    return TransferMonitor.unpack(mon.GetOutputPort("summary").Eval(ctx))


def test_summary_of_a_held_payload():
    s = _run(0.0, 0.0005, 0.5, [1.0, 2.0])
    assert math.isnan(s["detached_at_s"])
    assert s["max_slip_m"] == pytest.approx(0.0005)
    assert s["max_tracking_error_rad"] == pytest.approx(0.03)
    np.testing.assert_allclose(s["peak_motor_torque_Nm"], [0.01, 0.02])
    # 3 W for 0.5 s: updates at t = 0, 1, ..., 499 ms (AdvanceTo(0.5) stops before the 500 ms one).
    assert s["energy_J"] == pytest.approx(3.0 * 0.5, rel=1e-9)


def test_detachment_time_is_the_first_sample_past_the_gap():
    s = _run(0.003, 0.0, 0.2, [0.0, 0.0])
    assert s["detached_at_s"] == 0.0
    assert s["max_gap_m"] == pytest.approx(0.003)


def test_unseated_start_raises_instead_of_detaching_at_0():
    from qmt_drake.errors import QmtSimulationError
    with pytest.raises(QmtSimulationError, match=r"payload not seated on the hand at t = 0 s \(slip 0 mm, gap 3 mm"):
        _run(0.003, 0.0, 0.2, [0.0, 0.0], check_seated_at_start=True)
    # Within the tolerance (0.1 mm) the start is accepted and the run is the same as without the check.
    s = _run(0.0, 0.00005, 0.1, [1.0, 2.0], check_seated_at_start=True)
    assert math.isnan(s["detached_at_s"]) and s["max_slip_m"] == pytest.approx(0.00005)
