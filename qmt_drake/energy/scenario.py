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

from collections.abc import Mapping
from functools import lru_cache
from pathlib import Path

from qmt_drake.config import fields as F
from qmt_drake.config.registry import FAMILIES, OBJECTIVES, for_scenario_kind
from qmt_drake.config.resolve import kind_of, resolve_scenario
from qmt_drake.config.scenario import ENERGY_TIME_KIND, SCENARIO_DIR, builtin_scenarios, read_scenario_yaml
from qmt_drake.config.simulation import parse_simulation
from qmt_drake.energy.dynamics import OHSAKA_URDF, VerticalArm, ohsaka_arm
from qmt_drake.energy.experiments import EnergyScenarioData, Experiment
from qmt_drake.energy.kinematics import check_reachable
from qmt_drake.energy.objective import check_weights
from qmt_drake.errors import QmtInputError

KIND = ENERGY_TIME_KIND
ENERGY_SCENARIO_DIR = SCENARIO_DIR  # beside the transfer scenarios, told apart by `kind`

_KEYS = {"name", "kind", "description", "source", "arm", "task", "family", "objective", "limits", "paper", "simulation"}
# the vertical arm touches nothing: simulation.plant's contact fields have nothing to act on
NO_CONTACT = "the vertical arm makes no contact (its tip mass is welded to the last link): the field has nothing to act on"
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


def load_energy_data(name_or_path, overrides: dict | None = None) -> EnergyScenarioData:
    """The plain data (energy/experiments.EnergyScenarioData) of a built-in name or a YAML path, `overrides`
    merged into its YAML first (config/fields.merge_overrides): every value checked through
    config/fields.py (one line naming `file: section.key`)."""
    raw, path = read_raw(name_or_path)
    if overrides:
        raw = F.merge_overrides(raw, overrides)
    where = str(path)
    if raw.get("kind") != KIND:
        raise QmtInputError(f"{path}: kind = {raw.get('kind')!r}; an energy scenario needs kind: {KIND} "
                            "(other scenarios go to `qmt-drake plan` without it)")
    F.check_keys(raw, _KEYS, where)
    sec = {}
    for s, allowed in _SECTIONS.items():
        sec[s] = F.mapping(raw, s, where) if s in _REQUIRED else F.mapping(raw, s, where, default={})
        F.check_keys(sec[s], allowed, f"{where}: {s}")
        for key in sorted(_REQUIRED.get(s, ())):
            F.need(sec[s], key, f"{where}: {s}")
    # the kinds registered for energy-time scenarios (fourier.py, objective.py); one line listing them otherwise
    FAMILIES.get(F.string(sec["family"], "kind", f"{where}: family"), f"{path}: family", accept=for_scenario_kind(KIND))
    OBJECTIVES.get(F.string(sec["objective"], "kind", f"{where}: objective"), f"{path}: objective",
                   accept=for_scenario_kind(KIND))
    task, fam, ob, w = sec["task"], sec["family"], sec["objective"], f"{where}: task"
    if F.string(task, "start_posture", w, default="lowest_cog") != "lowest_cog":
        raise QmtInputError(f"{path}: task.start_posture = {task['start_posture']!r}; only "
                            "lowest_cog (seed 001 step I) is implemented")
    urdf = _urdf(path, sec["arm"])
    # numbers are kept as written (an int stays an int) where a plan's identity hashes them (plan_identity.py)
    F.vector(task, "coordinate_vector_m", w, length=4, what="X1(0), X2(0), X1(T), X2(T) [m]")
    X = tuple(task["coordinate_vector_m"])
    w = f"{where}: family"
    m = F.integer(fam, "m", w, minimum=1)
    T_init = F.num(fam, "T_init_s", w, positive=True, default=1.0)
    fixed_T = fam["fixed_T_s"] if F.num(fam, "fixed_T_s", w, positive=True, default=None) is not None else None
    mj = fam.get("moving_joints")
    if mj is not None:
        mj = tuple(F.integers(fam, "moving_joints", w, minimum=1, distinct=True, what="joint numbers from 1"))
    w = f"{where}: objective"
    c1, c2 = F.num(ob, "c1", w), F.num(ob, "c2", w)
    div = F.integer(ob, "divisions", w, minimum=2, default=40)
    lim = None
    if sec["limits"].get("joint_torque_Nm") is not None:
        F.vector(sec["limits"], "joint_torque_Nm", f"{where}: limits", positive=True, what="joint torque limits [N*m]")
        lim = tuple(sec["limits"]["joint_torque_Nm"])
    w = f"{where}: paper"
    init = {}
    for k, row in enumerate(F.sequence(sec["paper"], "initial_a", w, default=[])):
        key = f"initial_a[{k}]"
        i, j, a = F.vector({key: row}, key, w, length=3, what="i, j, a_ij (i, j from 1)")
        if float(i) != int(i) or float(j) != int(j) or i < 1 or j < 1:
            raise QmtInputError(f"{w}.{key} = {row}: i and j must be integers from 1")
        init[(int(i), int(j))] = float(a)
    reported = F.mapping(sec["paper"], "reported", w, default={})
    return EnergyScenarioData(F.string(raw, "name", where, default=path.stem), str(raw.get("description", "")).strip(), X,
                              c1=c1, c2=c2, m=m, divisions=div, T_init_s=T_init, fixed_T_s=fixed_T, moving_joints=mj,
                              paper_initial_a=init, reported=reported, torque_limit_Nm=lim, urdf=urdf,
                              source_path=path, simulation=parse_simulation(raw.get("simulation"), where,
                                                                            no_contact=NO_CONTACT))


