"""A spatial scenario's optional motor constants (`actuators.motor`), for the DC-motor co-simulation.

    actuators:
      motor:                              # one number for every joint, or a list with one per joint
        torque_constant_Nm_per_A: [0.10, 0.10, 0.10, 0.05, 0.05, 0.05]   # k_t = K_e in SI
        resistance_ohm: [0.35, 0.35, 0.35, 1.2, 1.2, 1.2]                # armature (terminal) resistance
        voltage_limit_V: 48.0                                            # supply / amplifier limit
        gear_efficiency: 1.0              # optional, (0, 1], default 1 (a loss-free gear, as the planners assume)
        integral_rate_per_s: 0.0          # optional, >= 0, default 0 (a PD law): the PID's integral gain as a
                                          # rate of the loop's stiffness, Ki = K * rate (joint side)

The law's control period is not a key here (it would change the scenario's identity, plan_identity.py, which
plans carry): SpatialMotorDrive.for_scenario(control_period_s=) or a sweep's loop_period_s set it.

The current limit is not a key: it is the joint's torque limit at the motor, I_max = tau_max / (N eta k_t),
so the motors never deliver more than the actuators section's torque_limit_Nm (the planners' limit).
A motor that cannot reach that torque even at stall through the gear (N eta k_t V_max / R < tau_max)
is refused: the planners would plan torques the motor cannot make. The gear ratio and the rotor inertia
stay in the actuators section (gear_ratio, rotor_inertia_kgm2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qmt_drake.config import fields as F
from qmt_drake.errors import QmtInputError

MOTOR_KEYS = ("torque_constant_Nm_per_A", "resistance_ohm", "voltage_limit_V")
OPTIONAL_KEYS = ("gear_efficiency", "integral_rate_per_s")
# the loop s^3 + 60 s^2 + 900 s + 900 rate (critically damped at 30 rad/s, sim/spatial_actuation) keeps its slow
# pole pair damped at 0.55 or better up to rate 10 1/s (0.28 at 20, unstable at 60)
MAX_INTEGRAL_RATE_PER_S = 10.0
# the slowest sample-and-hold law: its half-period delay costs the loop 8.6 degrees of phase at its 30 rad/s (38 at
# the 132 rad/s of the Panda's wrist joints, damped by their back EMF alone); the Panda tray's shaped TOPP-RA run is
# still carried at 10 ms (2.1 mrad tracking, docs/spatial_drives.md)
MAX_CONTROL_PERIOD_S = 0.01


@dataclass(frozen=True)
class SpatialMotors:
    """Per-joint motor constants (n,) arrays, motor side, SI."""

    torque_constant_Nm_per_A: np.ndarray
    resistance_ohm: np.ndarray
    voltage_limit_V: np.ndarray
    gear_efficiency: np.ndarray
    current_limit_A: np.ndarray  # tau_max / (N eta k_t): the torque limit at the motor
    integral_rate_per_s: np.ndarray  # Ki / K of the PID [1/s]; zeros: a PD law


def _per_joint(raw: dict, key: str, where: str, n: int, names, default=None, positive: bool = True) -> np.ndarray:
    v = raw.get(key, default)
    if F.is_number(v):  # one number for every joint: a bad one is named as given, not as n copies
        if not np.isfinite(v) or (v <= 0 if positive else v < 0):
            raise QmtInputError(f"{where}.{key} must be a {'positive' if positive else 'non-negative'} number "
                                f"(or a list of {n}, one per joint {list(names)}), got {float(v):g}")
        v = [v] * n
    if not isinstance(v, list) or len(v) != n:
        raise QmtInputError(f"{where}.{key} must be one number or a list of {n} numbers, one per joint {list(names)}; "
                            f"got {F.show(raw.get(key))}")
    return F.vector({key: v}, key, where, positive=positive, nonnegative=not positive, length=n)


def check_integral_rate(value, section: str, n: int, joint_names=()) -> np.ndarray:
    """`section`.integral_rate_per_s, the PID's Ki / K [1/s]: one number or one per joint, in
    [0, MAX_INTEGRAL_RATE_PER_S]; an (n,) array, or a one-line QmtInputError naming it."""
    key = "integral_rate_per_s"
    rate = _per_joint({key: value}, key, section, n, list(joint_names) or list(range(n)), positive=False)
    if np.any(rate > MAX_INTEGRAL_RATE_PER_S):
        raise QmtInputError(f"{section}.{key} must be at most {MAX_INTEGRAL_RATE_PER_S:g} 1/s (beyond it the joint "
                            f"loop's slow poles are damped less than 0.55 and ring); got {F.show(np.asarray(value).tolist())}")
    return rate


def check_control_period(period_s, time_step_s: float | None = None) -> float | None:
    """The DC drive law's control period [s] (None: the plant step): one line unless plant step <= period <=
    MAX_CONTROL_PERIOD_S (a law faster than the plant acts at the plant's steps; beyond the bound the hold's
    half-period delay costs the loop more than 8.6 degrees of phase at 30 rad/s: MAX_CONTROL_PERIOD_S)."""
    if period_s is None:
        return None
    lo = 0.0 if time_step_s is None else time_step_s * (1.0 - 1e-9)
    if not (np.isfinite(period_s) and lo < period_s <= MAX_CONTROL_PERIOD_S):
        floor = "positive" if time_step_s is None else f"at least the plant step {time_step_s * 1e3:g} ms"
        raise QmtInputError(f"control period {period_s * 1e3:g} ms: the DC drive's law is sampled at a period "
                            f"{floor} and at most {MAX_CONTROL_PERIOD_S * 1e3:g} ms")
    return float(period_s)


def parse_motor_section(raw, joint_names, torque_limit_Nm, gear_ratio, where: str) -> SpatialMotors | None:
    """The validated `actuators.motor` mapping (module docstring); None when absent. One-line
    QmtInputError naming the key and the fix for anything else."""
    if raw is None:
        return None
    if not isinstance(raw, dict):
        raise QmtInputError(f"{where} must be a mapping with {', '.join(MOTOR_KEYS)}; got {F.show(raw)}")
    F.check_keys(raw, set(MOTOR_KEYS + OPTIONAL_KEYS), where)
    missing = [k for k in MOTOR_KEYS if k not in raw]
    if missing:
        raise QmtInputError(f"{where} lacks {', '.join(missing)}; give each as one number or one per joint")
    n = len(joint_names)
    kt, r, v = (_per_joint(raw, k, where, n, joint_names) for k in MOTOR_KEYS)
    eta = _per_joint(raw, "gear_efficiency", where, n, joint_names, default=1.0)
    if np.any(eta > 1.0):
        raise QmtInputError(f"{where}.gear_efficiency must be in (0, 1]; got {eta.tolist()}")
    rate = check_integral_rate(raw.get("integral_rate_per_s", 0.0), where, n, joint_names)
    tau_max, N = np.asarray(torque_limit_Nm, float), np.asarray(gear_ratio, float)
    stall = N * eta * kt * v / r  # joint torque at stall with the full voltage [N*m]
    short = np.flatnonzero(stall < tau_max)
    if short.size:
        k = int(short[0])
        raise QmtInputError(f"{where}: joint {joint_names[k]}'s motor reaches {stall[k]:.4g} N m at stall through the "
                            f"gear (N eta k_t V/R), below its torque limit {tau_max[k]:g} N m; raise voltage_limit_V "
                            "or torque_constant_Nm_per_A, or lower resistance_ohm")
    return SpatialMotors(kt, r, v, eta, tau_max / (N * eta * kt), rate)
