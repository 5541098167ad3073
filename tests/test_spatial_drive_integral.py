"""The spatial DC drive's PID integral (actuators.motor.integral_rate_per_s, or sweep sim.integral_rate_per_s):
it integrates the error the loop actually has (live plant ports), and it brings a drawn weak motor to its goal
where the nominal PD law with nominal feedforward stops short (docs/spatial_uncertainty.md: every Panda tray
loss through the motors was `unfinished`)."""

from __future__ import annotations

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.sweep.cases import build_cases
from qmt_drake.sweep.spatial_cases import build_spatial_cases, drawn_drive, perturbed_scenario
from qmt_drake.sweep.spec import load_spec
from tests.spatial_fixtures import load_or_skip, shipped_toppra

WEAK = {"motor_torque_constant_scale": 0.915}  # the torque constant drawn 1.7 sigma low (1 sigma 5 %)


@pytest.fixture(scope="module")
def panda():
    return load_or_skip("panda-tray-cup")


@pytest.fixture(scope="module")
def plan(panda):
    return shipped_toppra(panda.name)


def _run(sc, plan, rate, values=None):
    """The plan through the motors drawn with `values`, under the law designed from the nominal sc."""
    q0 = plan.trajectory.sample([0.0])[0][0]
    physical = perturbed_scenario(sc, values) if values else sc
    drive = drawn_drive(SpatialMotorDrive.for_scenario(sc, q0, "shaped", integral_rate_per_s=rate), sc, physical,
                        values or {})
    return simulate_spatial(physical, plan.trajectory, controller_sc=sc, drive=drive, feedforward="shaped")


def test_integral_gain_is_the_rate_times_the_stiffness(panda):
    q0 = panda.q_poses_rad[0]
    pd = SpatialMotorDrive.for_scenario(panda, q0, "shaped")
    pid = SpatialMotorDrive.for_scenario(panda, q0, "shaped", integral_rate_per_s=5.0)
    assert not pd.has_discrete_law(1e-3) and pid.has_discrete_law(1e-3)
    np.testing.assert_array_equal(pid.gains.kp_V_per_rad, pd.gains.kp_V_per_rad)
    np.testing.assert_allclose(pid.gains.ki_V_per_rad_s, 5.0 * pd.gains.kp_V_per_rad, rtol=1e-15)
    with pytest.raises(QmtInputError, match=r"^sim.integral_rate_per_s must be at most 10 1/s") as e:
        SpatialMotorDrive.for_scenario(panda, q0, "shaped", integral_rate_per_s=12.0)
    assert "\n" not in str(e.value)


def test_nominal_run_keeps_its_tracking_with_the_integral(panda, plan):
    """Nominally the shaped reference is tracked to about 1e-6 rad, so the integral has nothing to add. With
    Drake's sampled plant ports its update read the next state against this step's reference and wound up
    about h qd per step: 2.0 mrad tracking error at 5 1/s (the defect this guards)."""
    r = _run(panda, plan, 5.0)
    assert r["outcome"] == "carried"
    assert r["max_tracking_error_rad"] < 1e-5
    assert r["final_goal_error_rad"] < 1e-5


def test_integral_brings_a_weak_motor_to_its_goal(panda, plan):
    """A torque constant 8.5 % low: the nominal feedforward delivers 8.5 % too little torque, the PD law
    stops beyond the 1 mrad arrival tolerance (unfinished, cup held); with the integral at 5 1/s the error
    left after the 0.5 s tail is e^-2.5-ish of it, and the run is carried."""
    pd, pid = _run(panda, plan, 0.0, WEAK), _run(panda, plan, 5.0, WEAK)
    assert pd["outcome"] == "unfinished" and pd["final_goal_error_rad"] > ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    assert pid["outcome"] == "carried"
    assert pid["final_goal_error_rad"] < 0.2 * pd["final_goal_error_rad"]


def test_a_sweep_takes_the_integral_rate(panda):
    spec = {"name": "i", "scenario": "panda-tray-cup", "plans": [{"method": "toppra"}],
            "sim": {"actuator": "dc_motor", "feedforward": "shaped", "integral_rate_per_s": 5.0},
            "parameters": {"motor_torque_constant_scale": [0.915, 1.0]}}
    cases, _ = build_spatial_cases(load_spec(spec))
    assert {c.sim["integral_rate_per_s"] for c in cases} == {5.0}
    del spec["sim"]["integral_rate_per_s"]  # absent: the scenario's (0), and the cases' keys as before
    assert all("integral_rate_per_s" not in c.sim for c in build_spatial_cases(load_spec(spec))[0])


@pytest.mark.parametrize("sim, says", [
    ({"actuator": "dc_motor", "integral_rate_per_s": 11.0}, "sweep sim.integral_rate_per_s must be at most 10 1/s"),
    ({"actuator": "dc_motor", "integral_rate_per_s": -1.0}, "integral_rate_per_s must be a non-negative number"),
    ({"actuator": "ideal", "integral_rate_per_s": 1.0}, "the DC-motor drive's PID integral"),
])
def test_a_meaningless_integral_rate_is_refused_in_one_line(sim, says):
    spec = {"name": "i", "scenario": "panda-tray-cup", "plans": [{"method": "toppra"}], "sim": sim,
            "parameters": {"mass_scale": [1.0]}}
    with pytest.raises(QmtInputError, match=says) as e:
        build_spatial_cases(load_spec(spec))
    assert "\n" not in str(e.value)


def test_planar_sweep_refuses_the_integral_rate():
    spec = {"name": "p", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
            "sim": {"integral_rate_per_s": 1.0}, "parameters": {"time_scale": 1.1}}
    with pytest.raises(QmtInputError, match="for the spatial DC-motor drive") as e:
        build_cases(load_spec(spec))
    assert "\n" not in str(e.value)
