"""The spatial co-simulation through DC motors with gears (sim/spatial_actuation.py): refusals, the
feedforward voltage against the motor model backwards, the reflected rotor inertia in the plant, a
static gravity hold against its closed form, the TOPP-RA plan carried and arriving, and the torque cap."""

from __future__ import annotations

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.suction import GripModel
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD
from qmt_drake.planners.spatial_methods import plan_toppra_spatial
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive, set_drive_inertia
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_motor import parse_motor_section
from qmt_drake.spatial_task import SCENARIO_DIR, load_spatial_scenario
from qmt_drake.systems.dc_motor import motor_inverse, motor_joints
from qmt_drake.systems.joint_tracking import JointPidController, pd_voltage
from tests.spatial_fixtures import edited_copy, load_or_skip, shipped_toppra

SHIPPED = SCENARIO_DIR / "ur5-suction-bins.yaml"


@pytest.fixture(scope="module")
def sc():
    return load_or_skip("ur5-suction-bins")


@pytest.fixture(scope="module")
def toppra(sc):
    return shipped_toppra(sc.name)


class Hold:
    """A plan that stays at q [rad] for duration_s (the spatial trajectory interface)."""

    def __init__(self, q, duration_s):
        self.q, self.duration_s = np.asarray(q, float), duration_s

    def sample(self, t):
        t = np.atleast_1d(t)
        z = np.zeros((len(t), len(self.q)))
        return np.tile(self.q, (len(t), 1)), z, z.copy()


def _strong_grip(sc):
    """A cup that never lets go, so the hold's statics include the part."""
    return GripModel(sc.grip.radius_m, 1e4, 5.0, face_normal=sc.grip.basis[2])


def test_dc_motor_refused_without_motor_constants(sc, tmp_path):
    bare = load_spatial_scenario(edited_copy(SHIPPED, tmp_path, lambda raw: raw["actuators"].pop("motor")))
    assert bare.motor is None
    hold = Hold(bare.q_poses_rad[0], 0.1)
    with pytest.raises(QmtInputError, match="actuators.motor with torque_constant_Nm_per_A, resistance_ohm, "
                                            "voltage_limit_V") as e:
        simulate_spatial(bare, hold, actuator="dc_motor")
    assert "\n" not in str(e.value)
    for kw, msg in (({"actuator": "stepper"}, "choose one of ideal, dc_motor"),
                    ({"actuator": "dc_motor", "feedforward": "half"}, "choose one of none, back-emf, full"),
                    ({"feedforward": "none"}, "applies to actuator dc_motor")):
        with pytest.raises(QmtInputError, match=msg):
            simulate_spatial(sc, hold, **kw)


@pytest.mark.parametrize("motor, message", [
    ({"resistance_ohm": 0.35, "voltage_limit_V": 48.0}, "lacks torque_constant_Nm_per_A"),
    ({"torque_constant_Nm_per_A": [0.1] * 5, "resistance_ohm": 0.35, "voltage_limit_V": 48.0},
     "one number or a list of 6 numbers"),
    ({"torque_constant_Nm_per_A": 0.1, "resistance_ohm": -0.35, "voltage_limit_V": 48.0}, "resistance_ohm"),
    ({"torque_constant_Nm_per_A": 0.1, "resistance_ohm": 0.35, "voltage_limit_V": 48.0, "gear_efficiency": 1.2},
     r"gear_efficiency must be in \(0, 1\]"),
    ({"torque_constant_Nm_per_A": 0.001, "resistance_ohm": 5.0, "voltage_limit_V": 12.0},
     "shoulder_pan_joint's motor reaches 0.2424 N m at stall .* below its torque limit 150 N m"),
    ({"torque_constant_Nm_per_A": 0.1, "resistance_ohm": 0.35, "voltage_limit_V": 48.0, "kv": 1.0}, "unknown key 'kv'"),
    ({"torque_constant_Nm_per_A": 0.1, "resistance_ohm": 0.35, "voltage_limit_V": 48.0, "integral_rate_per_s": -1.0},
     r"integral_rate_per_s must be a non-negative number \(or a list of 6.*got -1$"),
    ({"torque_constant_Nm_per_A": 0.1, "resistance_ohm": 0.35, "voltage_limit_V": 48.0, "integral_rate_per_s": 30.0},
     "integral_rate_per_s must be at most 10 1/s"),
])
def test_motor_section_refused_in_one_line(sc, motor, message):
    with pytest.raises(QmtInputError, match=message) as e:
        parse_motor_section(motor, sc.joint_names, sc.torque_limit_Nm, sc.drive["gear_ratio"], "x: actuators.motor")
    assert "\n" not in str(e.value)


