"""Scenarios: a typed description of one transfer task, loaded from YAML and validated.

A scenario names the arm (URDF), the payload (mass, r_G), the task points and IK branch, the
planning limits, the trajectory family with its genes and bounds, the GA settings, the joint
control gains and what the thesis reported. Built-in scenarios live in `models/scenarios/` and are
loaded by name (`thesis-ch2`, `thesis-ch3`, `thesis-ch4`); any other YAML file by path.

Every problem with a file raises QmtInputError with one line naming the key and the fix.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from qmt_drake.errors import QmtInputError

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"
SCENARIO_DIR = MODELS_DIR / "scenarios"
FAMILY_KINDS = ("line_cubic_velocity", "trapezoid_ptp", "via_cubic")


@dataclass(frozen=True)
class Payload:
    """The carried part. `com_offset_m` is r_G, attraction face to centre of mass."""

    name: str
    mass_kg: float
    com_offset_m: float
    length_m: float | None = None  # size for the co-simulation body (None: the co-sim decides)


@dataclass(frozen=True)
class Limits:
    """Planning limits. Moment |tau_M| = m_o * r_G * |a_tip| (eq. 2-24, 3-10, 4-33); motor torque
    is motor side (joint torque / N, eq. 2-34)."""

    moment_limit_Nm: float
    motor_torque_limit_Nm: np.ndarray


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
    control: dict = field(default_factory=dict)
    reported: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    @cached_property
    def arm(self):
        """The ArmModel built from the URDF with the carried part welded to the hand (loaded once
        per scenario object)."""
        from qmt_drake.model.arm import ArmModel
        from qmt_drake.systems.payload import PayloadSpec
        carried = PayloadSpec.for_scenario(self).spatial_inertia_about_origin()
        return ArmModel.from_urdf(self.urdf_path, hand_frame=self.hand_frame, carried_inertia=carried)

    def fingerprint(self) -> str:
        """sha256 of the scenario's data and its URDF's bytes (GA checkpoints store it)."""
        import hashlib
        from dataclasses import fields
        parts = [repr((f.name, getattr(self, f.name))) for f in fields(self) if f.name != "source_path"]
        h = hashlib.sha256("\n".join(parts).encode())
        h.update(Path(self.urdf_path).read_bytes())
        return h.hexdigest()

    @cached_property
    def limit_set(self):
        """The scenario's LimitSet (payload moment, motor torques, joint ranges)."""
        from qmt_drake.limits import LimitSet
        return LimitSet.for_scenario(self)

    @property
    def gear_ratio(self) -> np.ndarray:
        return self.arm.gear_ratio

    @property
    def moment_per_accel_kgm(self) -> float:
        """m_o * r_G: payload moment per unit tip acceleration."""
        return self.payload.mass_kg * self.payload.com_offset_m


# ---------------------------------------------------------------------------------------- loading
_TOP_KEYS = {"name", "description", "arm", "payload", "task", "limits", "family", "ga",
             "sampling", "control", "reported", "notes", "source"}
_SECTION_KEYS = {
    "arm": {"urdf", "hand_frame"},
    "payload": {"name", "mass_kg", "com_offset_m", "length_m"},
    "task": {"points_m", "tool_angle_rad", "ik_branch"},
    "limits": {"moment_limit_Nm", "motor_torque_limit_Nm"},
    "family": {"kind", "genes"},
    "ga": set(GaSettings.__dataclass_fields__),
    "sampling": set(Sampling.__dataclass_fields__),
}


def builtin_scenarios() -> list[str]:
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml"))


