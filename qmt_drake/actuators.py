"""Actuator plug-ins: each actuator kind registers once (config/registry.ACTUATORS) what it adds to
the scenario and to what is built from it.

    dc_motor_gear  catalogue DC motors behind the URDF's gears (seed 000): the magnet co-simulation's
                   motors with PID (sim/actuation.py)
    ideal          joint torque sources with joint-side PD gains: the magnet co-simulation without motors
    dynamixel      Dynamixel position servos with firmware gains (seed 002): the tray co-simulation

What an entry says: how its YAML section is parsed, which of its lists goes one per joint, whether
the scenario's `control` gains apply, whether the planning arm needs the URDF's gear ratios (motor
torque limits are motor side), the joint speeds that `limits.joint_speed_fraction` scales (the limit
set's joint-speed term), which co-simulation drives it, and, for the magnet co-simulation, how
(`magnet_actuation`: sim/magnet_actuation.MagnetActuation, which build_transfer_diagram and the
runner ask instead of branching on the kind). Register a new kind with `register_actuator`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from qmt_drake.config.registry import ACTUATORS, actuator_entry
from qmt_drake.config.validate import parse_dc_motor_gear, parse_dynamixel, parse_ideal_torque
from qmt_drake.errors import QmtInputError
from qmt_drake.sim.magnet_actuation import DC_MOTOR_ACTUATION, IDEAL_TORQUE_ACTUATION, MagnetActuation


@dataclass(frozen=True)
class ActuatorPlugin:
    """parse(raw_section, limits, where) -> the typed section; per_joint: the section's attribute
    with one entry per joint (checked against the arm), None if none; control_refused: None when
    the scenario's control.kp/ki/kd drive it, else the fix the loader prints for a control section;
    gear_ratio_required: the planning arm refuses a URDF without gear ratios (motor-side torque
    limits); joint_speeds_rad_s(section) -> each joint's speed [rad/s] that limits.joint_speed_fraction
    scales (None: the URDF's velocity limits); drives: the co-simulation that runs it (prose);
    magnet_actuation: how the magnet co-simulation drives it (sim/magnet_actuation.MagnetActuation:
    its checks, gains and the systems it adds; None: that co-simulation refuses it in one line)."""

    kind: str
    parse: Callable[..., Any]
    per_joint: str | None = None
    control_refused: str | None = None
    gear_ratio_required: bool = True
    joint_speeds_rad_s: Callable[[Any], list[float]] | None = None
    drives: str = ""
    magnet_actuation: MagnetActuation | None = None


def register_actuator(plugin: ActuatorPlugin, *, replace: bool = False) -> None:
    """Register an actuator kind (an ActuatorPlugin); an existing kind only with replace=True. One line else."""
    if not isinstance(plugin, ActuatorPlugin):
        raise QmtInputError(f"register_actuator needs an ActuatorPlugin, got {type(plugin).__name__}; build one "
                            "with qmt_drake.actuators.ActuatorPlugin(kind=..., parse=...)")
    ACTUATORS.register(plugin, replace=replace)


def actuator_plugin(scenario: Any) -> ActuatorPlugin | None:
    """The registered plug-in of the scenario's actuator (None without an actuator section)."""
    entry: ActuatorPlugin | None = actuator_entry(scenario)
    return entry


# the words naming a planar scenario's YAML actuator kinds as the spatial drives are named (--actuator, actuator=)
_ACTUATOR_FLAG = {"dc_motor_gear": "dc_motor", "ideal": "ideal"}


def check_own_actuator(sc, value: str | None, option: str = "--actuator") -> str | None:
    """A planar scenario's drive is its YAML actuator section (the arm's hardware): `option` (the CLI's
    --actuator, the API's actuator=) may name it (dc_motor for DC motors with gears, ideal for a torque
    source) and nothing else; one-line QmtInputError naming the scenario's own actuator else. Returns
    its actuator.kind when `value` named it (None when no value was given)."""
    if value is None:
        return None
    if sc.actuator is None:
        raise QmtInputError(f"{option} {value}: scenario {sc.name} has no actuator section to name; drop {option}")
    kind = sc.actuator.kind
    if _ACTUATOR_FLAG.get(kind) == value:
        return kind
    if kind == "dynamixel":
        raise QmtInputError(f"{option} {value}: {sc.name}'s actuator is its YAML's Dynamixel position servos "
                            f"({', '.join(sc.actuator.servos)}), whose firmware closes the position loop: there is "
                            f"no motor voltage or joint torque to drive from outside; drop {option}")
    raise QmtInputError(f"{option} {value}: {sc.name}'s actuator is its YAML's actuator.kind {kind} "
                        f"({option} {_ACTUATOR_FLAG.get(kind, kind)}); the arm's drive is part of the scenario: "
                        f"drop {option} or set actuator.kind in a copy of the YAML file")


register_actuator(ActuatorPlugin(
    kind="dc_motor_gear", parse=parse_dc_motor_gear, per_joint="motors",
    magnet_actuation=DC_MOTOR_ACTUATION,
    drives="the magnet co-simulation: PID on motor voltages, the motors behind the gears (sim/actuation.py)"))
register_actuator(ActuatorPlugin(
    kind="ideal", parse=parse_ideal_torque, gear_ratio_required=False,
    magnet_actuation=IDEAL_TORQUE_ACTUATION,
    drives="the magnet co-simulation: a joint-side PD torque source (sim/actuation.add_ideal_torque_actuation)"))
register_actuator(ActuatorPlugin(
    kind="dynamixel", parse=parse_dynamixel, per_joint="servos",
    control_refused=("a Dynamixel scenario sets its firmware gains in actuator.p / i / d (control-table units): "
                     "move them there and drop the control section"),
    joint_speeds_rad_s=lambda act: [s.no_load_speed_rad_s for s in act.datasheets()],
    drives="the tray co-simulation: the servos' firmware loop (systems/dynamixel_servo.py)"))