def test_shipped_motors_reach_rated_torque_at_the_velocity_limit(sc):
    m = sc.motor
    N = sc.drive["gear_ratio"]
    np.testing.assert_allclose(N * m.gear_efficiency * m.torque_constant_Nm_per_A * m.current_limit_A,
                               sc.torque_limit_Nm)
    assert np.all(m.resistance_ohm * m.current_limit_A + m.torque_constant_Nm_per_A * N * sc.velocity_limit_rad_s
                  <= m.voltage_limit_V)


def test_feedforward_voltage_is_the_motor_model_backwards(sc):
    """The full feedforward (back EMF + inverse-dynamics torque) of the PD law equals
    dc_motor.motor_inverse's voltage at the desired speed (loss-free gear: the shipped default)."""
    drive = SpatialMotorDrive.for_scenario(sc, sc.q_poses_rad[0], "full")
    mp, n = drive.params, drive.params.n
    pid = JointPidController(drive.gains, mp.gear_ratio, mp.voltage_limit_V, motor=mp, back_emf_feedforward=True,
                             torque_feedforward=True)
    rng = np.random.default_rng(0)
    qd, tau = rng.uniform(-1.0, 1.0, n), rng.uniform(-10.0, 10.0, n)
    x = np.r_[np.zeros(n), qd]
    v = pd_voltage(pid, x, x, tau)  # zero tracking error: the feedforward alone
    expected = [motor_inverse(t, w, j)[0] for t, w, j in zip(tau, qd, motor_joints(mp))]
    np.testing.assert_allclose(v, expected, rtol=1e-12)


def test_reflected_rotor_inertia_enters_the_mass_matrix(sc):
    plain, _, _ = load_arm_plant(sc.urdf, sc.hand_frame, effort_limit_Nm=sc.torque_limit_Nm,
                                 velocity_limit_rad_s=sc.velocity_limit_rad_s)
    geared, H, _ = load_arm_plant(sc.urdf, sc.hand_frame, effort_limit_Nm=sc.torque_limit_Nm,
                                  velocity_limit_rad_s=sc.velocity_limit_rad_s, finalize=False)
    set_drive_inertia(geared, H.model_instance(), sc)
    geared.Finalize()
    M = []
    for p in (plain, geared):
        c = p.CreateDefaultContext()
        p.SetPositions(c, sc.q_poses_rad[0])
        M.append(p.CalcMassMatrix(c))
    np.testing.assert_allclose(M[1] - M[0], np.diag(sc.drive["reflected_inertia_kgm2"]), atol=1e-12)


def test_static_gravity_hold_matches_the_closed_form(sc):
    """Holding the pick pose against gravity without feedforward: at rest i = v / R with
    v = Kp N e, so the arm settles where N k_t i equals the gravity torque (Drake, at the settled pose),
    e = R tau_g / (N^2 k_t Kp) and i = tau_g / (N k_t). With the full feedforward the error vanishes
    and the current is the same."""
    q0 = sc.q_poses_rad[0]
    arm, _, _ = load_arm_plant(sc.urdf, sc.hand_frame, carried=sc.body.as_dict(), effort_limit_Nm=sc.torque_limit_Nm,
                               velocity_limit_rad_s=sc.velocity_limit_rad_s)
    ctx = arm.CreateDefaultContext()
    for ff in ("none", "full"):
        r = simulate_spatial(sc, Hold(q0, 1.5), actuator="dc_motor", feedforward=ff, grip=_strong_grip(sc))
        assert r["lost_at_s"] is None  # held ("unfinished" without feedforward: the sag exceeds the tolerance)
        e, i = np.array(r["final_tracking_error_rad"]), np.array(r["final_current_A"])
        arm.SetPositions(ctx, q0 - e)
        tau_g = -arm.CalcGravityGeneralizedForces(ctx)  # the torque that holds the arm (and part) still
        drive = SpatialMotorDrive.for_scenario(sc, q0, ff)
        mp = drive.params
        N, kt, R = mp.gear_ratio, mp.torque_constant_Nm_per_A, mp.resistance_ohm
        scale = np.abs(tau_g).max()
        assert scale > 10.0  # the shoulder and elbow carry the arm
        np.testing.assert_allclose(N * kt * i, tau_g, atol=1e-4 * scale)
        expected_e = R * tau_g / (N ** 2 * kt * drive.gains.kp_V_per_rad) if ff == "none" else np.zeros(6)
        np.testing.assert_allclose(e, expected_e, atol=1e-7)
        if ff == "none":
            assert np.abs(e).max() > 1e-3  # a visible sag, so the check above is not trivially zero


