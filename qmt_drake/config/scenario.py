"""Scenarios: a typed description of one transfer task, loaded from YAML and validated.

A scenario names the arm (`arm`: a URDF), the hand (`hand`: an electromagnet with its coil, how its
current is set, and the contact it makes with the part; or a tray on which the part rests unfixed,
seed 002), the motors (`actuator`: DC motors with gears, ideal torque sources, or Dynamixel position
servos), the payload (mass, r_G, the rigid body the co-simulation uses),
the task points and IK branch, the planning limits, the trajectory family with its genes and
bounds, the GA settings, the joint control gains and what the thesis reported. Built-in scenarios
live in `models/scenarios/` and are loaded by name (`thesis-ch2`, `thesis-ch3`, `thesis-ch4`,
`crane-tray`, ...); any other YAML file by path.

Tray scenarios (`hand: {kind: tray}`): the payload is the bottle standing on the tray (mass, its
centre-of-mass height as `com_offset_m`, `body: {kind: bottle}` with its size); the hand frame is
the tray frame (z the surface normal); the limits are the tray terms (no slide, no tip, no lift-off;
tray/limit_terms.py) plus motor torques, joint speeds and ranges. Checked at load, one line each: every
task point inside the joint ranges (tray level), the bottle standing at rest on the tray tilted by
`hand.rest_tilt_rad`, friction positive.

Each section is a small frozen dataclass (config/sections.py) with its own validation
(config/validate.py), in the spirit of Drake's hardware_sim scenario (`yaml_load_typed`), written
out so that every bad key gets its own one-line QmtInputError naming the key and the fix. This
module is the data half of the loader: it finds the file, reads and merges the YAML, resolves the
arm's URDF, calls the section validators and checks the sections against each other
(`load_transfer_data`: plain data, no Drake object, nothing registered is called). Numbers are
checked as numbers: a YAML `true` is not 1, a string is not 0.5. The checks that need the loaded
arm (per-joint list lengths, tray points reachable, bottle at rest) and the `uncertainty`
distributions are the other half, qmt_drake/transfer_scenario.load_scenario, above the builders.

`Scenario.fingerprint()` is a sha256 of the validated data and the URDF's bytes: what a GA
checkpoint or a plan file stores to recognise its scenario.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path
from typing import Any

from qmt_drake.config import fields as fields_mod
from qmt_drake.config.registry import (
    ACTUATORS,
    DEFAULT_HAND_KIND,
    DEFAULT_OBJECTIVE_KIND,
    ENERGY_TIME,
    HANDS,
    OBJECTIVES,
    TRANSFER,
    for_scenario_kind,
)
from qmt_drake.config.resolve import (  # noqa: F401 (re-exported: the one resolver)
    MODELS_DIR,
    SCENARIO_DIR,
    SPATIAL_METHODS,
    builtin_scenarios,
    resolve_scenario,
    scenario_kind,
)
from qmt_drake.config.sections import (  # noqa: F401 (re-exported: the scenario's types)
    STANDARD_GRAVITY_M_S2,
    DcMotorGear,
    DynamixelServos,
    Family,
    GaSettings,
    IdealTorque,
    Limits,
    MagnetHand,
    Payload,
    PayloadBody,
    Sampling,
    Scenario,
    Task,
    TrayHand,
    UrdfArm,
    World,
)
from qmt_drake.config.simulation import parse_simulation
from qmt_drake.config.validate import (
    WORLD_KEYS,
    check_scenario_kind,
    parse_actuator,
    parse_family,
    parse_ga,
    parse_hand,
    parse_payload,
    parse_task,
    parse_uncertainty,
    parse_world,
)
from qmt_drake.errors import QmtInputError

# ---------------------------------------------------------------------------------------- loading
_TOP_KEYS = {"name", "description", "world", "uncertainty", "arm", "hand", "actuator", "payload", "task", "limits",
             "family", "objective", "ga", "sampling", "control", "reported", "notes", "source", "simulation"}
_SECTION_KEYS = {
    "world": WORLD_KEYS,
    "arm": {"kind", "urdf", "hand_frame"},
    "payload": {"name", "mass_kg", "com_offset_m", "length_m", "body"},
    "task": {"points_m", "tool_angle_rad", "ik_branch"},
    "limits": {"moment_limit_Nm", "motor_torque_limit_Nm", "joint_speed_fraction"},
    "family": {"kind", "genes"},
    "objective": {"kind"},
    "ga": {f.name for f in fields(GaSettings)},
    "sampling": {f.name for f in fields(Sampling)},
    "control": {"kp", "ki", "kd"},
    "reported": None,  # free-form
}


# why a transfer scenario's plant cannot be continuous (simulation.plant.time_step 0)
DISCRETE_ONLY = ("its co-simulation samples the drive, the monitor and the logs at the plant step and steps the "
                 "hand's point contact (and the motor loop's damping) in the discrete plant's solver")
ENERGY_TIME_KIND = ENERGY_TIME  # seed 001's scenarios (qmt_drake/energy/scenario.py) share the folder


def read_scenario_yaml(path: Path, example: str = "thesis-ch4") -> dict:
    """The YAML mapping of a scenario file (duplicated keys refused); QmtInputError (one line) if it
    is not one."""
    return fields_mod.read_yaml_mapping(path, "scenario", SCENARIO_DIR / (example + ".yaml"))


def load_transfer_data(name_or_path: str | Path, overrides: dict | None = None) -> Scenario:
    """The plain data of a built-in transfer scenario by name or a YAML file by path; `overrides` is
    merged into the raw YAML mapping first (nested dicts merge key by key). The checks against the
    built arm are transfer_scenario.load_scenario's (module docstring)."""
    path = resolve_scenario(name_or_path, TRANSFER)
    raw = read_scenario_yaml(path)
    check_scenario_kind(raw, str(path))
    if overrides:
        raw = fields_mod.merge_overrides(raw, overrides)
    return scenario_from_dict(raw, path)


