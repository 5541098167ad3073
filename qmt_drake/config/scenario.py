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

import math
from dataclasses import fields
from pathlib import Path

import numpy as np
import yaml

from qmt_drake.catalog import (
    HARMONIC_DRIVE_EFFICIENCY,
    IK_BRANCHES,
    MOTOR_CATALOG,
    SERVO_CATALOG,
    THESIS_COILS,
    CoilSpec,
    motor_for_rated_torque,
)
from qmt_drake.config import fields as fields_mod
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
    register_builders,
    registered_validator,
)
from qmt_drake.errors import QmtInputError

MODELS_DIR = Path(__file__).resolve().parents[2] / "models"
SCENARIO_DIR = MODELS_DIR / "scenarios"
FAMILY_KINDS = ("line_cubic_velocity", "trapezoid_ptp", "via_cubic")
STEEL_DENSITY_KG_M3 = 7850.0



# ---------------------------------------------------------------------------------------- loading
_TOP_KEYS = {"name", "description", "world", "uncertainty", "arm", "hand", "actuator", "payload", "task", "limits",
             "family", "ga", "sampling", "control", "reported", "notes", "source"}
_SECTION_KEYS = {
    "world": {"gravity_m_s2"},
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


# planners/spatial_methods.METHODS (named here: config imports nothing above it; a test checks they agree)
SPATIAL_METHODS = ("toppra", "ruckig", "family_optimum", "ga", "trajopt")


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
        raise QmtInputError(f"scenario '{name_or_path}' is a spatial (3-D) scenario: plan it with `qmt-drake plan "
                            f"{name_or_path} --method {'|'.join(SPATIAL_METHODS)} --json PLAN.json` and co-simulate "
                            f"it with `qmt-drake simulate {name_or_path} --plan PLAN.json`")
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

    world = _world(raw.get("world") or {}, f"{where}: world")
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
        moment = payload.mass_kg * world.g_m_s2 * hand.contact_radius_m * hand.plan_margin
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
    act_kind = (raw.get("actuator") or {}).get("kind") if isinstance(raw.get("actuator"), dict) else None
    if raw.get("control") and act_kind == "dynamixel":
        raise QmtInputError(f"{where}: control.{'/'.join(raw['control'])} are the PID gains of DC motors or ideal "
                            "actuators; a Dynamixel scenario sets its firmware gains in actuator.p / i / d "
                            "(control-table units): move them there and drop the control section")
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
        actuator=_actuator(raw.get("actuator"), limits, f"{where}: actuator"), world=world,
        uncertainty=_uncertainty(raw.get("uncertainty"), f"{where}: uncertainty"))
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


def _uncertainty(u, where: str) -> dict:
    """The shape only (a mapping with `parameters` and optional `monte_carlo`); the distributions are
    checked by the sweep spec's validation when `plan --success` uses them."""
    if u is None:
        return {}
    if not isinstance(u, dict):
        raise QmtInputError(f"{where} must be a mapping {{parameters: {{friction: {{dist: normal, mean: 0.3, "
                            f"std: 0.03}}}}, monte_carlo: {{cases: 200, seed: 1}}}}, got {_show(u)}")
    _check_keys(u, {"parameters", "monte_carlo"}, where)
    if not isinstance(u.get("parameters"), dict) or not u["parameters"]:
        raise QmtInputError(f"{where}.parameters must be a non-empty mapping of parameter -> distribution "
                            "(the sweep spec's form, models/sweeps/ch4-ga-mc200.yaml)")
    check = registered_validator("uncertainty")
    if check is not None:
        check(u, where)
    return dict(u)


def _world(w: dict, where: str) -> World:
    if not isinstance(w, dict):
        raise QmtInputError(f"{where} must be a mapping like {{gravity_m_s2: [0, 0, -9.81]}}, got {_show(w)}")
    _check_keys(w, _SECTION_KEYS["world"], where)
    if "gravity_m_s2" not in w:
        return World()
    g = _vector(w, "gravity_m_s2", where, what="the gravity vector in the world frame, m/s^2")
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise QmtInputError(f"{where}.gravity_m_s2 must be three finite numbers [gx, gy, gz] in m/s^2, got {g.tolist()}")
    return World(tuple(float(x) for x in g))


def _dynamixel(a: dict, where: str) -> DynamixelServos:
    _check_keys(a, {"kind", "servos", "p", "i", "d", "ff1", "ff2", "control_period_s", "reference"}, where)
    reference = a.get("reference", "plain")
    if reference not in ("plain", "shaped"):
        raise QmtInputError(f"{where}.reference must be 'plain' (stream the plan) or 'shaped' (goals that make "
                            f"the servo loop execute the plan), got {_show(reference)}")
    servos = _need(a, "servos", where)
    if not isinstance(servos, list) or not all(isinstance(x, str) for x in servos):
        raise QmtInputError(f"{where}.servos must be a list of servo models ({', '.join(SERVO_CATALOG)}), "
                            f"got {_show(servos)}")
    for x in servos:
        if x not in SERVO_CATALOG:
            raise QmtInputError(f"{where}.servos: {x!r} is not one of {', '.join(SERVO_CATALOG)}")
    gains = {}
    for k in ("p", "i", "d", "ff1", "ff2"):
        if k in ("ff1", "ff2") and k not in a:
            gains[k] = tuple(0.0 for _ in servos)  # the servo's default: no feedforward
            continue
        v = _vector(a, k, where, nonnegative=True, what="control-table gains, one per servo")
        if np.any(v > 16383) or np.any(v != np.round(v)):
            raise QmtInputError(f"{where}.{k} {v.tolist()} must be integers in the control table's range 0..16383")
        if len(v) != len(servos):
            raise QmtInputError(f"{where}.{k} has {len(v)} entries for {len(servos)} servos; give one per servo")
        gains[k] = tuple(float(x) for x in v)
    period = _num(a, "control_period_s", where, positive=True, default=1e-3)
    return DynamixelServos(servos=tuple(servos), control_period_s=period, reference=reference, **gains)


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
