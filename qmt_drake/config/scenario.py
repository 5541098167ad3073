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
limits/tray.py) plus motor torques, joint speeds and ranges. Checked at load, one line each: every
task point inside the joint ranges (tray level), the bottle standing at rest on the tray tilted by
`hand.rest_tilt_rad`, friction positive.

Each section is a small frozen dataclass with its own validation, in the spirit of Drake's
hardware_sim scenario (`yaml_load_typed`), written out here so that every bad key gets its own
one-line QmtInputError naming the key and the fix. Numbers are checked as numbers: a YAML `true`
is not 1, a string is not 0.5. After the file is read, the arm is loaded once (`Scenario.arm`) and
the lists that go per joint (motor limits, gains, motors) are checked against its joint count.

Scenarios pickle (sweeps ship them to worker processes); the cached Drake arm is left out of the
pickled state and rebuilt on first use. `Scenario.fingerprint()` is a sha256 of the validated data
and the URDF's bytes: what a GA checkpoint or a plan file stores to recognise its scenario.
"""

from __future__ import annotations

import hashlib
import json
import math
import numbers
from dataclasses import dataclass, field, fields, is_dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from qmt_drake.config import fields as fields_mod
from qmt_drake.errors import QmtInputError

MODELS_DIR = Path(__file__).resolve().parents[2] / "models"
SCENARIO_DIR = MODELS_DIR / "scenarios"
FAMILY_KINDS = ("line_cubic_velocity", "trapezoid_ptp", "via_cubic")
STEEL_DENSITY_KG_M3 = 7850.0


# ------------------------------------------------------------------------------------ sections
@dataclass(frozen=True)
class UrdfArm:
    """arm.kind 'urdf' (the default): a serial arm read from a URDF file."""

    urdf_path: Path
    hand_frame: str = "hand"
    kind: str = "urdf"


@dataclass(frozen=True)
class PayloadBody:
    """The rigid body the co-simulation carries (sets rotational inertia and the visual; mass and
    r_G always come from the payload). A cylinder about the face normal."""

    name: str
    length_m: float  # along the face normal
    radius_m: float
    face_radius_m: float  # radius of the part's attraction face (>= the core radius)
    shell_mass_kg: float = 0.0  # kind bottle: the empty bottle (thin-walled); the rest is water


@dataclass(frozen=True)
class Payload:
    """The carried part. `com_offset_m` is r_G, attraction face to centre of mass."""

    name: str
    mass_kg: float
    com_offset_m: float
    length_m: float | None = None  # kept for old callers: body.length_m
    body: PayloadBody | None = None


@dataclass(frozen=True)
class MagnetHand:
    """hand.kind 'magnet': an iron-cored coil pulling an iron part onto its face (electromagnet.py).

    The coil current is either given (`coil_current_A`) or calibrated (`slip_boundary_Nm`: the
    thesis's last-success and first-failure peak moments; the current whose quasi-static hold
    limit is their geometric mean, sim/magnet_hand.py). Contact data: friction coefficient, the
    ring of contact points (the core end's radius), point stiffness and Hunt-Crossley dissipation."""

    coil: Any  # systems.electromagnet.CoilSpec
    coil_name: str  # THESIS_COILS key, or "explicit"
    slip_boundary_Nm: tuple[float, float] | None = None
    coil_current_A: float | None = None
    effective_gap_m: float = 0.5e-3  # g0: an assumption, shared by both thesis hands
    friction: float = 0.3
    contact_radius_m: float = 3.9e-3
    n_contact_points: int = 8
    sphere_radius_m: float = 0.5e-3
    point_stiffness_N_per_m: float = 1.0e6
    hunt_crossley_dissipation_s_per_m: float = 5.0
    kind: str = "magnet"


@dataclass(frozen=True)
class DcMotorGear:
    """actuator.kind 'dc_motor_gear': one catalogue DC motor per joint (systems/dc_motor.py
    MOTOR_CATALOG keys) behind the URDF's gear ratio; `efficiency` is the gearbox's."""

    motors: tuple[str, ...]
    efficiency: float = 0.7
    kind: str = "dc_motor_gear"


@dataclass(frozen=True)
class IdealTorque:
    """actuator.kind 'ideal': the joint torque is whatever the controller asks (no motor model). The
    co-simulation then reads control.kp [N*m/rad] and control.kd [N*m*s/rad] as JOINT-side PD
    torque gains (not the thesis's motor-side volt gains; sim/actuation.add_ideal_torque_actuation)."""

    kind: str = "ideal"


@dataclass(frozen=True)
class TrayHand:
    """hand.kind 'tray' (seed 002): the payload rests unfixed on a tray held by the hand frame
    (z up when level). friction: bottle-tray Coulomb coefficient; contact_radius_m: radius of the
    ring the bottle stands on (its feet); plan_margin (0, 1]: friction and ring radius are scaled
    by it for planning (the servos lag the plan); rest_tilt_rad: the tray's tilt at rest that the
    bottle must survive (default: the seed's printed start joints sum to -0.0168 rad);
    tray_mass_kg: tray plus attachment (seed: 208 g; the URDF's tray link carries it)."""

    friction: float = 0.3
    contact_radius_m: float = 0.029
    plan_margin: float = 0.8
    rest_tilt_rad: float = 0.0168
    tray_mass_kg: float = 0.208
    n_contact_points: int = 16
    kind: str = "tray"


@dataclass(frozen=True)
class DynamixelServos:
    """actuator.kind 'dynamixel': one Dynamixel position servo per joint (systems/dynamixel_servo.py
    datasheets), firmware PID gains in control-table units, sampled every control_period_s."""

    servos: tuple[str, ...]
    p: tuple[float, ...]
    i: tuple[float, ...]
    d: tuple[float, ...]
    control_period_s: float = 1e-3
    kind: str = "dynamixel"

    def gains(self):
        from qmt_drake.systems.dynamixel_servo import ServoGains
        return ServoGains(tuple(self.p), tuple(self.i), tuple(self.d))

    def datasheets(self):
        from qmt_drake.systems.dynamixel_servo import SERVO_CATALOG
        return tuple(SERVO_CATALOG[s] for s in self.servos)


@dataclass(frozen=True)
class Limits:
    """Planning limits. Moment |tau_M| = m_o * r_G * |a_tip| (eq. 2-24, 3-10, 4-33); motor torque
    is motor side (joint torque / N, eq. 2-34)."""

    moment_limit_Nm: float
    motor_torque_limit_Nm: np.ndarray
    joint_speed_fraction: float | None = None  # tray scenarios: |qd| <= fraction * URDF velocity limit


@dataclass(frozen=True)
class Task:
    points_m: np.ndarray  # (k, 2): start, vias..., goal
    tool_angle_rad: float | None
    ik_branch: str


@dataclass(frozen=True)
class Family:
    kind: str
    gene_names: tuple[str, ...]
    gene_bounds: np.ndarray  # (G, 2)


@dataclass(frozen=True)
class GaSettings:
    population: int = 50
    bits_per_gene: int = 12
    crossover_rate: float = 0.5
    mutation_rate: float = 0.05  # per bit
    max_generations: int = 10000
    fitness_c_per_s: float = 0.1  # fitness = exp(-c * T0)
    elite_count: int = 1  # 0 reproduces the thesis's plain GA
    stall_generations: int = 0  # stop when the best has not improved this long (0: never)
    # Parent selection. The thesis names "selection" without saying how; "roulette" is
    # fitness-proportional, "tournament" picks the fitter of two random individuals.
    selection: str = "roulette"
    # How 12 bits map to a level: "binary" (plain) or "gray" (reflected Gray code, where
    # neighbouring levels differ in one bit, so a one-bit mutation can always step to them).
    encoding: str = "binary"
    # Seed 003's operator: if > 0, that many individuals get one random bit flipped per
    # generation (instead of flipping each bit with mutation_rate).
    mutants_per_generation: int = 0
    # Not in the thesis: play each chromosome at the time scale that puts it exactly on its limits
    # (the family optimum's tight motion), so the GA searches the shape of the motion and never its
    # feasibility boundary. Off reproduces the thesis's GA.
    tight_timing: bool = False


@dataclass(frozen=True)
class Sampling:
    plan_rate_hz: float = 1000.0  # limit checks inside planners
    check_rate_hz: float = 10000.0  # the independent re-check of every plan written out


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    source_path: Path
    urdf_path: Path
    hand_frame: str
    payload: Payload
    task: Task
    limits: Limits
    family: Family
    ga: GaSettings
    sampling: Sampling
    control: dict = field(default_factory=dict)  # kp, ki, kd lists (one per joint), validated
    reported: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    arm_spec: UrdfArm | None = None
    hand: MagnetHand | TrayHand | None = None
    actuator: DcMotorGear | IdealTorque | DynamixelServos | None = None

    @property
    def is_tray(self) -> bool:
        return isinstance(self.hand, TrayHand)

    @property
    def bottle(self):
        """Tray scenarios: the BottleSpec (systems/tray_object.py) of the payload and the hand."""
        if not self.is_tray:
            return None
        from qmt_drake.systems.tray_object import BottleSpec
        b = self.payload.body
        return BottleSpec(self.payload.name, float(self.payload.mass_kg), b.radius_m, b.length_m,
                          float(self.payload.com_offset_m), b.shell_mass_kg, self.hand.contact_radius_m,
                          friction=self.hand.friction, n_contact_points=self.hand.n_contact_points)

    @cached_property
    def arm(self):
        """The ArmModel built from the URDF with the carried part welded to the hand (loaded once
        per scenario object; not pickled)."""
        if self.is_tray:  # the bottle seated at the tray centre, its base at the tray frame's origin
            carried = self.bottle.spatial_inertia()
        else:
            from qmt_drake.systems.payload import PayloadSpec
            carried = PayloadSpec.for_scenario(self).spatial_inertia_about_origin()
        return _load_arm(self.urdf_path, self.hand_frame, str(self.source_path), carried_inertia=carried,
                         require_gear_ratio=not isinstance(self.actuator, IdealTorque))

    @cached_property
    def limit_set(self):
        """The scenario's LimitSet (payload moment, motor torques, joint ranges; limits/)."""
        from qmt_drake.limits import LimitSet
        return LimitSet.for_scenario(self)

    @property
    def gear_ratio(self) -> np.ndarray:
        return self.arm.gear_ratio

    @property
    def moment_per_accel_kgm(self) -> float:
        """m_o * r_G: payload moment per unit tip acceleration (tray: the bottle's tipping moment
        about its base per unit horizontal tray acceleration, m h_G)."""
        return self.payload.mass_kg * self.payload.com_offset_m

    def __getstate__(self):
        state = dict(self.__dict__)
        for cached in ("arm", "limit_set"):  # hold Drake objects, which do not pickle: rebuilt on demand
            state.pop(cached, None)
        return state

    def fingerprint(self) -> str:
        """sha256 (hex) of a canonical JSON of the validated data plus the URDF file's bytes.

        Left out: where the files are (source_path, urdf_path: the URDF counts by content) and
        the prose (description, notes, reported). Any edit that can change a plan or a
        simulation changes the fingerprint."""
        data = {f.name: _canonical(getattr(self, f.name)) for f in fields(self)
                if f.name not in ("source_path", "urdf_path", "description", "notes", "reported")}
        if isinstance(data.get("arm_spec"), dict):
            data["arm_spec"].pop("urdf_path", None)
        h = hashlib.sha256(json.dumps(data, sort_keys=True, separators=(",", ":")).encode())
        h.update(b"\0urdf\0")
        h.update(Path(self.urdf_path).read_bytes())
        return h.hexdigest()


def _canonical(x):
    """JSON-ready data of validated dataclasses/arrays; floats as repr strings (exact, stable)."""
    if is_dataclass(x):
        return {f.name: _canonical(getattr(x, f.name)) for f in fields(x)}
    if isinstance(x, dict):
        return {str(k): _canonical(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_canonical(v) for v in x]
    if isinstance(x, np.ndarray):
        return _canonical(x.tolist())
    if isinstance(x, Path):
        return str(x)
    if isinstance(x, bool) or x is None or isinstance(x, str):
        return x
    if isinstance(x, numbers.Integral):
        return int(x)
    if isinstance(x, numbers.Real):
        return repr(float(x))
    return repr(x)


def _load_arm(urdf_path: Path, hand_frame: str, where: str, **kw):
    """ArmModel of a URDF (model/arm.py refuses non-XML, unparsable or non-serial URDFs in one
    line); the message is prefixed with the scenario that names it."""
    from qmt_drake.model.arm import ArmModel
    if Path(urdf_path).is_dir():
        raise QmtInputError(f"{where}: arm.urdf {urdf_path} is a directory; give the URDF file")
    try:
        return ArmModel.from_urdf(urdf_path, hand_frame=hand_frame, **kw)
    except QmtInputError as exc:
        raise QmtInputError(f"{where}: {exc}") from None
    except OSError as exc:
        raise QmtInputError(f"{where}: arm.urdf {urdf_path} cannot be read ({exc.strerror})") from None


# ---------------------------------------------------------------------------------------- loading
_TOP_KEYS = {"name", "description", "arm", "hand", "actuator", "payload", "task", "limits",
             "family", "ga", "sampling", "control", "reported", "notes", "source"}
_SECTION_KEYS = {
    "arm": {"kind", "urdf", "hand_frame"},
    "payload": {"name", "mass_kg", "com_offset_m", "length_m", "body"},
    "task": {"points_m", "tool_angle_rad", "ik_branch"},
    "limits": {"moment_limit_Nm", "motor_torque_limit_Nm", "joint_speed_fraction"},
    "family": {"kind", "genes"},
    "ga": {f.name for f in fields(GaSettings)},
    "sampling": {f.name for f in fields(Sampling)},
    "control": {"kp", "ki", "kd"},
    "reported": None,  # free-form
}
_HAND_KEYS = {"kind", "coil", "slip_boundary_Nm", "coil_current_A", "effective_gap_m", "friction",
              "contact_radius_m", "n_contact_points", "sphere_radius_m", "point_stiffness_N_per_m",
              "hunt_crossley_dissipation_s_per_m"}
_COIL_KEYS = {"name", "turns", "resistance_ohm", "core_diameter_m", "outer_diameter_m", "length_m"}


ENERGY_TIME_KIND = "energy_time"  # seed 001's scenarios (qmt_drake/energy/scenario.py) share the folder


def scenario_kind(path: Path) -> str:
    """A scenario file's top-level `kind` (transfer scenarios have none: 'transfer'); '' if the
    file cannot be read as a YAML mapping (load_scenario then says why)."""
    try:
        raw = yaml.safe_load(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return ""
    return str(raw.get("kind", "transfer")) if isinstance(raw, dict) else ""


def builtin_scenarios(kind: str = "transfer") -> list[str]:
    """Names of the built-in scenarios of one kind ('transfer': the planners' and co-simulation's;
    ENERGY_TIME_KIND: seed 001's energy-time experiments)."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml") if scenario_kind(p) == kind)


def read_scenario_yaml(path: Path, example: str = "thesis-ch4") -> dict:
    """The YAML mapping of a scenario file (duplicated keys refused); QmtInputError (one line) if it
    is not one."""
    return fields_mod.read_yaml_mapping(path, "scenario", SCENARIO_DIR / (example + ".yaml"))


def load_scenario(name_or_path: str | Path, overrides: dict | None = None) -> Scenario:
    """Load a built-in scenario by name or a YAML file by path; `overrides` is merged into the
    raw YAML mapping first (nested dicts merge key by key)."""
    path = Path(name_or_path)
    if not path.suffix and (SCENARIO_DIR / f"{name_or_path}.yaml").is_file():
        path = SCENARIO_DIR / f"{name_or_path}.yaml"
    if path.is_dir():
        raise QmtInputError(f"scenario '{name_or_path}' is a directory; give a built-in name "
                            f"({', '.join(builtin_scenarios())}) or a YAML file")
    if not path.is_file():
        raise QmtInputError(f"scenario '{name_or_path}' is neither a built-in "
                            f"({', '.join(builtin_scenarios())}) nor a YAML file that exists")
    raw = read_scenario_yaml(path)
    if raw.get("kind") == "spatial_transfer":  # issue 19: qmt_drake/spatial_task.py loads these
        raise QmtInputError(f"scenario '{name_or_path}' is a spatial (3-D) scenario: plan, re-check and co-simulate "
                            f"it with `python -m studies.spatial_benchmark --scenario {path.stem}`")
    if raw.get("kind") == ENERGY_TIME_KIND:
        raise QmtInputError(f"scenario '{name_or_path}' is a seed-001 energy-time scenario: plan it with "
                            f"`qmt-drake plan {name_or_path} --method snopt|steepest|ipopt|collocation`; "
                            "simulate, benchmark and sweeps take transfer scenarios")
    if overrides:
        raw = _merge(raw, overrides)
    return scenario_from_dict(raw, path)


def _merge(base: dict, extra: dict) -> dict:
    out = dict(base)
    for k, v in extra.items():
        # Gene maps are replaced whole: their keys are the family's genes, in order.
        nested = isinstance(v, dict) and isinstance(out.get(k), dict) and k != "genes"
        out[k] = _merge(out[k], v) if nested else v
    return out


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
    payload = _payload(raw["payload"], f"{where}: payload")
    task = _task(raw["task"], f"{where}: task")

    lim = raw["limits"]
    h = raw.get("hand")
    if isinstance(h, dict) and h.get("kind") == "tray" and (payload.body is None or payload.body.shell_mass_kg <= 0):
        raise QmtInputError(f"{where}: hand.kind 'tray' is not available for this payload: a tray carries a "
                            "bottle; give payload.body kind 'bottle' (radius_m, height_m, shell_mass_kg)")
    hand = _hand(h, f"{where}: hand")
    tray = isinstance(hand, TrayHand)
    if tray:
        if lim.get("moment_limit_Nm") is not None:
            raise QmtInputError(f"{where}: limits.moment_limit_Nm does not apply to a tray hand (its limits "
                                "are no slide, no tip, no lift-off from hand.friction and hand.contact_radius_m); "
                                "remove it")
        # Not a planning limit here: the bottle's tipping moment m g r_c (with the planning margin),
        # so that moment_limit / moment_per_accel = g r_c / h_G is the level tray's tipping
        # acceleration, the starting acceleration scale of the Ruckig baseline.
        moment = payload.mass_kg * 9.81 * hand.contact_radius_m * hand.plan_margin
    else:
        moment = _num(lim, "moment_limit_Nm", f"{where}: limits", positive=True)
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
    family = _family(raw["family"], f"{where}: family")
    ga = _ga(raw.get("ga") or {}, f"{where}: ga")
    sm = raw.get("sampling") or {}
    sampling = Sampling(**{f.name: _num(sm, f.name, f"{where}: sampling", positive=True,
                                        default=f.default) for f in fields(Sampling)})
    control = {}
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
    notes = raw.get("notes") or []
    if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
        raise QmtInputError(f"{where}: notes must be a list of strings")
    name = raw.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise QmtInputError(f"{where}: name must be a non-empty string, got {_show(name)}")
    description = raw.get("description", "")
    if not isinstance(description, str):
        raise QmtInputError(f"{where}: description must be a string, got {_show(description)}")

    sc = Scenario(
        name=name, description=description, source_path=path, urdf_path=arm_spec.urdf_path,
        hand_frame=arm_spec.hand_frame, payload=payload, task=task, limits=limits, family=family,
        ga=ga, sampling=sampling, control=control, reported=reported,
        notes=tuple(notes), arm_spec=arm_spec,
        hand=hand,
        actuator=_actuator(raw.get("actuator"), limits, f"{where}: actuator"))
    _check_against_arm(sc, where)
    if tray:
        _check_tray(sc, where)
    return sc


def _arm(a: dict, path: Path, where: str) -> UrdfArm:
    kind = a.get("kind", "urdf")
    if kind != "urdf":
        raise QmtInputError(f"{where}: arm.kind {_show(kind)} is not available; use 'urdf' "
                            "(generated arms are not implemented yet)")
    urdf_raw = _need(a, "urdf", f"{where}: arm")
    if not isinstance(urdf_raw, str) or not urdf_raw:
        raise QmtInputError(f"{where}: arm.urdf must be a file path, got {_show(urdf_raw)}")
    urdf = Path(urdf_raw)
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
    frame = a.get("hand_frame", "hand")
    if not isinstance(frame, str) or not frame:
        raise QmtInputError(f"{where}: arm.hand_frame must be a frame name, got {_show(frame)}")
    return UrdfArm(urdf_path=urdf, hand_frame=frame)


def _payload(p: dict, where: str) -> Payload:
    mass = _num(p, "mass_kg", where, positive=True)
    r_g = _num(p, "com_offset_m", where, positive=True)
    name = p.get("name", "payload")
    if not isinstance(name, str):
        raise QmtInputError(f"{where}.name must be a string, got {_show(name)}")
    length = None if p.get("length_m") is None else _num(p, "length_m", where, positive=True)
    b = p.get("body", {"kind": "steel_cylinder"})
    bw = f"{where}.body"
    if not isinstance(b, dict):
        raise QmtInputError(f"{bw} must be a mapping with kind steel_cylinder or cylinder, "
                            f"got {_show(b)}")
    kind = b.get("kind")
    if kind == "steel_cylinder":
        _check_keys(b, {"kind", "name"}, bw)
        # Fig. 3.4 prints no dimensions: a steel cylinder of length 2 r_G whose radius follows
        # from the mass (the face is the whole end).
        blen = 2.0 * r_g
        rad = math.sqrt(mass / (STEEL_DENSITY_KG_M3 * math.pi * blen))
        body = PayloadBody(str(b.get("name", "steel part")), blen, rad, rad)
    elif kind == "bottle":
        # An unfixed bottle on a tray (seed 002): com_offset_m is its centre of mass above its base.
        _check_keys(b, {"kind", "name", "radius_m", "height_m", "shell_mass_kg"}, bw)
        height = _num(b, "height_m", bw, positive=True)
        shell = _num(b, "shell_mass_kg", bw, positive=True)
        if r_g >= height:
            raise QmtInputError(f"{where}.com_offset_m {r_g} m (the bottle's centre of mass above its base) must "
                                f"lie inside the bottle (below height_m {height} m)")
        if shell > mass:
            raise QmtInputError(f"{bw}.shell_mass_kg {shell} kg exceeds the bottle's mass {mass} kg")
        body = PayloadBody(str(b.get("name", name)), height, _num(b, "radius_m", bw, positive=True),
                           _num(b, "radius_m", bw, positive=True), shell)
    elif kind == "cylinder":
        _check_keys(b, {"kind", "name", "length_m", "radius_m", "face_radius_m"}, bw)
        body = PayloadBody(str(b.get("name", name)), _num(b, "length_m", bw, positive=True),
                           _num(b, "radius_m", bw, positive=True),
                           _num(b, "face_radius_m", bw, positive=True))
    else:
        raise QmtInputError(f"{bw}.kind must be 'steel_cylinder' (sized from mass and r_G), "
                            f"'cylinder' (length_m, radius_m, face_radius_m) or 'bottle' (radius_m, height_m, "
                            f"shell_mass_kg), got {_show(kind)}")
    return Payload(name=name, mass_kg=mass, com_offset_m=r_g, length_m=length, body=body)


def _task(t: dict, where: str) -> Task:
    pts_raw = _need(t, "points_m", where)
    shape_hint = "a list of at least two [x, y] points in metres"
    if (not isinstance(pts_raw, list) or len(pts_raw) < 2
            or not all(isinstance(p, list) for p in pts_raw)):
        raise QmtInputError(f"{where}.points_m must be {shape_hint}, got {_show(pts_raw)}")
    for i, p in enumerate(pts_raw):
        if len(p) != 2:
            raise QmtInputError(f"{where}.points_m[{i}] has {len(p)} coordinates; planar arms take "
                                f"[x, y] in metres ({shape_hint})")
        for v in p:
            if not _is_number(v):
                raise QmtInputError(f"{where}.points_m[{i}] must hold numbers, got {_show(v)}")
    pts = np.asarray(pts_raw, dtype=float)
    if not np.all(np.isfinite(pts)):
        raise QmtInputError(f"{where}.points_m must be finite numbers")
    branch = t.get("ik_branch", "elbow_positive")
    from qmt_drake.model.arm import IK_BRANCHES
    if branch not in IK_BRANCHES:
        raise QmtInputError(f"{where}.ik_branch {_show(branch)} is not one of {IK_BRANCHES}")
    tool = None if t.get("tool_angle_rad") is None else _num(t, "tool_angle_rad", where)
    return Task(points_m=pts, tool_angle_rad=tool, ik_branch=branch)


def _family(fam: dict, where: str) -> Family:
    kind = _need(fam, "kind", where)
    if kind not in FAMILY_KINDS:
        raise QmtInputError(f"{where}.kind {_show(kind)} is not one of {FAMILY_KINDS}")
    genes = _need(fam, "genes", where)
    if not isinstance(genes, dict) or not genes:
        raise QmtInputError(f"{where}.genes must map gene names to [min, max] bounds")
    bounds = []
    for gname, b in genes.items():
        if not (isinstance(b, list) and len(b) == 2 and all(_is_number(v) for v in b)):
            raise QmtInputError(f"{where}.genes.{gname} must be [min, max] (numbers), got {_show(b)}")
        lo, hi = float(b[0]), float(b[1])
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise QmtInputError(f"{where}.genes.{gname} bounds must be finite, got {b}")
        if not lo < hi:
            raise QmtInputError(f"{where}.genes.{gname} has min {lo} >= max {hi}; "
                                "swap them or widen the range")
        if lo <= 0:
            raise QmtInputError(f"{where}.genes.{gname} min {lo} must be positive "
                                "(times and rates)")
        bounds.append((lo, hi))
    return Family(kind=kind, gene_names=tuple(str(g) for g in genes), gene_bounds=np.array(bounds))


def _ga(g: dict, where: str) -> GaSettings:
    d = GaSettings()
    kw = {}
    for k in ("population", "bits_per_gene", "max_generations"):
        kw[k] = _int(g, k, where, minimum=1, default=getattr(d, k))
    for k in ("elite_count", "stall_generations", "mutants_per_generation"):
        kw[k] = _int(g, k, where, minimum=0, default=getattr(d, k))
    kw["tight_timing"] = g.get("tight_timing", d.tight_timing)
    if not isinstance(kw["tight_timing"], bool):
        raise QmtInputError(f"{where}.tight_timing must be true or false, got {_show(kw['tight_timing'])}")
    for k in ("crossover_rate", "mutation_rate"):
        kw[k] = _num(g, k, where, default=getattr(d, k))
        if not 0.0 <= kw[k] <= 1.0:
            raise QmtInputError(f"{where}.{k} must lie in [0, 1], got {kw[k]}")
    kw["fitness_c_per_s"] = _num(g, "fitness_c_per_s", where, positive=True, default=d.fitness_c_per_s)
    for k, allowed in (("selection", ("roulette", "tournament")), ("encoding", ("binary", "gray"))):
        kw[k] = g.get(k, getattr(d, k))
        if kw[k] not in allowed:
            raise QmtInputError(f"{where}.{k} must be one of {allowed}, got {_show(kw[k])}")
    if kw["population"] < 2 or kw["population"] % 2:
        raise QmtInputError(f"{where}.population must be an even number >= 2, got {kw['population']}")
    if kw["elite_count"] >= kw["population"]:
        raise QmtInputError(f"{where}.elite_count {kw['elite_count']} must be below the population "
                            f"{kw['population']}")
    return GaSettings(**kw)


def _hand(h, where: str) -> MagnetHand | None:
    if h is None:
        return None
    if not isinstance(h, dict):
        raise QmtInputError(f"{where} must be a mapping with kind: magnet, got {_show(h)}")
    kind = h.get("kind", "magnet")
    if kind == "tray":
        return _tray_hand(h, where)
    if kind != "magnet":
        raise QmtInputError(f"{where}.kind {_show(kind)} is not available; use 'magnet' or 'tray'")
    _check_keys(h, _HAND_KEYS, where)
    from qmt_drake.systems.electromagnet import THESIS_COILS, CoilSpec
    c = _need(h, "coil", where)
    if isinstance(c, str):
        if c not in THESIS_COILS:
            raise QmtInputError(f"{where}.coil {c!r} is not one of {sorted(THESIS_COILS)}; name one or "
                                f"give a mapping with {', '.join(sorted(_COIL_KEYS - {'name'}))}")
        coil, coil_name = THESIS_COILS[c], c
    elif isinstance(c, dict):
        cw = f"{where}.coil"
        _check_keys(c, _COIL_KEYS, cw)
        coil = CoilSpec(str(c.get("name", "coil")), _int(c, "turns", cw, minimum=1),
                        _num(c, "resistance_ohm", cw, positive=True),
                        _num(c, "core_diameter_m", cw, positive=True),
                        _num(c, "outer_diameter_m", cw, positive=True), _num(c, "length_m", cw, positive=True))
        coil_name = "explicit"
    else:
        raise QmtInputError(f"{where}.coil must name a thesis coil ({', '.join(sorted(THESIS_COILS))}) "
                            f"or be a mapping, got {_show(c)}")
    boundary = current = None
    if h.get("slip_boundary_Nm") is not None:
        b = _vector(h, "slip_boundary_Nm", where, positive=True, what="[last success, first failure] [N*m]")
        if b.shape != (2,) or not b[0] < b[1]:
            raise QmtInputError(f"{where}.slip_boundary_Nm must be [last success, first failure] with "
                                f"the first below the second, got {b.tolist()}")
        boundary = (float(b[0]), float(b[1]))
    if h.get("coil_current_A") is not None:
        current = _num(h, "coil_current_A", where, positive=True)
    if (boundary is None) == (current is None):
        raise QmtInputError(f"{where}: give exactly one of slip_boundary_Nm (calibrate the coil current) "
                            "or coil_current_A")
    d = MagnetHand(coil=coil, coil_name=coil_name)
    kw = {k: _num(h, k, where, positive=True, default=getattr(d, k))
          for k in ("effective_gap_m", "friction", "contact_radius_m", "sphere_radius_m",
                    "point_stiffness_N_per_m", "hunt_crossley_dissipation_s_per_m")}
    kw["n_contact_points"] = _int(h, "n_contact_points", where, minimum=3, default=d.n_contact_points)
    return MagnetHand(coil=coil, coil_name=coil_name, slip_boundary_Nm=boundary, coil_current_A=current, **kw)


_TRAY_KEYS = {f.name for f in fields(TrayHand)}


def _tray_hand(h: dict, where: str) -> TrayHand:
    _check_keys(h, _TRAY_KEYS, where)
    d = TrayHand()
    fr = h.get("friction", d.friction)
    if not _is_number(fr) or not math.isfinite(fr) or fr <= 0:
        raise QmtInputError(f"{where}.friction {_show(fr)} must be a positive number (the bottle-tray Coulomb "
                            "coefficient; dry PET on plastic is about 0.2-0.5)")
    kw = {k: _num(h, k, where, positive=True, default=getattr(d, k))
          for k in ("contact_radius_m", "plan_margin", "tray_mass_kg")}
    if kw["plan_margin"] > 1:
        raise QmtInputError(f"{where}.plan_margin {kw['plan_margin']} must lie in (0, 1]; it scales friction and "
                            "ring radius for planning")
    kw["rest_tilt_rad"] = abs(_num(h, "rest_tilt_rad", where, default=d.rest_tilt_rad))
    kw["n_contact_points"] = _int(h, "n_contact_points", where, minimum=3, default=d.n_contact_points)
    return TrayHand(friction=float(fr), **kw)


def _check_tray(sc: Scenario, where: str) -> None:
    """The task's tray points inside the joint ranges (tray level: task.tool_angle_rad) and the
    bottle standing at rest: one line each, before any planning."""
    b = sc.payload.body
    if sc.hand.contact_radius_m > b.radius_m:
        raise QmtInputError(f"{where}: hand.contact_radius_m {sc.hand.contact_radius_m} m is wider than the bottle "
                            f"(payload.body.radius_m {b.radius_m} m)")
    bottle = sc.bottle
    try:
        bottle.check_rests(sc.hand.rest_tilt_rad)
    except QmtInputError as exc:
        raise QmtInputError(f"{where}: payload: {exc} (the tray at rest: hand.rest_tilt_rad "
                            f"{sc.hand.rest_tilt_rad:.4g} rad)") from None
    for i, p in enumerate(sc.task.points_m):
        try:
            sc.arm.inverse_kinematics(p, sc.task.tool_angle_rad, sc.task.ik_branch, what=f"tray point {i + 1}")
        except QmtInputError as exc:
            raise QmtInputError(f"{where}: task.points_m[{i}] ({p[0]:g}, {p[1]:g}) m: {exc}") from None


def _actuator(a, limits: Limits, where: str):
    if a is None:
        return None
    if not isinstance(a, dict):
        raise QmtInputError(f"{where} must be a mapping with kind dc_motor_gear, ideal or dynamixel, got {_show(a)}")
    kind = a.get("kind")
    if kind == "dynamixel":
        return _dynamixel(a, where)
    if kind == "ideal":
        _check_keys(a, {"kind"}, where)
        return IdealTorque()
    if kind != "dc_motor_gear":
        raise QmtInputError(f"{where}.kind must be 'dc_motor_gear' or 'ideal' (motor models) or 'dynamixel' "
                            f"(position servos), got {_show(kind)}")
    _check_keys(a, {"kind", "motors", "efficiency"}, where)
    from qmt_drake.systems.dc_motor import HARMONIC_DRIVE_EFFICIENCY, MOTOR_CATALOG, motor_for_rated_torque
    motors = a.get("motors", "by_rated_torque")
    if motors == "by_rated_torque":
        # The smallest catalogue motor whose continuous torque covers each rated motor torque.
        inv = {id(v): k for k, v in MOTOR_CATALOG.items()}
        motors = [inv[id(motor_for_rated_torque(t))] for t in limits.motor_torque_limit_Nm]
    if not isinstance(motors, list) or not all(isinstance(m, str) for m in motors):
        raise QmtInputError(f"{where}.motors must be a list of catalogue motor names or 'by_rated_torque', "
                            f"got {_show(motors)}")
    for m in motors:
        if m not in MOTOR_CATALOG:
            raise QmtInputError(f"{where}.motors: {m!r} is not in the catalogue ({', '.join(MOTOR_CATALOG)})")
    eff = _num(a, "efficiency", where, positive=True, default=HARMONIC_DRIVE_EFFICIENCY)
    if eff > 1:
        raise QmtInputError(f"{where}.efficiency must lie in (0, 1], got {eff}")
    return DcMotorGear(motors=tuple(motors), efficiency=eff)


def _dynamixel(a: dict, where: str) -> DynamixelServos:
    _check_keys(a, {"kind", "servos", "p", "i", "d", "control_period_s"}, where)
    from qmt_drake.systems.dynamixel_servo import SERVO_CATALOG
    servos = _need(a, "servos", where)
    if not isinstance(servos, list) or not all(isinstance(x, str) for x in servos):
        raise QmtInputError(f"{where}.servos must be a list of servo models ({', '.join(SERVO_CATALOG)}), "
                            f"got {_show(servos)}")
    for x in servos:
        if x not in SERVO_CATALOG:
            raise QmtInputError(f"{where}.servos: {x!r} is not one of {', '.join(SERVO_CATALOG)}")
    gains = {}
    for k in ("p", "i", "d"):
        v = _vector(a, k, where, nonnegative=True, what="control-table gains, one per servo")
        if np.any(v > 16383) or np.any(v != np.round(v)):
            raise QmtInputError(f"{where}.{k} {v.tolist()} must be integers in the control table's range 0..16383")
        if len(v) != len(servos):
            raise QmtInputError(f"{where}.{k} has {len(v)} entries for {len(servos)} servos; give one per servo")
        gains[k] = tuple(float(x) for x in v)
    period = _num(a, "control_period_s", where, positive=True, default=1e-3)
    return DynamixelServos(servos=tuple(servos), control_period_s=period, **gains)


def _check_against_arm(sc: Scenario, where: str) -> None:
    """Lists that go one per joint must match the arm's joint count (loads the arm once)."""
    n = sc.arm.n_dof
    checks = [("limits.motor_torque_limit_Nm", sc.limits.motor_torque_limit_Nm)]
    checks += [(f"control.{k}", v) for k, v in sc.control.items()]
    if isinstance(sc.actuator, DcMotorGear):
        checks.append(("actuator.motors", sc.actuator.motors))
    if isinstance(sc.actuator, DynamixelServos):
        checks.append(("actuator.servos", sc.actuator.servos))
    for key, v in checks:
        if len(v) != n:
            raise QmtInputError(f"{where}: {key} has {len(v)} entries but the arm "
                                f"({sc.urdf_path.name}) has {n} joints; give one per joint")


# ------------------------------------------------------------------------------------ value checks
# The shared validation layer (config/fields.py), under this module's historical names.
_show = fields_mod.show
_is_number = fields_mod.is_number
_check_keys = fields_mod.check_keys
_need = fields_mod.need
_MISSING = fields_mod.MISSING
_num = fields_mod.num
_int = fields_mod.integer
_vector = fields_mod.vector
