"""Builders: a scenario (plain data, config/) turned into the numpy and Drake objects the planners
and the co-simulation use. One builder for each thing: the arm model, the limit set, the tray's
bottle. qmt_drake/transfer_scenario.TransferScenario calls them (plain imports, nothing registered):
`scenario.arm`, `scenario.limit_set` and `scenario.bottle` build once per scenario object. They take
the built scenario (a builder may use what another built: the limit set takes `scenario.arm`). The
hand's and the actuator's plug-ins are looked up in config/registry (hand_entry, actuator_entry), not
through hands.py, which imports the plan files and with them the scenario loader.
"""

from __future__ import annotations

from pathlib import Path

from qmt_drake.config.registry import actuator_entry, hand_entry
from qmt_drake.config.scenario import Scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.limits import JointRangeTerm, LimitSet, MotorTorqueTerm
from qmt_drake.limits.joint_speed import JointSpeedTerm
from qmt_drake.model.arm import ArmModel
from qmt_drake.systems.tray_object import BottleSpec


def build_bottle(scenario: Scenario) -> BottleSpec | None:
    """The BottleSpec (systems/tray_object.py) of a hand that carries a bottle (its plug-in's
    `bottle`: the tray's); None for other hands."""
    make = hand_entry(scenario).bottle
    return None if make is None else make(scenario)


def build_arm(scenario: Scenario) -> ArmModel:
    """The ArmModel of the scenario's URDF with the carried part's inertia welded to the hand (tray:
    the bottle seated at the tray centre, its base at the tray frame's origin). A URDF that is a
    directory, unreadable, not XML or not a serial chain: one-line QmtInputError naming the scenario."""
    carried = hand_entry(scenario).carried_inertia(scenario)
    where, urdf = str(scenario.source_path), Path(scenario.urdf_path)
    if urdf.is_dir():
        raise QmtInputError(f"{where}: arm.urdf {urdf} is a directory; give the URDF file")
    try:
        act = actuator_entry(scenario)
        return ArmModel.from_urdf(urdf, hand_frame=scenario.hand_frame, carried_inertia=carried,
                                  require_gear_ratio=act is None or act.gear_ratio_required,
                                  gravity_m_s2=scenario.world.gravity_m_s2)
    except QmtInputError as exc:
        raise QmtInputError(f"{where}: {exc}") from None
    except OSError as exc:
        raise QmtInputError(f"{where}: arm.urdf {urdf} cannot be read ({exc.strerror})") from None


def build_limit_set(scenario: Scenario) -> LimitSet:
    """The scenario's LimitSet: the hand's terms (its plug-in in hands.py: the thesis's payload moment,
    or the tray's no slide / no tip / no lift-off), motor torques, joint speeds when
    limits.joint_speed_fraction is given, joint ranges."""
    arm = scenario.arm
    terms = hand_entry(scenario).limit_terms(scenario, arm)  # what the hand adds (hands.py)
    terms.append(MotorTorqueTerm(arm, scenario.limits.motor_torque_limit_Nm))
    if scenario.limits.joint_speed_fraction is not None:
        act = actuator_entry(scenario)  # its joints' speeds (the servos' no-load speeds), else the URDF's
        v = act.joint_speeds_rad_s(scenario.actuator) if act is not None and act.joint_speeds_rad_s else None
        terms.append(JointSpeedTerm(arm, scenario.limits.joint_speed_fraction, v))
    return LimitSet(arm, terms + [JointRangeTerm(arm)])