def load_scenario(name_or_path: str | Path, overrides: dict | None = None) -> Scenario:
    """Load a built-in scenario by name or a YAML file by path; `overrides` is merged into the
    raw YAML mapping first (nested dicts merge key by key)."""
    path = Path(name_or_path)
    if not path.suffix and (SCENARIO_DIR / f"{name_or_path}.yaml").is_file():
        path = SCENARIO_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        raise QmtInputError(f"scenario '{name_or_path}' is neither a built-in "
                            f"({', '.join(builtin_scenarios())}) nor a YAML file that exists")
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise QmtInputError(f"{path}: not valid YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(raw, dict):
        raise QmtInputError(f"{path}: a scenario file must be a YAML mapping")
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
        if sec in raw:
            if not isinstance(raw[sec], dict):
                raise QmtInputError(f"{where}: '{sec}' must be a mapping")
            _check_keys(raw[sec], keys, f"{where}: {sec}")
    for sec in ("arm", "payload", "task", "limits", "family"):
        if sec not in raw:
            raise QmtInputError(f"{where}: missing section '{sec}'")

    arm = raw["arm"]
    urdf = Path(_need(arm, "urdf", f"{where}: arm"))
    if not urdf.is_absolute():
        beside = (path.parent / urdf).resolve()
        # A built-in scenario copied elsewhere still finds the packaged model by its file name.
        packaged = MODELS_DIR / urdf.name
        urdf = beside if beside.is_file() or not packaged.is_file() else packaged
    if not urdf.is_file():
        raise QmtInputError(f"{where}: arm.urdf {urdf} does not exist; give a path relative to "
                            "the scenario file or an absolute one")

    p = raw["payload"]
    payload = Payload(
        name=str(p.get("name", "payload")),
        mass_kg=_positive(p, "mass_kg", f"{where}: payload"),
        com_offset_m=_positive(p, "com_offset_m", f"{where}: payload"),
        length_m=None if p.get("length_m") is None else _positive(p, "length_m",
                                                                    f"{where}: payload"))

    t = raw["task"]
    pts = np.asarray(_need(t, "points_m", f"{where}: task"), dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 2:
        raise QmtInputError(f"{where}: task.points_m must be a list of at least two [x, y] "
                            f"points in metres, got shape {pts.shape}")
    branch = str(t.get("ik_branch", "elbow_positive"))
    from qmt_drake.model.arm import IK_BRANCHES
    if branch not in IK_BRANCHES:
        raise QmtInputError(f"{where}: task.ik_branch '{branch}' is not one of {IK_BRANCHES}")
    tool = t.get("tool_angle_rad")
    task = Task(points_m=pts, tool_angle_rad=None if tool is None else float(tool),
                ik_branch=branch)

    lim = raw["limits"]
    motor = np.asarray(_need(lim, "motor_torque_limit_Nm", f"{where}: limits"), dtype=float)
    if motor.ndim != 1 or np.any(~np.isfinite(motor)) or np.any(motor <= 0):
        raise QmtInputError(f"{where}: limits.motor_torque_limit_Nm must be a list of positive "
                            f"numbers (one per joint), got {motor.tolist()}")
    limits = Limits(moment_limit_Nm=_positive(lim, "moment_limit_Nm", f"{where}: limits"),
                    motor_torque_limit_Nm=motor)

    fam = raw["family"]
    kind = _need(fam, "kind", f"{where}: family")
    if kind not in FAMILY_KINDS:
        raise QmtInputError(f"{where}: family.kind '{kind}' is not one of {FAMILY_KINDS}")
    genes = _need(fam, "genes", f"{where}: family")
    if not isinstance(genes, dict) or not genes:
        raise QmtInputError(f"{where}: family.genes must map gene names to [min, max] bounds")
    bounds = []
    for gname, b in genes.items():
        if not (isinstance(b, (list, tuple)) and len(b) == 2):
            raise QmtInputError(f"{where}: family.genes.{gname} must be [min, max], got {b!r}")
        lo, hi = float(b[0]), float(b[1])
        if not lo < hi:
            raise QmtInputError(f"{where}: family.genes.{gname} has min {lo} >= max {hi}; "
                                "swap them or widen the range")
        if lo <= 0:
            raise QmtInputError(f"{where}: family.genes.{gname} min {lo} must be positive "
                                "(times and rates)")
        bounds.append((lo, hi))
    family = Family(kind=kind, gene_names=tuple(genes), gene_bounds=np.array(bounds))

    ga = GaSettings(**raw.get("ga", {}))
    for k in ("population", "bits_per_gene", "max_generations"):
        if int(getattr(ga, k)) < 1:
            raise QmtInputError(f"{where}: ga.{k} must be a positive integer")
    if ga.population < 2 or ga.population % 2:
        raise QmtInputError(f"{where}: ga.population must be an even number >= 2, got "
                            f"{ga.population}")
    for k in ("crossover_rate", "mutation_rate"):
        if not 0.0 <= getattr(ga, k) <= 1.0:
            raise QmtInputError(f"{where}: ga.{k} must lie in [0, 1]")
    if ga.encoding not in ("binary", "gray"):
        raise QmtInputError(f"{where}: ga.encoding must be 'binary' or 'gray'")
    if ga.selection not in ("roulette", "tournament"):
        raise QmtInputError(f"{where}: ga.selection must be 'roulette' or 'tournament'")
    if ga.fitness_c_per_s <= 0:
        raise QmtInputError(f"{where}: ga.fitness_c_per_s must be positive")
    sampling = Sampling(**raw.get("sampling", {}))
    if sampling.plan_rate_hz <= 0 or sampling.check_rate_hz <= 0:
        raise QmtInputError(f"{where}: sampling rates must be positive")

    return Scenario(
        name=str(raw.get("name", path.stem)), description=str(raw.get("description", "")),
        source_path=path, urdf_path=urdf, hand_frame=str(arm.get("hand_frame", "hand")),
        payload=payload, task=task, limits=limits, family=family, ga=ga, sampling=sampling,
        control=dict(raw.get("control", {}) or {}), reported=dict(raw.get("reported", {}) or {}),
        notes=tuple(raw.get("notes", []) or []))


def _check_keys(d: dict, allowed: set, where: str) -> None:
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise QmtInputError(f"{where}: unknown key '{unknown[0]}'; allowed keys are "
                            f"{', '.join(sorted(allowed))}")


def _need(d: dict, key: str, where: str) -> Any:
    if key not in d or d[key] is None:
        raise QmtInputError(f"{where}: missing key '{key}'")
    return d[key]


def _positive(d: dict, key: str, where: str) -> float:
    v = _need(d, key, where)
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise QmtInputError(f"{where}.{key} must be a number, got {v!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise QmtInputError(f"{where}.{key} must be positive, got {v}")
    return v