def test_integral_term_removes_the_gravity_sag(sc, tmp_path):
    """With the PID's integral (actuators.motor.integral_rate_per_s) and no feedforward, the hold's sag
    (the closed form of the test above: e = R tau_g / (N^2 k_t Kp)) decays at about that rate: after
    2 s at 5 1/s it is under 1 % of the PD's, and the current still carries the gravity torque."""
    pid_sc = load_spatial_scenario(edited_copy(SHIPPED, tmp_path,
                                               lambda raw: raw["actuators"]["motor"].update(integral_rate_per_s=5.0)))
    q0 = pid_sc.q_poses_rad[0]
    drive = SpatialMotorDrive.for_scenario(pid_sc, q0, "none")
    np.testing.assert_allclose(drive.gains.ki_V_per_rad_s, 5.0 * drive.gains.kp_V_per_rad)
    pd = simulate_spatial(sc, Hold(q0, 2.0), actuator="dc_motor", feedforward="none", grip=_strong_grip(sc))
    pid = simulate_spatial(pid_sc, Hold(q0, 2.0), actuator="dc_motor", feedforward="none", grip=_strong_grip(sc))
    e_pd, e_pid = np.abs(pd["final_tracking_error_rad"]), np.abs(pid["final_tracking_error_rad"])
    assert e_pd.max() > 1e-3 and pid["lost_at_s"] is None
    assert e_pid.max() < 0.01 * e_pd.max()
    np.testing.assert_allclose(pid["final_current_A"], pd["final_current_A"], rtol=0.02, atol=1e-3)


def test_toppra_plan_carried_and_arrives_through_dc_motors(sc, toppra):
    """The TOPP-RA plan (carried by the ideal co-simulation) through the motors: carried, arrives within
    the arrival tolerance, tracks within it along the motion, and the motors stay under their torque
    limits; 1.5x faster the part is lost."""
    r = simulate_spatial(sc, toppra.trajectory, actuator="dc_motor")
    assert r["outcome"] == "carried" and r["actuator"] == "dc_motor"
    assert r["final_goal_error_rad"] <= ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    assert r["max_tracking_error_rad"] <= ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    assert r["max_motor_torque_over_limit"] <= 1.0
    fast = simulate_spatial(sc, TimeScaled(toppra.trajectory, 0.67), actuator="dc_motor")
    assert fast["outcome"] == "detached"


def test_motor_torque_capped_at_the_limit_when_saturated(sc, toppra):
    """Played 2.5x faster than planned (part held by a cup that never lets go), the big joints ask for
    more than their rated torque: the current clips at I_max = tau_max / (N k_t), the delivered motor
    torque N k_t i reaches the limit and does not exceed it, the tracking error grows, and the arm
    still arrives."""
    r = simulate_spatial(sc, TimeScaled(toppra.trajectory, 0.4), actuator="dc_motor", grip=_strong_grip(sc))
    assert 0.999 <= r["max_motor_torque_over_limit"] <= 1.0 + 1e-9
    np.testing.assert_allclose(np.array(r["max_current_A"])[:2], sc.motor.current_limit_A[:2], rtol=1e-9)
    assert r["max_tracking_error_rad"] > 10 * ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    assert r["final_goal_error_rad"] <= ARRIVAL_TOLERANCE_DC_MOTOR_RAD


def test_panda_tray_plan_carried_through_dc_motors():
    """The tray hand through the shipped Panda's DC motors (actuators.motor): the TOPP-RA plan, which
    puts the cup's contact at its limit, is carried with the full feedforward and tracks within a
    milliradian; without feedforward the lag leaves the arm short of its goal (unfinished), with the
    cup still on the tray."""
    panda = load_or_skip("panda-tray-cup")
    plan = plan_toppra_spatial(panda)
    full = simulate_spatial(panda, plan.trajectory, actuator="dc_motor", feedforward="full")
    assert full["outcome"] == "carried" and full["actuator"] == "dc_motor"
    assert full["max_tracking_error_rad"] < 1e-3 and full["max_motor_torque_over_limit"] <= 1.0 + 1e-9
    assert full["max_grip_ratio_while_held"] > 0.9  # the plan runs the contact near its limit
    bare = simulate_spatial(panda, plan.trajectory, actuator="dc_motor", feedforward="none")
    assert bare["outcome"] == "unfinished" and bare["final_goal_error_rad"] > ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    assert bare["max_slide_m"] < 0.01
