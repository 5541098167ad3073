"""Limits of seed 000 evaluated on sampled trajectories.

- payload moment |tau_M| = m_o * r_G * |a_tip|, with a_tip the in-plane acceleration of the hand
  (eq. 2-24, 3-10, 4-33), against the scenario's moment limit;
- motor torque |tau_A,i| = |tau_i| / N_i, with tau_i the joint torque of inverse dynamics
  including the reflected rotor inertia N_i^2 * J_r,i (eq. 2-34), against each motor's limit;
- joint positions inside the URDF's joint ranges.

A ratio is peak / limit; a plan is feasible when every ratio is <= 1 and the joints stay in range.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np



@dataclass(frozen=True)
class SampleLimits:
    """Per-sample limit quantities (S,) / (S, n)."""

    moment_Nm: np.ndarray
    motor_torque_Nm: np.ndarray
    joint_violation_rad: np.ndarray  # how far outside its range each joint is (0 inside)


def sample_limits(scenario, q, qd, qdd) -> SampleLimits:
    arm = scenario.arm
    a, tau = arm.tip_acceleration_and_joint_torque(q, qd, qdd)
    moment = scenario.moment_per_accel_kgm * np.hypot(a[..., 0], a[..., 1])
    motor = tau / arm.gear_ratio
    out = np.maximum(arm.joint_lower_rad - q, 0.0) + np.maximum(q - arm.joint_upper_rad, 0.0)
    return SampleLimits(moment, motor, out)


def limit_columns(scenario, q, qd, qdd) -> np.ndarray:
    """Per-sample columns whose maxima decide feasibility, (S, 1 + 3n): the moment ratio, each
    motor's torque ratio, and each joint's excess over its upper and under its lower limit (rad,
    <= 0 inside the range)."""
    lim = sample_limits(scenario, q, qd, qdd)
    arm = scenario.arm
    return np.concatenate([
        (lim.moment_Nm / scenario.limits.moment_limit_Nm)[:, None],
        np.abs(lim.motor_torque_Nm) / scenario.limits.motor_torque_limit_Nm,
        q - arm.joint_upper_rad, arm.joint_lower_rad - q], axis=1)


@dataclass(frozen=True)
class BatchPeaks:
    """Peak ratios of K candidates (inf where a candidate defines no trajectory)."""

    motion_time_s: np.ndarray  # (K,)
    peak_moment_ratio: np.ndarray  # (K,)
    peak_motor_torque_ratio: np.ndarray  # (K, n)
    joint_range_ok: np.ndarray  # (K,) bool
    valid: np.ndarray  # (K,) bool: the genes define a trajectory

    @classmethod
    def from_columns(cls, motion_time_s, valid, peaks: np.ndarray, n: int) -> "BatchPeaks":
        joint_excess = peaks[:, 1 + n:].max(axis=1)
        return cls(motion_time_s, peaks[:, 0], peaks[:, 1:1 + n], joint_excess <= 1e-12, valid)

    @property
    def worst_ratio(self) -> np.ndarray:
        return np.maximum(self.peak_moment_ratio, self.peak_motor_torque_ratio.max(axis=1))

    @property
    def feasible(self) -> np.ndarray:
        return self.valid & self.joint_range_ok & (self.worst_ratio <= 1.0)


@dataclass(frozen=True)
class LimitReport:
    """Limits of one trajectory on one sampling, in the units of its field names."""

    rate_hz: float
    motion_time_s: float
    peak_moment_Nm: float
    moment_limit_Nm: float
    peak_moment_ratio: float
    peak_moment_time_s: float
    peak_motor_torque_Nm: list
    motor_torque_limit_Nm: list
    peak_motor_torque_ratio: float
    joint_range_ok: bool
    feasible: bool

    def to_dict(self) -> dict:
        return asdict(self)


def limit_report(scenario, t_s, q, qd, qdd, rate_hz: float, motion_time_s: float,
                 valid: bool = True) -> LimitReport:
    lim = sample_limits(scenario, q, qd, qdd)
    k = int(np.argmax(lim.moment_Nm))
    motor_peak = np.abs(lim.motor_torque_Nm).max(axis=0)
    motor_lim = scenario.limits.motor_torque_limit_Nm
    moment_ratio = float(lim.moment_Nm[k] / scenario.limits.moment_limit_Nm)
    motor_ratio = float(np.max(motor_peak / motor_lim))
    joint_ok = bool(np.all(lim.joint_violation_rad <= 1e-12))
    return LimitReport(
        rate_hz=float(rate_hz), motion_time_s=float(motion_time_s),
        peak_moment_Nm=float(lim.moment_Nm[k]), moment_limit_Nm=scenario.limits.moment_limit_Nm,
        peak_moment_ratio=moment_ratio, peak_moment_time_s=float(t_s[k]),
        peak_motor_torque_Nm=motor_peak.tolist(), motor_torque_limit_Nm=motor_lim.tolist(),
        peak_motor_torque_ratio=motor_ratio, joint_range_ok=joint_ok,
        feasible=bool(valid and joint_ok and moment_ratio <= 1.0 and motor_ratio <= 1.0))