def scenario_from_dict(raw: dict, path: Path) -> Scenario:
    where = str(path)
    _check_keys(raw, _TOP_KEYS, where)
    for sec, keys in _SECTION_KEYS.items():
        if sec in raw and raw[sec] is not None:
            if not isinstance(raw[sec], dict):
                raise QmtInputError(f"{where}: '{sec}' must be a mapping, got {_show(raw[sec])}")
            if keys is not None:
                _check_keys(raw[sec], keys, f"{where}: {sec}")
    for sec in ("arm", "payload", "task", "limits", "family"):
        if sec not in raw or raw[sec] is None:
            raise QmtInputError(f"{where}: missing section '{sec}'")

    arm_spec = _arm(raw["arm"], path, where)
    payload = parse_payload(raw["payload"], f"{where}: payload")
    task = parse_task(raw["task"], f"{where}: task")

    world = parse_world(raw.get("world") or {}, f"{where}: world")
    lim = raw["limits"]
    h = raw.get("hand")
    hand_plugin = HANDS.get(h.get("kind", DEFAULT_HAND_KIND) if isinstance(h, dict) else DEFAULT_HAND_KIND,
                            f"{where}: hand")
    if hand_plugin.check_payload is not None:
        hand_plugin.check_payload(payload, where)  # before the section's keys: e.g. a tray carries a bottle
    hand = parse_hand(h, f"{where}: hand")
    moment = hand_plugin.moment_limit(hand, payload, world, lim, where)  # its payload limit [N*m]
    speed = lim.get("joint_speed_fraction")
    if speed is not None:
        speed = _num(lim, "joint_speed_fraction", f"{where}: limits", positive=True)
        if speed > 1:
            raise QmtInputError(f"{where}: limits.joint_speed_fraction {speed} must lie in (0, 1] (a fraction of "
                                "the URDF's joint velocity limits)")
    limits = Limits(moment_limit_Nm=moment,
                    motor_torque_limit_Nm=_vector(lim, "motor_torque_limit_Nm", f"{where}: limits",
                                                  positive=True, what="motor torque limits [N*m]"),
                    joint_speed_fraction=speed)
    family = parse_family(raw["family"], f"{where}: family")
    objective = (raw.get("objective") or {}).get("kind", DEFAULT_OBJECTIVE_KIND)
    OBJECTIVES.get(objective, f"{where}: objective", accept=for_scenario_kind(TRANSFER))  # one line if unknown
    ga = parse_ga(raw.get("ga") or {}, f"{where}: ga")
    sm = raw.get("sampling") or {}
    sampling = Sampling(**{f.name: _num(sm, f.name, f"{where}: sampling", positive=True,
                                        default=f.default) for f in fields(Sampling)})
    control = {}
    act_kind = (raw.get("actuator") or {}).get("kind") if isinstance(raw.get("actuator"), dict) else None
    refused = ACTUATORS[act_kind].control_refused if isinstance(act_kind, str) and act_kind in ACTUATORS else None
    if raw.get("control") and refused:
        raise QmtInputError(f"{where}: control.{'/'.join(raw['control'])} are the PID gains of DC motors or ideal "
                            f"actuators; {refused}")
    for k, v in (raw.get("control") or {}).items():
        control[k] = _vector({k: v}, k, f"{where}: control", nonnegative=True,
                             what="gains, one per joint").tolist()
    reported = dict(raw.get("reported") or {})
    if "genes" in reported and reported["genes"] is not None:
        rg = reported["genes"]
        if not isinstance(rg, dict) or not all(_is_number(v) for v in rg.values()):
            raise QmtInputError(f"{where}: reported.genes must map gene names to numbers, got {_show(rg)}")
    for k in ("motion_time_s", "settled_after_generations"):
        if reported.get(k) is not None:
            _num(reported, k, f"{where}: reported", positive=True)
    notes = fields_mod.sequence(raw, "notes", where, default=[], item=str, what="strings") if raw.get("notes") else []
    name = fields_mod.string(raw, "name", where, default=path.stem)
    description = fields_mod.string(raw, "description", where, default="", allow_empty=True, what="a string")

    sc = Scenario(
        name=name, description=description, source_path=path, urdf_path=arm_spec.urdf_path,
        hand_frame=arm_spec.hand_frame, payload=payload, task=task, limits=limits, family=family,
        objective=objective, ga=ga, sampling=sampling, control=control, reported=reported,
        notes=tuple(notes), arm_spec=arm_spec,
        hand=hand,
        actuator=parse_actuator(raw.get("actuator"), limits, f"{where}: actuator"), world=world,
        uncertainty=parse_uncertainty(raw.get("uncertainty"), f"{where}: uncertainty"),
        simulation=parse_simulation(raw.get("simulation"), where, continuous=DISCRETE_ONLY))
    return sc


