"""Arms from example-robot-data that no scenario used before issue 28 (studies/arms_from_the_field.py):
the SO-101 (5 joints, its transmissions listed wrist first) planned by TOPP-RA holds every limit by
an independent check (Pinocchio's own URDF parse and RNEA, 10x the planner's re-check rate), reaches
its task poses and is carried in the co-simulation with ideal actuators and with DC motors; the
independent check sees a limit broken when the same plan is played faster; TALOS's left-arm file
(a transmission for a joint it does not have, which Drake refuses) loads with a warning naming it."""

import logging

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.planners.spatial_methods import plan_toppra_spatial
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from studies.arms_from_the_field import PinocchioCheck, field_scenario, independent_check


def _scenario(name, tmp_path):
    try:
        path = field_scenario(name, tmp_path)
    except QmtInputError as exc:  # example-robot-data (a test extra) missing: skip; anything else fails
        if "example-robot-data" not in str(exc):
            raise
        pytest.skip(str(exc))
    logging.getLogger("drake").setLevel(logging.ERROR)
    return load_spatial_scenario(path)


def test_so101_toppra_holds_by_pinocchio_and_is_carried(tmp_path):
    sc = _scenario("so101", tmp_path)
    assert sc.joint_names == ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"]
    plan = plan_toppra_spatial(sc, n_grid=400)
    assert plan.pose_error[:, 0].max() < 1e-6 and plan.pose_error[:, 1].max() < 1e-6
    checker = PinocchioCheck(sc)
    # the independent model is the planner's robot: Pinocchio's torques and hand state equal Drake's chain's
    q, qd, qdd = plan.trajectory.sample(np.linspace(0.0, plan.duration_s, 40))
    pin_state, drake_state = checker.state(q, qd, qdd), sc.chain.evaluate(q, qd, qdd)
    for key in ("joint_torque_Nm", "linear_acceleration_m_s2", "angular_acceleration_rad_s2", "position_m"):
        assert np.abs(pin_state[key] - drake_state[key]).max() < 1e-9, key
    ind = independent_check(sc, plan.trajectory, checker=checker)
    assert ind["rate_hz"] == 10 * sc.recheck_rate_hz
    assert ind["n_samples"] >= 10 * plan.duration_s * sc.recheck_rate_hz
    assert ind["max"] <= 1.0
    assert ind["max"] > 0.99  # a time-optimal plan: some limit is active
    faster = independent_check(sc, TimeScaled(plan.trajectory, 0.95), checker=checker)
    assert faster["max"] > 1.0  # the same path played 5 % faster breaks a limit, and the check says so
    for actuator in ("ideal", "dc_motor"):
        res = simulate_spatial(sc, plan.trajectory, actuator=actuator)
        assert res["outcome"] == "carried", (actuator, res["outcome"])


def test_talos_left_arm_with_a_transmission_for_a_missing_joint_loads(tmp_path):
    with pytest.warns(UserWarning, match="arm_left_1_joint"):
        sc = _scenario("talos_left_arm", tmp_path)
    assert sc.n_dof == 6 and sc.joint_names[0] == "arm_left_2_joint"
