"""Catalogue data the scenario validates against: motor, servo and coil datasheets, the servos'
control-table units and gains, the IK branch names. Plain data (numpy only, no Drake), so that the
scenario (config/) can check a file's names and numbers without importing any system above it;
systems/ re-export these names where they are used.

Sources are named per entry (maxon and Faulhaber catalogues, the ROBOTIS e-Manual, seed 000's
tables).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from qmt_drake.errors import QmtInputError

IK_BRANCHES = ("elbow_positive", "elbow_negative")
STEEL_DENSITY_KG_M3 = 7850.0  # the thesis's steel part (a cylinder sized from its mass)


# ------------------------------------------------------------------------------- DC motors
@dataclass(frozen=True)
class MotorDatasheet:
    """One motor's catalogue numbers (motor side, SI)."""

    name: str
    source: str
    nominal_voltage_V: float
    resistance_ohm: float
    inductance_H: float
    torque_constant_Nm_per_A: float
    rotor_inertia_kgm2: float
    nominal_torque_Nm: float  # max. continuous torque
    max_current_A: float  # drive current limit used here (amplifier), not the motor's stall current

    @property
    def stall_torque_Nm(self) -> float:
        return self.torque_constant_Nm_per_A * self.nominal_voltage_V / self.resistance_ohm

    @property
    def no_load_speed_rad_s(self) -> float:
        return self.nominal_voltage_V / self.torque_constant_Nm_per_A


MOTOR_CATALOG: dict[str, MotorDatasheet] = {
    # maxon RE 30, 60 W, graphite brushes, 24 V winding (order no. 310007).
    "maxon_RE30_60W_24V": MotorDatasheet(
        name="maxon RE 30 60 W 24 V", source="maxon catalogue 2012/13, RE 30 page, 310007",
        nominal_voltage_V=24.0, resistance_ohm=0.611, inductance_H=0.119e-3,
        torque_constant_Nm_per_A=25.9e-3, rotor_inertia_kgm2=33.3e-7, nominal_torque_Nm=85.6e-3,
        max_current_A=6.0),
    # maxon RE 25, 20 W, graphite brushes, 24 V winding (order no. 118752).
    "maxon_RE25_20W_24V": MotorDatasheet(
        name="maxon RE 25 20 W 24 V", source="maxon catalogue 2012/13, RE 25 page, 118752",
        nominal_voltage_V=24.0, resistance_ohm=2.32, inductance_H=0.24e-3,
        torque_constant_Nm_per_A=23.4e-3, rotor_inertia_kgm2=10.8e-7, nominal_torque_Nm=28.8e-3,
        max_current_A=4.0),
    # Faulhaber 1724 T 012 SR, 12 V coreless micromotor.
    "faulhaber_1724T012SR": MotorDatasheet(
        name="Faulhaber 1724 T 012 SR", source="Faulhaber DC-Micromotors catalogue, series 1724 SR",
        nominal_voltage_V=12.0, resistance_ohm=8.71, inductance_H=0.26e-3,
        torque_constant_Nm_per_A=14.7e-3, rotor_inertia_kgm2=1.0e-7, nominal_torque_Nm=4.5e-3,
        max_current_A=1.4),
}

HARMONIC_DRIVE_EFFICIENCY = 0.7


def motor_for_rated_torque(rated_torque_Nm: float) -> MotorDatasheet:
    """The smallest catalogue motor whose continuous torque covers a thesis rated torque [N*m]."""
    fitting = [m for m in MOTOR_CATALOG.values() if m.nominal_torque_Nm >= rated_torque_Nm]
    if not fitting:
        return max(MOTOR_CATALOG.values(), key=lambda m: m.nominal_torque_Nm)
    return min(fitting, key=lambda m: m.nominal_torque_Nm)




# ---------------------------------------------------------------- Dynamixel X-series servos
PULSES_PER_REV = 4096
PULSES_PER_RAD = PULSES_PER_REV / (2.0 * math.pi)
PWM_FULL_SCALE = 885.0  # PWM Limit(36) default and maximum: 100 % duty
CURRENT_UNIT_A = 2.69e-3  # Current Limit(38) unit
CONTROL_PERIOD_S = 1e-3  # ASSUMPTION (not stated by the maker); see the module docstring
RPM = 2.0 * math.pi / 60.0


@dataclass(frozen=True)
class ServoDatasheet:
    """One servo's datasheet numbers at its supply voltage (output-shaft side, SI except rpm)."""

    model: str
    source: str
    supply_voltage_V: float
    gear_ratio: float
    stall_torque_Nm: float
    stall_current_A: float
    no_load_speed_rpm: float
    current_limit_A: float

    @property
    def no_load_speed_rad_s(self) -> float:
        return self.no_load_speed_rpm * RPM

    @property
    def back_emf_V_s_per_rad(self) -> float:
        """Output-side back-EMF constant V / w0 [V*s/rad]."""
        return self.supply_voltage_V / (self.no_load_speed_rpm * RPM)

    @property
    def resistance_ohm(self) -> float:
        return self.supply_voltage_V / self.stall_current_A

    @property
    def efficiency(self) -> float:
        """Stall torque over the ideal Ke*I_s: gear efficiency and friction lumped."""
        return self.stall_torque_Nm / (self.back_emf_V_s_per_rad * self.stall_current_A)


