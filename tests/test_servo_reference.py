"""The goal shaper inverts the firmware's discrete PID: fed its goals while the joint follows the
plan exactly, the law (written out here from the e-Manual's gains) asks exactly the PWM the plan needs."""

import numpy as np

from qmt_drake.catalog import PULSES_PER_RAD, SERVO_CATALOG, ServoGains
from qmt_drake.systems.servo_reference import pwm_for_motion, shaped_goals


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
