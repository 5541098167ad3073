"""The per-section validators of a scenario: one raw YAML mapping in, one typed section out
(config/sections.py), or a one-line QmtInputError naming the key and the fix.

config/scenario.py reads the file, resolves the arm's URDF, calls these and then checks the
sections against the loaded arm (per-joint list lengths, tray points reachable, bottle at rest).
Numbers are checked as numbers (config/fields.py): a YAML `true` is not 1, a string is not 0.5.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import fields

import numpy as np

from qmt_drake.catalog import (
    HARMONIC_DRIVE_EFFICIENCY,
    IK_BRANCHES,
    MOTOR_CATALOG,
    SERVO_CATALOG,
    STEEL_DENSITY_KG_M3,
    THESIS_COILS,
    CoilSpec,
    motor_for_rated_torque,
)
from qmt_drake.config import fields as fields_mod
from qmt_drake.config.registry import (
    ACTUATORS,
    DEFAULT_HAND_KIND,
    FAMILIES,
    HANDS,
    TRANSFER,
    for_scenario_kind,
)
from qmt_drake.config.sections import (
    DcMotorGear,
    DynamixelServos,
    Family,
    GaSettings,
    IdealTorque,
    Limits,
    MagnetHand,
    Payload,
    PayloadBody,
    Task,
    TrayHand,
    World,
)
from qmt_drake.errors import QmtInputError

WORLD_KEYS = {"gravity_m_s2"}
SERVO_PERIOD_RANGE_S = (1e-4, 0.1)  # a Dynamixel position loop's control period [s] (parse_dynamixel)

_HAND_KEYS = {"kind", "coil", "slip_boundary_Nm", "coil_current_A", "effective_gap_m", "friction",
              "contact_radius_m", "n_contact_points", "sphere_radius_m", "point_stiffness_N_per_m",
              "hunt_crossley_dissipation_s_per_m"}
_COIL_KEYS = {"name", "turns", "resistance_ohm", "core_diameter_m", "outer_diameter_m", "length_m"}


SCENARIO_KINDS = ("transfer", "spatial_transfer", "energy_time")  # a file's top-level `kind` (none: transfer)
SPATIAL_ONLY_KEYS = {"actuators"}  # a spatial file's section a transfer file never has (its is `actuator`)


def check_scenario_kind(raw: dict, where: str) -> None:
    """A misspelt top-level `kind`, or a spatial file without one, named as such (not as an unknown key
    of the transfer scenario it was then read as)."""
    kind = raw.get("kind", "transfer")
    if kind not in SCENARIO_KINDS:
        near = difflib.get_close_matches(str(kind), SCENARIO_KINDS, n=1)
        raise QmtInputError(f"{where}: kind {_show(kind)} is not a scenario kind; "
                            + (f"did you mean {near[0]!r}? " if near else "")
                            + "use spatial_transfer or energy_time, or no kind for a transfer scenario")
    spatial = sorted(SPATIAL_ONLY_KEYS & set(raw))
    if "kind" not in raw and spatial:
        raise QmtInputError(f"{where}: no top-level kind, but the spatial section {spatial[0]!r}: add "
                            "'kind: spatial_transfer' (a transfer scenario has 'actuator')")


def parse_payload(p: dict, where: str) -> Payload:
    """`payload`: mass, r_G and the rigid body the co-simulation uses (steel cylinder, cylinder, bottle)."""
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


def parse_task(t: dict, where: str) -> Task:
    """`task`: the [x, y] task points (m), the tool angle and the IK branch."""
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


def parse_family(fam: dict, where: str) -> Family:
    """`family`: a registered transfer family (config/registry.FAMILIES) and its genes' [min, max]
    bounds (all positive; the family checks the gene names against its own when it is built)."""
    kind = _need(fam, "kind", where)
    FAMILIES.get(kind, where, accept=for_scenario_kind(TRANSFER))
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


def parse_ga(g: dict, where: str) -> GaSettings:
    """`ga`: the GA settings, defaults from GaSettings."""
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


def parse_hand(h, where: str):
    """`hand`: the section of a registered hand kind (config/registry.HANDS: magnet, tray, ...),
    parsed by its plug-in; None without a hand."""
    if h is None:
        return None
    if not isinstance(h, dict):
        raise QmtInputError(f"{where} must be a mapping with kind: {' | '.join(HANDS.kinds())}, got {_show(h)}")
    return HANDS.get(h.get("kind", DEFAULT_HAND_KIND), where).parse(h, where)


def parse_magnet_hand(h: dict, where: str) -> MagnetHand:
    """hand.kind 'magnet': the coil, its current or slip boundary, the contact."""
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


def parse_tray_hand(h: dict, where: str) -> TrayHand:
    """hand.kind 'tray': the bottle-tray friction and ring, the planning margin, the rest tilt."""
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



def parse_actuator(a, limits: Limits, where: str):
    """`actuator`: the section of a registered actuator kind (config/registry.ACTUATORS: DC motors
    with gears, ideal torque sources, Dynamixel servos, ...), parsed by its plug-in; None without one."""
    if a is None:
        return None
    if not isinstance(a, dict):
        raise QmtInputError(f"{where} must be a mapping with kind {' | '.join(ACTUATORS.kinds())}, got {_show(a)}")
    return ACTUATORS.get(a.get("kind"), where).parse(a, limits, where)


def parse_ideal_torque(a: dict, limits: Limits, where: str) -> IdealTorque:
    """actuator.kind 'ideal': no keys besides the kind."""
    _check_keys(a, {"kind"}, where)
    return IdealTorque()


def parse_dc_motor_gear(a: dict, limits: Limits, where: str) -> DcMotorGear:
    """actuator.kind 'dc_motor_gear': catalogue motors (or 'by_rated_torque') and the gear efficiency."""
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


def parse_uncertainty(u, where: str) -> dict:
    """The shape only (a mapping with `parameters` and optional `monte_carlo`); the distributions are
    the sweep's vocabulary, checked by transfer_scenario.load_scenario (sweep/parameters.validate_uncertainty)."""
    if u is None:
        return {}
    if not isinstance(u, dict):
        raise QmtInputError(f"{where} must be a mapping {{parameters: {{friction: {{dist: normal, mean: 0.3, "
                            f"std: 0.03}}}}, monte_carlo: {{cases: 200, seed: 1}}}}, got {_show(u)}")
    _check_keys(u, {"parameters", "monte_carlo"}, where)
    if not isinstance(u.get("parameters"), dict) or not u["parameters"]:
        raise QmtInputError(f"{where}.parameters must be a non-empty mapping of parameter -> distribution "
                            "(the sweep spec's form, models/sweeps/ch4-ga-mc200.yaml)")
    return dict(u)