def _arm(a: dict, path: Path, where: str) -> UrdfArm:
    kind = a.get("kind", "urdf")
    if kind != "urdf":
        raise QmtInputError(f"{where}: arm.kind {_show(kind)} is not available; use 'urdf' "
                            "(generated arms are not implemented yet)")
    urdf = Path(fields_mod.string(a, "urdf", f"{where}: arm", what="a file path"))
    if not urdf.is_absolute():
        beside = (path.parent / urdf).resolve()
        # A built-in scenario copied elsewhere still finds the packaged model by its file name.
        packaged = MODELS_DIR / urdf.name
        urdf = beside if beside.is_file() or not packaged.is_file() else packaged
    if urdf.is_dir():
        raise QmtInputError(f"{where}: arm.urdf {urdf} is a directory; give the URDF file")
    if not urdf.is_file():
        raise QmtInputError(f"{where}: arm.urdf {urdf} does not exist; give a path relative to "
                            "the scenario file or an absolute one")
    frame = fields_mod.string(a, "hand_frame", f"{where}: arm", default="hand", what="a frame name")
    return UrdfArm(urdf_path=urdf, hand_frame=frame)


def magnet_moment_limit(hand: MagnetHand | None, payload: Payload, world: World, lim: dict, where: str) -> float:
    """The magnet hand's payload limit: limits.moment_limit_Nm [N*m] as given."""
    return _num(lim, "moment_limit_Nm", f"{where}: limits", positive=True)


def tray_moment_limit(hand: TrayHand, payload: Payload, world: World, lim: dict, where: str) -> float:
    """The tray's: not a planning limit but the bottle's tipping moment m g r_c (with the planning
    margin) [N*m], so that moment_limit / moment_per_accel = g r_c / h_G is the level tray's tipping
    acceleration, the starting acceleration scale of the Ruckig baseline. limits.moment_limit_Nm
    does not apply: one line."""
    if lim.get("moment_limit_Nm") is not None:
        raise QmtInputError(f"{where}: limits.moment_limit_Nm does not apply to a tray hand (its limits "
                            "are no slide, no tip, no lift-off from hand.friction and hand.contact_radius_m); "
                            "remove it")
    return payload.mass_kg * world.g_m_s2 * hand.contact_radius_m * hand.plan_margin


def check_tray_payload(payload: Payload, where: str) -> None:
    """A tray carries a bottle: one line otherwise."""
    if payload.body is None or payload.body.shell_mass_kg <= 0:
        raise QmtInputError(f"{where}: hand.kind 'tray' is not available for this payload: a tray carries a "
                            "bottle; give payload.body kind 'bottle' (radius_m, height_m, shell_mass_kg)")


def check_tray_scenario(sc: Any, where: str) -> None:
    """The task's tray points inside the joint ranges (tray level: task.tool_angle_rad) and the
    bottle standing at rest: one line each, before any planning. `sc` is the built scenario
    (transfer_scenario.TransferScenario: its arm and bottle); the tray plug-in's check_loaded."""
    b, hand = sc.payload.body, sc.hand
    assert b is not None and isinstance(hand, TrayHand)  # check_tray_payload and the parser checked both
    if hand.contact_radius_m > b.radius_m:
        raise QmtInputError(f"{where}: hand.contact_radius_m {hand.contact_radius_m} m is wider than the bottle "
                            f"(payload.body.radius_m {b.radius_m} m)")
    bottle = sc.bottle
    try:
        bottle.check_rests(hand.rest_tilt_rad)
    except QmtInputError as exc:
        raise QmtInputError(f"{where}: payload: {exc} (the tray at rest: hand.rest_tilt_rad "
                            f"{hand.rest_tilt_rad:.4g} rad)") from None
    for i, p in enumerate(sc.task.points_m):
        try:
            sc.arm.inverse_kinematics(p, sc.task.tool_angle_rad, sc.task.ik_branch, what=f"tray point {i + 1}")
        except QmtInputError as exc:
            raise QmtInputError(f"{where}: task.points_m[{i}] ({p[0]:g}, {p[1]:g}) m: {exc}") from None


# ------------------------------------------------------------------------------------ value checks
# The shared validation layer (config/fields.py), under this module's historical names.
_show = fields_mod.show
_is_number = fields_mod.is_number
_check_keys = fields_mod.check_keys
_need = fields_mod.need
_num = fields_mod.num
_vector = fields_mod.vector
