"""The transfer monitor's summary computed after the run from per-step C++ logs.

The monitor only observes: nothing it computes feeds back into the loop. So instead of a Python
system called every plant step (TransferMonitor with a period), the diagram logs, every step and
in C++ (VectorLogSink), the plant state, the reference and the joint torque applied over the step
(`add_step_logs`), and `summary_from_logs` computes afterwards what the monitor would have:

    slip, tilt, gap   per sample from the payload's joint coordinates, its pose in the hand frame
                      (`transfer_monitor.motion_from_joint` on numpy columns). The per-step monitor
                      gets the same quantities from body poses through world coordinates
                      (X_WH^-1 X_WP, `motion_in_hand`), an independent route: the two agree to the
                      rounding of world positions (~1e-16 m, tests/test_cosim.py)
    detached_at_s     first sample with gap > detach_gap_m or slip > detach_slip_m
    tracking          max over samples and joints of |q_des - q|
    motor peaks, energy  the delivered motor_torque / electrical_power of each sample (DC motors:
                      dc_motor's `motor_inverse`, the formula the applied-signals system runs, on
                      numpy columns; the ideal source: its own output ports on a scratch context),
                      energy = sum of h * P over the samples (the monitor's rectangle rule)

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
from pydrake.systems.primitives import LogVectorOutput, Multiplexer

from qmt_drake.systems.dc_motor import motor_inverse, motor_joints
from qmt_drake.systems.payload import payload_joint
from qmt_drake.systems.scalar_ops import NUMPY
from qmt_drake.systems.transfer_monitor import DETACH_GAP_M, DETACH_SLIP_M, SUMMARY_FIELDS, motion_from_joint

STEP_LOGS = ("plant_state", "desired_state", "applied_joint_torque")


def add_step_logs(builder, plant, desired_state_port, applied_joint_torque_port, time_step_s: float) -> dict:
    """One C++ logger sampling every plant step the STEP_LOGS signals side by side (a Multiplexer in
    front: one publish per step instead of three). Returns {"logger": VectorLogSink, "widths": {name: size}}."""
    ports = dict(zip(STEP_LOGS, (plant.get_state_output_port(), desired_state_port, applied_joint_torque_port)))
    widths = {name: port.size() for name, port in ports.items()}
    mux = builder.AddNamedSystem("step_log_signals", Multiplexer(list(widths.values())))
    for k, port in enumerate(ports.values()):
        builder.Connect(port, mux.get_input_port(k))
    return {"logger": LogVectorOutput(mux.get_output_port(), builder, time_step_s), "widths": widths}


def _delivered_signals(td, tau: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(motor_torque, electrical_power), each (K, n), of the delivered signals for applied joint
    torques tau and joint speeds qd, both (K, n): with DC motors dc_motor's `motor_inverse` (what the
    applied-signals system runs) on whole columns; otherwise the signals system's own output ports
    on a scratch context."""
    if td.motor_params is not None:
        cols = [motor_inverse(tau[:, k], qd[:, k], joint, NUMPY) for k, joint in enumerate(motor_joints(td.motor_params))]
        return np.column_stack([c[2] for c in cols]), np.column_stack([c[3] for c in cols])
    delivered = td.delivered
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
    log = td.step_logs["logger"].FindLog(root_context)
    t = log.sample_times()
    keep = t < td.t_final_s  # the monitor updates at every sample time before the final time (exactly)
    data = log.data().T[keep]
    out = {"t_s": t[keep].copy()}
    start = 0
    for name, width in td.step_logs["widths"].items():
        out[name] = data[:, start:start + width].copy()
        start += width
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
    slip, tilt, gap = motion_from_joint(x[:, joint.position_start():joint.position_start() + 7].T, NUMPY)
    gap_lim, slip_lim = DETACH_GAP_M, DETACH_SLIP_M
    lost = np.flatnonzero((gap > gap_lim) | (slip > slip_lim))
    tm, pw = _delivered_signals(td, s["applied_joint_torque"], qd_arm)
    out = np.empty(len(SUMMARY_FIELDS) + n)
    out[0] = slip.max()
    out[1] = tilt.max()
    out[2] = s["t_s"][lost[0]] if len(lost) else math.nan
    out[3] = np.abs(s["desired_state"][:, :n] - q_arm).max()
    out[4] = td.time_step_s * pw.sum()
    out[5] = gap.max()
    out[6:] = np.abs(tm).max(axis=0)
    return out