def parse_world(w: dict, where: str) -> World:
    """`world`: the gravity vector (m/s^2)."""
    if not isinstance(w, dict):
        raise QmtInputError(f"{where} must be a mapping like {{gravity_m_s2: [0, 0, -9.81]}}, got {_show(w)}")
    _check_keys(w, WORLD_KEYS, where)
    if "gravity_m_s2" not in w:
        return World()
    g = _vector(w, "gravity_m_s2", where, what="the gravity vector in the world frame, m/s^2")
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise QmtInputError(f"{where}.gravity_m_s2 must be three finite numbers [gx, gy, gz] in m/s^2, got {g.tolist()}")
    return World(tuple(float(x) for x in g))


def parse_dynamixel(a: dict, limits: Limits, where: str) -> DynamixelServos:
    """actuator.kind 'dynamixel': servo models, firmware gains (control-table units), period, goal stream."""
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
    for k, servo in enumerate(servos):  # without P and I the position loop has nothing to close on
        if gains["p"][k] == 0 and gains["i"][k] == 0:
            raise QmtInputError(f"{where}: servo {k + 1} ({servo}) has p = i = 0: its position loop never pulls toward "
                                "the goal; give p > 0 (the servo default is 800)")
    # the firmware's loop runs at ~1 kHz; below 0.1 ms the replay's servo updates (and its memory) explode
    # (1e-7 s: 3.7 GB), above 0.1 s the loop is too slow to follow any plan
    period = _num(a, "control_period_s", where, minimum=SERVO_PERIOD_RANGE_S[0], maximum=SERVO_PERIOD_RANGE_S[1],
                  default=1e-3)
    return DynamixelServos(servos=tuple(servos), control_period_s=period, reference=reference, **gains)



# ------------------------------------------------------------------------------------ value checks
# The shared validation layer (config/fields.py), under this module's historical names.
_show = fields_mod.show
_is_number = fields_mod.is_number
_check_keys = fields_mod.check_keys
_need = fields_mod.need
_num = fields_mod.num
_int = fields_mod.integer
_vector = fields_mod.vector