XM540_W270 = ServoDatasheet("XM540-W270", "ROBOTIS e-Manual XM540-W270 specifications, 12.0 V",
                            12.0, 272.5, 10.6, 4.4, 30.0, 2047 * CURRENT_UNIT_A)
XM430_W350 = ServoDatasheet("XM430-W350", "ROBOTIS e-Manual XM430-W350 specifications, 12.0 V",
                            12.0, 353.5, 4.1, 2.3, 46.0, 1193 * CURRENT_UNIT_A)
# CRANE-X7: XM540-W270 on joints 1-2, XM430-W350 on joints 3-7 (effort limits 10 / 4 N m in the
# maker's description); the planar arm uses joints 2, 4, 6.
CRANE_X7_PLANAR_SERVOS = (XM540_W270, XM430_W350, XM430_W350)
SERVO_CATALOG = {s.model: s for s in (XM540_W270, XM430_W350)}  # scenario actuator.servos names


@dataclass(frozen=True)
class ServoGains:
    """Position PID gains in control-table units (Position P/I/D Gain, addresses 84/82/80) and the
    feedforward gains (Feedforward 1st Gain, address 90: velocity; Feedforward 2nd Gain, address 88:
    acceleration; ROBOTIS e-Manual, X-series control table: K_FF1 = FF1(TBL) / 4, K_FF2 =
    FF2(TBL) / 4, acting on the target velocity and acceleration trajectories). ff1 / ff2 None: 0,
    the servo's default."""

    p: tuple
    i: tuple
    d: tuple
    ff1: tuple | None = None
    ff2: tuple | None = None

    def __post_init__(self) -> None:
        for name in ("ff1", "ff2"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, tuple(0.0 for _ in self.p))
        for name in ("p", "i", "d", "ff1", "ff2"):
            v = np.asarray(getattr(self, name), float)
            if np.any(v < 0) or np.any(v > 16383) or not np.all(np.isfinite(v)):
                raise QmtInputError(f"servo {name.upper()} gain {v.tolist()} must be in the control table's "
                                    f"range 0..16383")

    @classmethod
    def uniform(cls, n: int, p=800, i=0, d=0) -> ServoGains:
        return cls(tuple(np.broadcast_to(p, (n,)).tolist()), tuple(np.broadcast_to(i, (n,)).tolist()),
                   tuple(np.broadcast_to(d, (n,)).tolist()))

    def firmware(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(K_PP, K_PI, K_PD) in PWM units per pulse (per pulse-sample, per pulse-difference)."""
        return (np.asarray(self.p, float) / 128.0, np.asarray(self.i, float) / 65536.0,
                np.asarray(self.d, float) / 16.0)

    def feedforward(self) -> tuple[np.ndarray, np.ndarray]:
        """(K_FF1, K_FF2): PWM units per pulse/sample of target velocity and per pulse/sample^2 of
        target acceleration (e-Manual: FF(TBL) / 4; the constants include the sampling time)."""
        return np.asarray(self.ff1, float) / 4.0, np.asarray(self.ff2, float) / 4.0

    def continuous_equivalent(self, sheets, period_s: float = CONTROL_PERIOD_S) -> dict:
        """The loop in SI at the joint, for checks: voltage per rad (kp_V_per_rad), per rad*s
        (ki_V_per_rad_s), per rad/s (kd_V_s_per_rad) and the stall torque per volt."""
        kpp, kpi, kpd = self.firmware()
        v_per_pwm = np.array([s.supply_voltage_V for s in sheets]) / PWM_FULL_SCALE
        return {"kp_V_per_rad": kpp * PULSES_PER_RAD * v_per_pwm,
                "ki_V_per_rad_s": kpi * PULSES_PER_RAD * v_per_pwm / period_s,
                "kd_V_s_per_rad": kpd * PULSES_PER_RAD * v_per_pwm * period_s,
                "stall_Nm_per_V": np.array([s.stall_torque_Nm / s.supply_voltage_V for s in sheets])}


# Seed 002 section 7: P only (the servo default 800) before, retuned PID after.
SEED_GAINS_BEFORE = ServoGains((800, 800, 800), (0, 0, 0), (0, 0, 0))
SEED_GAINS_AFTER = ServoGains((1000, 1040, 1000), (150, 150, 150), (200, 250, 200))


# ------------------------------------------------------------------- electromagnet coils
@dataclass(frozen=True)
class CoilSpec:
    """A thesis hand's coil (SI)."""

    name: str
    turns: int
    resistance_ohm: float
    core_diameter_m: float
    outer_diameter_m: float
    length_m: float

    @property
    def core_area_m2(self) -> float:
        return math.pi * self.core_diameter_m**2 / 4


THESIS_COILS = {
    "table_2_2": CoilSpec("seed 000 Table 2.2 (ch.2 hand)", 420, 2.7, 7.8e-3, 16.5e-3, 20.0e-3),
    "table_3_2": CoilSpec("seed 000 Table 3.2 (ch.3-4 hand)", 156, 1.7, 7.8e-3, 11.35e-3, 20.0e-3),
}
