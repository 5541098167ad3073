"""Loader of energy-time scenario files (`kind: energy_time`): seed 001's experiments as YAML.

The built-in ones are models/scenarios/ohsaka-fig2.yaml, -fig3, -fig4 (the one source of truth
of the experiments: experiments.py reads them); a user's own file of the same kind is loaded by
path. A transfer scenario (qmt_drake/config/scenario.py) needs a payload, moment/motor limits and a
GA family, none of which this problem has, so this kind has its own small loader here; both kinds
share the folder, the YAML reading and its errors, and are told apart by the top-level `kind`
(config.scenario.builtin_scenarios(kind)).

Schema (SI; every key below, nothing else; `#` = optional with default):

    name: str                      kind: energy_time          description, source: str (#)
    arm:        urdf: path (relative to the YAML file), tip_frame (# "tip")
    task:       coordinate_vector_m: [X1(0), X2(0), X1(T), X2(T)] (X2 up), start_posture (# lowest_cog)
    family:     kind: fourier_velocity, m: int >= 1, T_init_s (# 1.0), fixed_T_s (# none),
                moving_joints (# all; 1-based list)
    objective:  kind: energy_time, c1 > 0, c2 > 0, divisions: int >= 2 (# 40)
    limits (#): joint_torque_Nm: [n positive numbers] (the time-optimal end of the front)
    paper (#):  initial_a: [[i, j, a_ij], ...] (1-based), reported: free-form mapping

Every bad value raises QmtInputError with one line naming the file, the key and the fix, before
any computation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

from qmt_drake.config import fields as F
from qmt_drake.config.registry import FAMILIES, OBJECTIVES, for_scenario_kind
from qmt_drake.config.resolve import kind_of, resolve_scenario
from qmt_drake.config.scenario import ENERGY_TIME_KIND, SCENARIO_DIR, builtin_scenarios, read_scenario_yaml
from qmt_drake.energy.dynamics import OHSAKA_URDF, VerticalArm, ohsaka_arm
from qmt_drake.energy.experiments import Experiment
from qmt_drake.energy.kinematics import check_reachable
from qmt_drake.energy.objective import check_weights
from qmt_drake.errors import QmtInputError

KIND = ENERGY_TIME_KIND
ENERGY_SCENARIO_DIR = SCENARIO_DIR  # beside the transfer scenarios, told apart by `kind`

_KEYS = {"name", "kind", "description", "source", "arm", "task", "family", "objective", "limits", "paper"}
_SECTIONS = {
    "arm": {"urdf", "tip_frame"},
    "task": {"coordinate_vector_m", "start_posture"},
    "family": {"kind", "m", "T_init_s", "fixed_T_s", "moving_joints"},
    "objective": {"kind", "c1", "c2", "divisions"},
    "limits": {"joint_torque_Nm"},
    "paper": {"initial_a", "reported"},
}
_REQUIRED = {"arm": {"urdf"}, "task": {"coordinate_vector_m"}, "family": {"kind", "m"},
             "objective": {"kind", "c1", "c2"}}


def builtin_energy_scenarios() -> list[str]:
    return builtin_scenarios(KIND)


def resolve(name_or_path: str | Path) -> Path:
    """The YAML file of a built-in name or a path; QmtInputError if neither, or of another kind."""
    return resolve_scenario(name_or_path, KIND)


def is_energy_scenario(name_or_path) -> bool:
    """True for a built-in energy scenario name or a readable YAML file with `kind: energy_time`
    (lets `qmt-drake plan FILE` route such a file to the energy planner); never raises."""
    return kind_of(name_or_path) == KIND


def read_raw(name_or_path) -> tuple[dict, Path]:
    path = resolve(name_or_path)
    return read_scenario_yaml(path, example="ohsaka-fig3"), path


def _number(path, key, v, *, lo=None, lo_open=False, integer=False):
    """The number rule of every loader (config/fields.is_number): a finite number, not a bool, not text."""
    if not F.is_number(v) or not math.isfinite(v):
        raise QmtInputError(f"{path}: {key} = {v!r} must be a finite number{F.float_text_hint(v)}")
    if integer:
        if float(v) != int(v):
            raise QmtInputError(f"{path}: {key} = {v!r} must be an integer")
        v = int(v)
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise QmtInputError(f"{path}: {key} = {v!r} must be {'>' if lo_open else '>='} {lo}")
    return v


def _numbers(path, key, v, n=None, **kw):
    if not isinstance(v, (list, tuple)) or (n is not None and len(v) != n):
        raise QmtInputError(f"{path}: {key} must be a list of {n or 'some'} numbers, got {v!r}")
    return [_number(path, f"{key}[{k}]", x, **kw) for k, x in enumerate(v)]


def load_energy_scenario(name_or_path):
    """The Experiment (experiments.py) of a built-in name or a YAML path, every value checked."""
    raw, path = read_raw(name_or_path)
    if raw.get("kind") != KIND:
        raise QmtInputError(f"{path}: kind = {raw.get('kind')!r}; an energy scenario needs kind: {KIND} "
                            "(other scenarios go to `qmt-drake plan` without it)")
    bad = set(raw) - _KEYS
    if bad:
        raise QmtInputError(f"{path}: unknown key(s) {sorted(bad)}; allowed: {sorted(_KEYS)}")
    sec = {}
    for s, allowed in _SECTIONS.items():
        v = raw.get(s, {}) if s not in _REQUIRED else raw.get(s)
        if not isinstance(v, dict):
            raise QmtInputError(f"{path}: section '{s}' must be a mapping with keys {sorted(allowed)}")
        if set(v) - allowed:
            raise QmtInputError(f"{path}: unknown key(s) {sorted(set(v) - allowed)} in '{s}'; allowed: "
                                f"{sorted(allowed)}")
        missing = _REQUIRED.get(s, set()) - set(v)
        if missing:
            raise QmtInputError(f"{path}: '{s}' needs {sorted(missing)}")
        sec[s] = v
    # the kinds registered for energy-time scenarios (fourier.py, objective.py); one line listing them otherwise
    FAMILIES.get(sec["family"]["kind"], f"{path}: family", accept=for_scenario_kind(KIND))
    OBJECTIVES.get(sec["objective"]["kind"], f"{path}: objective", accept=for_scenario_kind(KIND))
    if sec["task"].get("start_posture", "lowest_cog") != "lowest_cog":
        raise QmtInputError(f"{path}: task.start_posture = {sec['task']['start_posture']!r}; only "
                            "lowest_cog (seed 001 step I) is implemented")
    arm = _arm(path, sec["arm"])
    n = arm.n_dof
    X = _numbers(path, "task.coordinate_vector_m", sec["task"]["coordinate_vector_m"], 4)
    fam = sec["family"]
    m = _number(path, "family.m", fam["m"], lo=1, integer=True)
    T_init = _number(path, "family.T_init_s", fam.get("T_init_s", 1.0), lo=0.0, lo_open=True)
    fixed_T = fam.get("fixed_T_s")
    fixed_T = None if fixed_T is None else _number(path, "family.fixed_T_s", fixed_T, lo=0.0, lo_open=True)
    mj = fam.get("moving_joints")
    if mj is not None:
        mj = _numbers(path, "family.moving_joints", mj, integer=True)
        if not mj or any(not 1 <= j <= n for j in mj) or len(set(mj)) != len(mj):
            raise QmtInputError(f"{path}: family.moving_joints = {mj} must be distinct joint numbers 1..{n}")
        mj = tuple(j - 1 for j in mj)
    ob = sec["objective"]
    c1 = _number(path, "objective.c1", ob["c1"])
    c2 = _number(path, "objective.c2", ob["c2"])
    div = _number(path, "objective.divisions", ob.get("divisions", 40), lo=2, integer=True)
    lim = sec["limits"].get("joint_torque_Nm")
    if lim is not None:
        lim = tuple(_numbers(path, "limits.joint_torque_Nm", lim, n, lo=0.0, lo_open=True))
    paper = sec["paper"]
    init = {}
    for k, row in enumerate(paper.get("initial_a") or []):
        i, j, a = _numbers(path, f"paper.initial_a[{k}]", row, 3)
        if float(i) != int(i) or float(j) != int(j) or not 1 <= i <= n or j < 1:
            raise QmtInputError(f"{path}: paper.initial_a[{k}] = {row}: i must be 1..{n}, j >= 1")
        init[(int(i), int(j))] = float(a)
    reported = paper.get("reported") or {}
    if not isinstance(reported, dict):
        raise QmtInputError(f"{path}: paper.reported must be a mapping")
    name = raw.get("name", path.stem)
    E = Experiment(str(name), str(raw.get("description", "")).strip(), tuple(X), c1=float(c1), c2=float(c2),
                   m=m, divisions=div, T_init_s=float(T_init), fixed_T_s=fixed_T, moving_joints=mj,
                   paper_initial_a=init, reported=reported, torque_limit_Nm=lim, arm=arm,
                   source_path=path)
    for what, fn in (("objective", lambda: check_weights(c1, c2)),
                     ("task.coordinate_vector_m", lambda: (check_reachable(arm, X[:2], "start point X(0)"),
                                                           check_reachable(arm, X[2:], "end point X(T)")))):
        try:
            fn()
        except QmtInputError as exc:
            raise QmtInputError(f"{path}: {what}: {exc}") from None
    return E


def _arm(path: Path, a: dict):
    urdf = Path(str(a["urdf"]))
    if not urdf.is_absolute():
        urdf = (path.parent / urdf).resolve()
    if not urdf.is_file():
        raise QmtInputError(f"{path}: arm.urdf {urdf} does not exist")
    tip = a.get("tip_frame", "tip")
    if tip != "tip":
        raise QmtInputError(f"{path}: arm.tip_frame = {tip!r}; the energy planner reads a URDF whose "
                            "tip point mass is the link 'tip' welded by joint 'tip_weld' "
                            "(as models/three_link_vertical_ohsaka.urdf)")
    if urdf == OHSAKA_URDF.resolve():
        return ohsaka_arm()
    try:
        arm = VerticalArm.from_urdf(urdf)
        _ = arm.chain  # the planar model must accept it (vertical plane, parallel joints)
    except QmtInputError as exc:
        raise QmtInputError(f"{path}: arm.urdf: {exc}") from None
    except Exception as exc:  # noqa: BLE001 - Drake's parser errors are multi-line
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise QmtInputError(f"{path}: arm.urdf {urdf} is not a 3-link vertical arm with a 'tip' "
                            f"link ({first})") from None
    if arm.n_dof != 3:
        raise QmtInputError(f"{path}: arm.urdf has {arm.n_dof} joints; the energy planner's start "
                            "postures and patterns are for 3 joints")
    return arm


class _Experiments(Mapping):
    """Built-in experiments by name (loaded on first use). `x in EXPERIMENTS` is also true for a
    path to a YAML file of kind energy_time, so `qmt-drake plan FILE` routes it here."""

    def __getitem__(self, name):
        if name not in builtin_energy_scenarios():
            raise KeyError(name)
        return _load(name)

    def __iter__(self):
        return iter(builtin_energy_scenarios())

    def __len__(self):
        return len(builtin_energy_scenarios())

    def __contains__(self, name) -> bool:
        return is_energy_scenario(name)


EXPERIMENTS = _Experiments()


@lru_cache(maxsize=16)
def _load(name_or_path: str) -> Experiment:
    return load_energy_scenario(name_or_path)


def get_experiment(name_or_path) -> Experiment:
    """A built-in experiment by name (ohsaka-fig2/3/4) or a user's energy scenario file by path."""
    return _load(str(resolve(name_or_path).resolve()))
