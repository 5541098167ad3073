"""The goal shaper inverts the firmware's discrete PID: fed its goals while the joint follows the
plan exactly, the law (written out here from the e-Manual's gains) asks exactly the PWM the plan needs."""

import numpy as np

from qmt_drake.catalog import PULSES_PER_RAD, SERVO_CATALOG, ServoGains
from qmt_drake.systems.servo_reference import hold_mean_motion, pwm_for_motion, shaped_goals


def test_the_firmware_law_on_shaped_goals_gives_the_needed_pwm():
    rng = np.random.default_rng(3)
    sheets = [SERVO_CATALOG["XM540-W270"], SERVO_CATALOG["XM430-W350"]]
    gains = ServoGains((1000, 1040), (150, 0), (200, 250), (300, 0), (0, 40))
    dt, k = 1e-3, 400
    t = np.arange(k) * dt
    q = np.column_stack([0.3 * np.sin(3 * t), -0.2 * np.cos(2 * t)])
    qd = np.column_stack([0.9 * np.cos(3 * t), 0.4 * np.sin(2 * t)])
    qdd = np.column_stack([-2.7 * np.sin(3 * t), 0.8 * np.cos(2 * t)])
    tau = rng.normal(size=(k, 2)) * 0.5 + 1.0
    goals = shaped_goals(q, qd, qdd, tau, sheets, gains, dt)
    need = pwm_for_motion(tau, qd, sheets)
    kpp, kpi, kpd = gains.firmware()
    kff1, kff2 = gains.feedforward()
    e = (goals - q) * PULSES_PER_RAD
    integral = np.where(kpi > 0, need[0] / np.where(kpi > 0, kpi, 1), 0.0)
    e_prev = np.where(kpi > 0, 0.0, need[0] / kpp)
    for j in range(k):
        integral = integral + np.where(kpi > 0, e[j], 0.0)
        pwm = (kpp * e[j] + kpi * integral + kpd * (e[j] - e_prev)
               + kff1 * qd[j] * PULSES_PER_RAD * dt + kff2 * qdd[j] * PULSES_PER_RAD * dt**2)
        np.testing.assert_allclose(pwm, need[j], rtol=1e-9, atol=1e-9)
        e_prev = e[j]


def _firmware_pwm(goals, q, qd, qdd, need0, gains, dt):
    """The firmware's PWM at each servo sample on goals, the joint exactly on the plan (test above)."""
    kpp, kpi, kpd = gains.firmware()
    kff1, kff2 = gains.feedforward()
    e = (goals - q) * PULSES_PER_RAD
    integral = np.where(kpi > 0, need0 / np.where(kpi > 0, kpi, 1), 0.0)
    e_prev = np.where(kpi > 0, 0.0, need0 / kpp)
    out = []
    for j in range(len(q)):
        integral = integral + np.where(kpi > 0, e[j], 0.0)
        out.append(kpp * e[j] + kpi * integral + kpd * (e[j] - e_prev)
                   + kff1 * qd[j] * PULSES_PER_RAD * dt + kff2 * qdd[j] * PULSES_PER_RAD * dt**2)
        e_prev = e[j]
    return np.array(out)


def test_a_held_servo_pwm_is_the_plans_mean_over_the_hold():
    """Servo period T = 4 ms on 1 ms plant steps, the plan at constant acceleration (speed ramp) and a torque
    affine in speed and acceleration: the needed PWM is a ramp alpha + beta t. Shaped on the hold's mean motion
    (hold_mean_motion), the firmware's held PWM is the ramp's mean over the hold's steps, alpha + beta (t_k +
    (T - h)/2): what the every-step PWM would average; shaped at the sample instant it is beta (T - h)/2 short."""
    sheets = [SERVO_CATALOG["XM540-W270"], SERVO_CATALOG["XM430-W350"]]
    gains = ServoGains((1000, 1040), (150, 0), (200, 250), (300, 0), (0, 40))
    T, h, acc = 4e-3, 1e-3, np.array([2.0, -3.0])

    def sample(t):
        t = np.asarray(t, float)[:, None]
        return 0.1 + 0.5 * acc * t**2, acc * t + 0 * t, acc + 0 * t

    def torque(q, qd, qdd):
        return 0.8 + 0.3 * qd + 0.05 * qdd

    t = np.arange(60) * T
    q, qd, qdd = sample(t)
    held = hold_mean_motion(sample, t, T, h)
    goals = shaped_goals(q, qd, qdd, torque(*held), sheets, gains, T, pwm_speed_rad_s=held[1])
    need = pwm_for_motion(torque(*held), held[1], sheets)
    pwm = _firmware_pwm(goals, q, qd, qdd, need[0], gains, T)
    steps = [sample(t + j * h) for j in range(round(T / h))]
    every_step_mean = np.mean([pwm_for_motion(torque(*s), s[1], sheets) for s in steps], axis=0)
    np.testing.assert_allclose(pwm, every_step_mean, rtol=1e-9, atol=1e-9)
    instant = _firmware_pwm(shaped_goals(q, qd, qdd, torque(q, qd, qdd), sheets, gains, T), q, qd, qdd,
                            pwm_for_motion(torque(q, qd, qdd), qd, sheets)[0], gains, T)
    beta = (pwm_for_motion(torque(*sample([1.0])), sample([1.0])[1], sheets)
            - pwm_for_motion(torque(*sample([0.0])), sample([0.0])[1], sheets))[0]
    np.testing.assert_allclose(instant - pwm, -beta * (T - h) / 2 + 0 * pwm, rtol=1e-9, atol=1e-9)


def test_goals_at_a_servo_period_of_one_plant_step_are_unchanged():
    """The published crane-tray runs (1 ms servo period on the 1 ms plant step): the hold's mean is the sample
    itself and plan_schedule's goals are the instant-shaped ones bit for bit; at 4 ms they move (the mean)."""
    from types import SimpleNamespace

    from qmt_drake import load_scenario
    from qmt_drake.tray.execute import plan_schedule

    sc = load_scenario("crane-tray")
    q0, q1 = np.array([0.2, -0.4, 0.9]), np.array([0.6, -0.1, 0.5])

    def sample(t):
        s = np.clip(np.asarray(t, float) / 0.5, 0.0, 1.0)[:, None]
        return q0 + (q1 - q0) * (3 * s**2 - 2 * s**3), (q1 - q0) * (6 * s - 6 * s**2) / 0.5, (q1 - q0) * (6 - 12 * s) / 0.25

    plan = SimpleNamespace(motion_time_s=0.5, method="test", sample=sample)
    sched = plan_schedule(plan, period_s=1e-3, shaped_for=sc)
    t_all = np.arange(0.0, 0.5 + 1.5, 1e-3)
    q, qd, qdd = sample(t_all)
    goals = shaped_goals(q, qd, qdd, sc.arm.joint_torque(q, qd, qdd), sc.actuator.datasheets(), sc.actuator.gains(),
                         1e-3)
    np.testing.assert_array_equal(sched.goals[1:], goals)
    held = plan_schedule(plan, period_s=4e-3, shaped_for=sc)
    instant = plan_schedule(plan, period_s=4e-3, shaped_for=sc, plant_step_s=4e-3)
    assert np.abs(held.goals - instant.goals).max() > 1e-5