def load_energy_scenario(name_or_path, overrides: dict | None = None) -> Experiment:
    """The Experiment (experiments.py) of a built-in name or a YAML path (`overrides` merged into its YAML
    first), every value checked."""
    return build_experiment(load_energy_data(name_or_path, overrides))


def build_experiment(data: EnergyScenarioData) -> Experiment:
    """The Experiment of the plain data: the arm read from its URDF and the checks that need it (one value
    per joint, joint numbers within the arm, both task points within reach, the weights)."""
    path = data.source_path
    arm = _arm(path, data.urdf)
    n = arm.n_dof
    mj = data.moving_joints
    if mj is not None:
        if any(j > n for j in mj):
            raise QmtInputError(f"{path}: family.moving_joints = {list(mj)} must be distinct joint numbers 1..{n}")
        mj = tuple(j - 1 for j in mj)
    if data.torque_limit_Nm is not None:
        F.vector({"joint_torque_Nm": list(data.torque_limit_Nm)}, "joint_torque_Nm", f"{path}: limits", positive=True,
                 length=n, what="joint torque limits [N*m], one per joint")
    for i, _ in data.paper_initial_a:
        if i > n:
            raise QmtInputError(f"{path}: paper.initial_a: i = {i} must be 1..{n} (a joint of the arm)")
    X = data.coordinate_vector_m
    E = Experiment(data.name, data.description, X, c1=data.c1, c2=data.c2, m=data.m, divisions=data.divisions,
                   T_init_s=data.T_init_s, fixed_T_s=data.fixed_T_s, moving_joints=mj,
                   paper_initial_a=dict(data.paper_initial_a), reported=data.reported,
                   torque_limit_Nm=data.torque_limit_Nm, arm=arm, source_path=path, simulation=data.simulation)
    for what, fn in (("objective", lambda: check_weights(data.c1, data.c2)),
                     ("task.coordinate_vector_m", lambda: (check_reachable(arm, X[:2], "start point X(0)"),
                                                           check_reachable(arm, X[2:], "end point X(T)")))):
        try:
            fn()
        except QmtInputError as exc:
            raise QmtInputError(f"{path}: {what}: {exc}") from None
    return E


def _urdf(path: Path, a: dict) -> Path:
    """arm.urdf (relative to the file) that exists, with the tip link the planner reads."""
    where = f"{path}: arm"
    urdf = Path(F.string(a, "urdf", where))
    if not urdf.is_absolute():
        urdf = (path.parent / urdf).resolve()
    if not urdf.is_file():
        raise QmtInputError(f"{where}.urdf {urdf} does not exist")
    tip = a.get("tip_frame", "tip")
    if tip != "tip":
        raise QmtInputError(f"{where}.tip_frame = {tip!r}; the energy planner reads a URDF whose "
                            "tip point mass is the link 'tip' welded by joint 'tip_weld' "
                            "(as models/three_link_vertical_ohsaka.urdf)")
    return urdf


def _arm(path: Path, urdf: Path):
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
