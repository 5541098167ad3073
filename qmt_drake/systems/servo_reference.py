"""Closed-loop-aware goal positions for Dynamixel position servos: the goal stream that makes the
servo's own loop produce the planned motion.

A position servo only moves when it sees an error: its PWM is the firmware's PID of the goal minus
the measured position (plus feedforward where FF1/FF2 are set). Streaming the plan itself as the
goal therefore lags it (about 0.1 rad on the CRANE-X7 tray transfer at full speed) and the executed
motion is slower and different from the planned one. `shaped_goals` inverts the loop instead: for
the planned joint motion (q, qd, qdd) at every servo period k it computes the PWM the motor needs
to produce it (inverse dynamics tau with gravity and the carried tray, through the servo's linear
torque-speed line: V = tau / (stall torque / V_s) + K_e qd, PWM = V / V_s * 885), and solves the
firmware's discrete law for the error e_k that gives that PWM:

    PWM_k = K_PP e_k + K_PI (I_{k-1} + e_k) + K_PD (e_k - e_{k-1}) + K_FF1 v_k + K_FF2 a_k,
    I_k = I_{k-1} + e_k          (e in pulses, I in pulse-samples; K_* as in catalog.ServoGains)

so e_k = (PWM_k - K_PI I_{k-1} + K_PD e_{k-1} - FF_k) / (K_PP + K_PI + K_PD), starting from the
rest state the co-simulation starts in (the integral holding the static load, no error). The goal
is q_k + e_k / (pulses per rad). It assumes the arm follows the plan (so the error the law sees is
the one computed) and ignores quantisation and the motor's electrical time constant; the test and
the study measure how close the executed motion comes (tracking error, executed limit ratio).

A servo period T longer than the plant step h holds each PWM over the hold's plant steps t_k + j h < t_k + T,
over which the plan moves on: the PWM needed at t_k lags the plan by about T/2 there (the DC drive's held
feedforward, joint_tracking.HoldCompensatedReference). `hold_mean_motion` gives the plan's mean over the hold's
steps (the one formula: joint_tracking.hold_offsets, "mean"), on which the needed PWM is then computed
(`shaped_goals`' pwm_speed_rad_s and the caller's torque); the firmware's P/I/D and feedforward terms keep the
plan at t_k, where the servo measures. At T = h the mean is the sample itself and nothing changes.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.catalog import PULSES_PER_RAD, PWM_FULL_SCALE, ServoGains
from qmt_drake.systems.joint_tracking import hold_offsets


def pwm_for_motion(joint_torque_Nm: np.ndarray, qd_rad_s: np.ndarray, sheets) -> np.ndarray:
    """PWM (control-table units, (K, n)) that the servos' linear torque-speed line needs to give the
    joint torques [N m] at the joint speeds [rad/s] (datasheet: stall torque at 0 speed, no-load
    speed at 0 torque, at the supply voltage)."""
    stall_per_volt = np.array([s.stall_torque_Nm / s.supply_voltage_V for s in sheets])
    ke = np.array([s.back_emf_V_s_per_rad for s in sheets])
    vs = np.array([s.supply_voltage_V for s in sheets])
    volts = joint_torque_Nm / stall_per_volt + ke * qd_rad_s
    return volts / vs * PWM_FULL_SCALE


def hold_mean_motion(sample, t_s: np.ndarray, period_s: float, plant_step_s: float):
    """(q, qd, qdd), each (K, n): the mean of sample(t) = (q, qd, qdd) over each servo hold's plant steps from the
    sample instants t_s [s] (module docstring; joint_tracking.hold_offsets)."""
    parts = [sample(np.asarray(t_s, float) + dt) for dt in hold_offsets(period_s, plant_step_s, "mean")]
    return tuple(np.mean([p[i] for p in parts], axis=0) for i in range(3))


def shaped_goals(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, joint_torque_Nm: np.ndarray, sheets,
                 gains: ServoGains, period_s: float, pwm_speed_rad_s: np.ndarray | None = None) -> np.ndarray:
    """Goal positions [rad], (K, n), for the planned samples q, qd, qdd (K, n) one servo period
    [s] apart, whose joint torques [N m] are joint_torque_Nm (module docstring). pwm_speed_rad_s: the
    speed whose back EMF the needed PWM includes (a held servo's: the plan's mean speed over the hold,
    hold_mean_motion, with joint_torque_Nm on the mean motion); None: qd."""
    kpp, kpi, kpd = gains.firmware()
    kff1, kff2 = gains.feedforward()
    pwm = pwm_for_motion(joint_torque_Nm, qd if pwm_speed_rad_s is None else pwm_speed_rad_s, sheets)
    v = qd * PULSES_PER_RAD * period_s  # target velocity, pulses per sample
    a = qdd * PULSES_PER_RAD * period_s**2  # target acceleration, pulses per sample^2
    integral = np.where(kpi > 0, pwm[0] / np.where(kpi > 0, kpi, 1.0), 0.0)  # at rest: holds the load
    e_prev = np.where(kpi > 0, 0.0, pwm[0] / kpp)  # P only: the sag that holds it
    e = np.empty_like(q)
    for k in range(q.shape[0]):
        ek = (pwm[k] - kpi * integral + kpd * e_prev - kff1 * v[k] - kff2 * a[k]) / (kpp + kpi + kpd)
        integral = integral + np.where(kpi > 0, ek, 0.0)
        e[k], e_prev = ek, ek
    return q + e / PULSES_PER_RAD
