"""The transfer monitor's summary computed after the run from per-step C++ logs.

The monitor only observes: nothing it computes feeds back into the loop. So instead of a Python
system called every plant step (TransferMonitor with a period), the diagram logs, every step and
in C++ (VectorLogSink), the plant state, the reference and the joint torque applied over the step
(`add_step_logs`), and `summary_from_logs` computes afterwards what the monitor would have:

    slip, tilt, gap   per sample from the payload's pose in the hand frame, which its joint's logged
                      coordinates are (`payload.pose_matrices`), then `transfer_monitor.motion_in_hand`
                      on the stack. The per-step monitor gets the same pose through world coordinates
                      (X_WH^-1 X_WP), so the two agree to rounding of world positions (~1e-16 m)
    detached_at_s     first sample with gap > detach_gap_m or slip > detach_slip_m
    tracking          max over samples and joints of |q_des - q|
    motor peaks, energy  the delivered system's motor_torque / electrical_power of each sample
                      (AppliedMotorSignals: dc_motor's per-joint kernel `_motor_side`, as the system
                      and `motor_signals_from_joint_torque` run it; any other
                      signals system, e.g. the ideal source's: its own output ports on a scratch
                      context), energy = sum of h * P over the samples (the monitor's rectangle rule)

Samples: the monitor's periodic update at t_k = k h sees the state reached at t_k, paired with the
actuation latched over the step into t_k; a periodic publish at t_k (the logs) sees the same. The
monitor updates at t_0 ... t_{N-1} (an update at the final time would come with the next step);
the logs also hold t_N when the final time is a multiple of h, which is then left out, so the
summary is the monitor's (tests/test_cosim.py compares both on the same run). Only the implicitly stepped loop is logged this way (the explicit
motors' signals depend on the PID's voltage and, with inductance, on a continuous state): the
explicit scheme keeps the per-step monitor.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.primitives import LogVectorOutput

from qmt_drake.systems.dc_motor import AppliedMotorSignals, _inverse_rows, _motor_side
from qmt_drake.systems.payload import payload_joint, pose_matrices
from qmt_drake.systems.transfer_monitor import SUMMARY_FIELDS, motion_in_hand

STEP_LOGS = ("plant_state", "desired_state", "applied_joint_torque")


def add_step_logs(builder, plant, desired_state_port, applied_joint_torque_port, time_step_s: float) -> dict:
    """C++ loggers sampling every plant step: {name: VectorLogSink} for STEP_LOGS."""
    ports = dict(zip(STEP_LOGS, (plant.get_state_output_port(), desired_state_port, applied_joint_torque_port)))
    return {name: LogVectorOutput(port, builder, time_step_s) for name, port in ports.items()}


def _delivered_signals(delivered, tau: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(motor_torque, electrical_power), each (K, n), of the signals system for applied joint
    torques tau and joint speeds qd, both (K, n)."""
    if isinstance(delivered, AppliedMotorSignals):
        # dc_motor's per-joint kernel (what motor_signals_from_joint_torque and AppliedMotorSignals
        # run), its per-joint constants taken once.
        rows = _inverse_rows(delivered.params)
        out = [[_motor_side(t, w, *r) for t, w, r in zip(tk, wk, rows)] for tk, wk in zip(tau.tolist(), qd.tolist())]
        arr = np.array(out)  # (K, n, 4): v, i, tau_m, P_el
        return arr[:, :, 2], arr[:, :, 3]
    ctx = delivered.CreateDefaultContext()
    tau_port, qd_port = delivered.GetInputPort("applied_joint_torque"), delivered.GetInputPort("joint_velocity")
    tm_port, pw_port = delivered.GetOutputPort("motor_torque"), delivered.GetOutputPort("electrical_power")
    tm, pw = [], []
    for t, w in zip(tau, qd):
        tau_port.FixValue(ctx, t)
        qd_port.FixValue(ctx, w)
        tm.append(tm_port.Eval(ctx).copy())
        pw.append(pw_port.Eval(ctx).copy())
    return np.array(tm), np.array(pw)


def step_samples(td, root_context) -> dict:
    """The logged samples the monitor would have seen: {'t_s': (K,), 'plant_state': (K, nx),
    'desired_state': (K, 2n), 'applied_joint_torque': (K, n)} (a sample at the final time left out)."""
    logs = {name: td.step_logs[name].FindLog(root_context) for name in STEP_LOGS}
    t = logs["plant_state"].sample_times()
    keep = t < td.t_final_s  # the monitor updates at every sample time before the final time (exactly)
    out = {"t_s": t[keep].copy()}
    for name, log in logs.items():
        out[name] = log.data().T[keep].copy()
    return out


def summary_from_logs(td, root_context) -> np.ndarray:
    """The TransferMonitor summary vector (SUMMARY_FIELDS + peak motor torques) of a finished run
    of `td` in root_context (see the module docstring)."""
    s = step_samples(td, root_context)
    plant, n = td.plant, len(td.q_start)
    nq = plant.num_positions()
    x = s["plant_state"]
    # Arm joint positions / velocities among the plant's generalized coordinates.
    q_arm_idx = plant.GetPositionsFromArray(td.arm_instance, np.arange(nq, dtype=float)).astype(int)
    v_arm_idx = plant.GetVelocitiesFromArray(td.arm_instance, np.arange(plant.num_velocities(), dtype=float)).astype(int)
    q_arm, qd_arm = x[:, q_arm_idx], x[:, nq + v_arm_idx]
    # Payload pose in the hand frame per sample: its joint's coordinates (quaternion, p_HP).
    joint = payload_joint(plant, td.payload_body)
    M = pose_matrices(x[:, joint.position_start():joint.position_start() + 7])
    p0, z0 = td.monitor.seated_axes
    slip, tilt, gap = motion_in_hand(M, p0, z0)
    gap_lim, slip_lim = td.monitor.detach_thresholds_m
    lost = np.flatnonzero((gap > gap_lim) | (slip > slip_lim))
    tm, pw = _delivered_signals(td.delivered, s["applied_joint_torque"], qd_arm)
    out = np.empty(len(SUMMARY_FIELDS) + n)
    out[0] = slip.max()
    out[1] = tilt.max()
    out[2] = s["t_s"][lost[0]] if len(lost) else math.nan
    out[3] = np.abs(s["desired_state"][:, :n] - q_arm).max()
    out[4] = td.time_step_s * pw.sum()
    out[5] = gap.max()
    out[6:] = np.abs(tm).max(axis=0)
    return out
