"""Plan: what every planner returns, re-checked independently, saved and loaded again.

ONE Plan type for every scenario kind (transfer, spatial_transfer, energy_time): scenario identity
(`scenario`, `scenario_kind`), method, trajectory, the limit report (`check`), the planner's
bookkeeping (genes, planner_wall_s, evaluations, generations, extra) and the kind's own facts as
DATA (`facts`: a spatial plan's pose times, hold scale and re-check; an energy-time plan's problem,
cost and optima; none for a transfer plan), readable as attributes (`plan.hold_scale`). What differs
by kind is a `PlanKind` (below): small functions registered by kind, not subclasses: how the kind
reports its summary, writes its file and CSV, judges `feasible` and rebuilds a file
(plan_files.load_plan dispatches on the file's `scenario_kind`).

`make_plan` never trusts the planner's own claim: it samples the trajectory at the scenario's
check rate (10 kHz; both one-sided values at every phase boundary) with the same limit code for
every method, and `feasible`, the peaks and the ratios come from that re-check.

The plan file (`write_json`, atomic), one schema for every kind: the common keys `scenario`,
`scenario_kind`, `method`, `feasible`, `motion_time_s`, `scenario_path`, `scenario_identity`
(plan_identity.py), `n_dof` and `trajectory` (samples to plot, or what rebuilds it), then the kind's
facts block, written flat beside them so that every file written so far reads back unchanged: a
transfer plan's limit peaks, genes, task points and fingerprint (1 kHz samples or the family's genes
rebuild it); a spatial plan's (planners/spatial_plan_io.py); an energy-time plan's
(energy/energy_plan.py). A plan loads back with the same re-check (tests/test_plan_io.py), and only
against a scenario it fits (plan_files.load_plan; one-line QmtInputError).

`write_csv` writes t, q1..qn, qd1..qdn, qdd1..qddn at 1 kHz or finer (the kind's columns and units).
"""

from __future__ import annotations

import dataclasses
import importlib
import json
import pickle
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.api_checks import number, path_arg, times
from qmt_drake.config.registry import check_registration
from qmt_drake.errors import QmtInputError
from qmt_drake.families import make_family
from qmt_drake.limits import LimitReport
from qmt_drake.outputs import write_text_atomic
from qmt_drake.problem import PlanningProblem
from qmt_drake.sampling import piecewise_grid
from qmt_drake.trajectory import FamilyTrajectory, JointTrajectory, SampledTrajectory
from qmt_drake.transfer_scenario import TransferScenario


def recheck(scenario: TransferScenario, trajectory: JointTrajectory, rate_hz: float | None = None,
            valid: bool = True) -> LimitReport:
    """Limits of `trajectory` sampled at `rate_hz` (default: the scenario's check rate), every
    local maximum near a peak or a limit refined between the samples (LimitSet.report)."""
    report: LimitReport = scenario.limit_set.report(trajectory, rate_hz or scenario.sampling.check_rate_hz,
                                                    valid=valid)
    return report


class Motion(Protocol):
    """What check_plan_fits and the co-simulations need of a plan: its duration [s] and its samples
    (q [rad], qd [rad/s], qdd [rad/s^2]) at times [s]. A Plan is one."""

    @property
    def motion_time_s(self) -> float: ...

    def sample(self, t_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


# The `scenario_kind` of each plan file; transfer files written before the field existed have none,
# energy-time files written before it say `kind: energy_time`.
TRANSFER_PLAN_KIND = "transfer"
SPATIAL_PLAN_KIND = "spatial_transfer"
ENERGY_PLAN_KIND = "energy_time"
KIND_WORDS = {TRANSFER_PLAN_KIND: "planar", SPATIAL_PLAN_KIND: "spatial (3-D)", ENERGY_PLAN_KIND: "energy-time"}


def a_kind(kind: str) -> str:
    """'a planar', 'a spatial (3-D)', 'an energy-time': a kind's words for one-line messages."""
    word = KIND_WORDS.get(kind, kind)
    return ("an " if word[:1] in "aeiou" else "a ") + word


def plan_file_kind(d: dict) -> str:
    """The scenario kind of a plan file's mapping (files older than `scenario_kind` included)."""
    kind = d.get("scenario_kind") or (ENERGY_PLAN_KIND if d.get("kind") == ENERGY_PLAN_KIND else TRANSFER_PLAN_KIND)
    return str(kind)


def plan_file_words(d: dict, wanted_kind: str) -> str:
    """'a planar plan', ...: a file's kind for a one-line refusal by a scenario of `wanted_kind`; a file
    without `scenario_kind` (planar files written before the field, or a file edited by hand) is not
    called planar: the line says the field is missing and which value that scenario's files carry."""
    if "scenario_kind" in d or d.get("kind") == ENERGY_PLAN_KIND:
        return f"{a_kind(plan_file_kind(d))} plan"
    return (f"a plan without scenario_kind (edited by hand? {a_kind(wanted_kind)} scenario's plans have "
            f"scenario_kind: {wanted_kind})")


def check_plan_file_kind(d: dict, path: str | Path, wanted_kind: str, scenario_name: str) -> None:
    """One line (QmtInputError) when a plan file's mapping is of another scenario kind than the scenario
    `scenario_name` (of `wanted_kind`) it is loaded on: every kind's loader refuses it in these words."""
    if plan_file_kind(d) != wanted_kind:
        raise QmtInputError(f"plan file {path} is {plan_file_words(d, wanted_kind)} for scenario {d.get('scenario')}, "
                            f"not one for the {KIND_WORDS.get(wanted_kind, wanted_kind)} scenario {scenario_name}; "
                            f"plan it with `qmt-drake plan {scenario_name} --json PATH`")


@dataclass(eq=False)
class Plan:
    """A planned motion of one scenario, of any kind, re-checked by sampling: `motion_time_s` [s],
    `sample(t)` -> (q [rad], qd [rad/s], qdd [rad/s^2]), `feasible` and `check` (the re-check's
    LimitReport, its peak_ratios: every limit's peak / limit), `summary()` (the CLI's JSON keys),
    `write_json` / `write_csv`, and plan_files.load_plan to read a file back. `scenario` is the kind's
    scenario (config Scenario, SpatialScenario, Experiment); `facts` the kind's own data (module
    docstring), each also an attribute (plan.facts["hold_scale"] is plan.hold_scale)."""

    scenario: Any
    method: str
    trajectory: JointTrajectory
    check: LimitReport
    genes: dict | None = None
    planner_wall_s: float = 0.0
    evaluations: int = 0
    generations: int = 0
    extra: dict = field(default_factory=dict)  # planner-specific facts (history, notes, ...)
    scenario_kind: str = TRANSFER_PLAN_KIND
    facts: dict = field(default_factory=dict)  # the kind's facts (module docstring)

    def __getattr__(self, name: str) -> Any:
        # only for names that are not fields or properties: the kind's facts
        facts = self.__dict__.get("facts")
        if facts is not None and not name.startswith("__") and name in facts:
            return facts[name]
        raise AttributeError(f"{a_kind(self.__dict__.get('scenario_kind', '?'))} plan has no attribute {name!r}")

    @property
    def kind(self) -> PlanKind:
        return plan_kind(self.scenario_kind)

    @property
    def feasible(self) -> bool:
        return self.kind.feasible(self)

    @property
    def motion_time_s(self) -> float:
        return float(self.trajectory.duration_s)

    @property
    def duration_s(self) -> float:
        return self.motion_time_s

    @property
    def planning_s(self) -> float:
        return self.planner_wall_s

    @property
    def info(self) -> dict:
        return self.extra

    @property
    def n_dof(self) -> int:
        return self.kind.n_dof(self)

    @property
    def peak_moment_ratio(self) -> float:
        return self.check.peak_moment_ratio

    def sample(self, t_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q [rad], qd [rad/s], qdd [rad/s^2]) at the times t_s [s] (finite numbers: a NaN would reach a
        Drake assertion that ends the process; one QmtInputError line instead)."""
        return self.trajectory.sample(times(t_s, "Plan.sample: t_s"))

    def to_piecewise_polynomial(self, rate_hz: float = 1000.0) -> PiecewisePolynomial:
        return self.kind.to_piecewise_polynomial(self, rate_hz)

    def summary(self) -> dict:
        """The JSON keys of the CLI contract: the common ones and the kind's (no other kind's)."""
        return self.kind.summary(self)

    def to_json_dict(self) -> dict:
        """The plan file's mapping (module docstring)."""
        return self.kind.file_dict(self)

    def replace(self, **changes: Any) -> Plan:
        """A copy with fields and facts changed (dataclasses.replace for the one Plan: a name that is
        not a field must be one of the kind's facts)."""
        names = {f.name for f in dataclasses.fields(self)}
        facts = {k: v for k, v in changes.items() if k not in names}
        unknown = sorted(set(facts) - set(self.facts))
        if unknown:
            raise TypeError(f"{a_kind(self.scenario_kind)} plan has no field or fact {unknown[0]!r}")
        fields_ = {k: v for k, v in changes.items() if k in names}
        return dataclasses.replace(self, **fields_, facts={**fields_.get("facts", self.facts), **facts})

    # Pickling (sweeps ship plans to worker processes): the trajectory may hold Drake objects
    # (a family's arm, a planner's closures). A family plan travels as its genes and is rebuilt
    # from the scenario's family; another trajectory travels as itself if it pickles, else as the
    # samples a plan file stores (1 kHz per piece, both values at each boundary, quintic Hermite
    # in between). The re-check travels unchanged.
    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        traj = self.trajectory
        if isinstance(traj, FamilyTrajectory):
            state["trajectory"] = ("family", np.asarray(traj.genes[0], float))
        else:
            try:
                pickle.dumps(traj)
            except Exception:  # noqa: BLE001 - any unpicklable part: fall back to samples
                grid = piecewise_grid(traj.breakpoints_s[None, :], 1000.0)
                q, qd, qdd = traj.evaluate(grid.t_s, grid.t_piece_s)
                state["trajectory"] = ("samples", grid.t_s, q, qd, qdd, np.asarray(traj.breakpoints_s))
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        traj = state["trajectory"]
        if isinstance(traj, tuple) and traj and traj[0] == "family":
            state["trajectory"] = FamilyTrajectory(make_family(state["scenario"]), traj[1])
        elif isinstance(traj, tuple) and traj and traj[0] == "samples":
            state["trajectory"] = SampledTrajectory(*traj[1:])
        self.__dict__.update(state)

    def write_json(self, path: str | Path) -> None:
        """The plan file (module docstring), atomically; a kind may prove its rebuild first (spatial)."""
        path = path_arg(path, "write_json: path", "JSON file")
        write_text_atomic(path, json.dumps(self.to_json_dict(), indent=self.kind.json_indent) + "\n")

    def write_csv(self, path: str | Path, rate_hz: float = 1000.0) -> None:
        check_csv_args(path, rate_hz, self.motion_time_s)
        self.kind.write_csv(self, path, rate_hz)


# A kind's plan-file loader: (path, the file's mapping, the scenario or None) -> Plan of that kind.
PlanLoader = Callable[[Path, dict, Any], Plan]


def _check_feasible(plan: Plan) -> bool:
    return bool(plan.check.feasible)


def _trajectory_n_dof(plan: Plan) -> int:
    return int(plan.trajectory.n_dof)


def _trajectory_pp(plan: Plan, rate_hz: float) -> PiecewisePolynomial:
    return plan.trajectory.to_piecewise_polynomial(rate_hz)


@dataclass(frozen=True)
class PlanKind:
    """What one scenario kind adds to the one Plan, as functions of the plan (no subclass):
    scenario_type (what load_scenario returns for the kind), summary (the CLI's keys), file_dict (the
    plan file's mapping), write_csv(plan, path, rate_hz), feasible, n_dof, to_piecewise_polynomial,
    json_indent (None: compact, for files of many samples) and load (plan_files.load_plan's rebuild
    of a file: (path, mapping, scenario or None) -> Plan)."""

    scenario_type: type
    load: PlanLoader
    summary: Callable[[Plan], dict]
    file_dict: Callable[[Plan], dict]
    write_csv: Callable[[Plan, Any, float], None]
    feasible: Callable[[Plan], bool] = _check_feasible
    n_dof: Callable[[Plan], int] = _trajectory_n_dof
    to_piecewise_polynomial: Callable[[Plan, float], PiecewisePolynomial] = _trajectory_pp
    json_indent: int | None = 1


# Each scenario kind registers once, in the module that knows its files: transfer in plan_files.py,
# spatial in planners/spatial_plan_io.py, energy-time in energy/energy_plan.py. A kind not registered
# yet is imported by that module's name the first time it is asked for (as config/registry does): a
# plan unpickled in a sweep's worker, or made by a planner alone, finds its kind whatever was imported.
PLAN_KINDS: dict[str, PlanKind] = {}
KIND_MODULES = {TRANSFER_PLAN_KIND: "qmt_drake.plan_files",
                SPATIAL_PLAN_KIND: "qmt_drake.planners.spatial_plan_io",
                ENERGY_PLAN_KIND: "qmt_drake.energy.energy_plan"}


def register_plan_kind(kind: str, scenario_type: type, load: PlanLoader, *, replace: bool = False,
                       **behaviour: Any) -> None:
    """A scenario kind's plans: its scenario class, its plan-file loader and its PlanKind functions
    (keyword arguments: summary, file_dict and write_csv required, the others optional). A kind
    registers once (replace=True to swap it)."""
    check_registration("plan kind", kind, kind in PLAN_KINDS, replace)
    if not isinstance(scenario_type, type) or not callable(load):
        raise QmtInputError(f"plan kind {kind!r}: give the scenario's class and a loader load(path, mapping, "
                            "scenario) -> Plan")
    try:
        PLAN_KINDS[kind] = PlanKind(scenario_type=scenario_type, load=load, **behaviour)
    except TypeError as exc:
        raise QmtInputError(f"plan kind {kind!r}: {exc}; give summary, file_dict and write_csv") from None


def plan_kind(kind: str) -> PlanKind:
    """The registered PlanKind of `kind` (its module imported by name on first use); one line naming
    the known kinds otherwise."""
    if kind not in PLAN_KINDS and kind in KIND_MODULES:
        importlib.import_module(KIND_MODULES[kind])
    try:
        return PLAN_KINDS[kind]
    except KeyError:
        raise QmtInputError(f"scenario_kind {kind!r} has no registered plan kind; known: "
                            f"{', '.join({**KIND_MODULES, **PLAN_KINDS})}") from None


# A CSV row per sample: more than this many rows is a budget question, not a trajectory file (10^7 rows of
# a 7-joint arm's 22 columns are ~2 GB of text)
CSV_MAX_ROWS = 10 ** 7


def check_csv_args(path: Any, rate_hz: Any, motion_time_s: float) -> None:
    """write_csv's arguments (every plan kind's): a path, and a finite positive rate whose rows stay
    under CSV_MAX_ROWS."""
    path_arg(path, "write_csv: path", "CSV file")
    number(rate_hz, "write_csv: rate_hz", positive=True, fix="samples per second [Hz], e.g. 1000")
    if rate_hz * motion_time_s > CSV_MAX_ROWS:
        raise QmtInputError(f"write_csv: rate_hz {rate_hz:g} gives {rate_hz * motion_time_s:.3g} rows over "
                            f"{motion_time_s:g} s, over {CSV_MAX_ROWS:.0e}; lower the rate (1000 Hz is the default)")


def make_plan(scenario: TransferScenario, method: str, trajectory: JointTrajectory, *, genes: dict | None = None,
              planner_wall_s: float = 0.0, evaluations: int = 0, generations: int = 0, valid: bool = True,
              extra: dict | None = None) -> Plan:
    """Wrap a planner's trajectory into a transfer scenario's Plan, re-checking it at the scenario's
    check rate."""
    return Plan(scenario=scenario, method=method, trajectory=trajectory,
                check=recheck(scenario, trajectory, valid=valid), genes=genes,
                planner_wall_s=float(planner_wall_s), evaluations=int(evaluations),
                generations=int(generations), extra=dict(extra or {}), scenario_kind=TRANSFER_PLAN_KIND)


def family_plan(problem: PlanningProblem, genes: npt.ArrayLike, method: str, **kw: Any) -> Plan:
    g = np.asarray(genes, dtype=float)
    valid = bool(problem.family.valid(g[None])[0])
    return make_plan(problem.scenario, method, FamilyTrajectory(problem.family, g),
                     genes=problem.genes_dict(g), valid=valid, **kw)


def ratio_report(rate_hz: float, motion_time_s: float, peak_ratios: dict[str, float],
                 feasible: bool | None = None) -> LimitReport:
    """The LimitReport of a plan whose limits are ratio terms only (a spatial arm's joint speed,
    acceleration, torque and hand terms; an energy-time plan has none): peak_ratios name -> peak /
    limit, feasible (default: every ratio <= 1). The planar magnet's own fields (moment, per-motor
    torque) do not apply and are nan / empty."""
    ratios = {k: float(v) for k, v in peak_ratios.items()}
    ok = all(v <= 1.0 for v in ratios.values()) if feasible is None else bool(feasible)
    nan = float("nan")
    return LimitReport(rate_hz=float(rate_hz), motion_time_s=float(motion_time_s), peak_moment_Nm=nan,
                       moment_limit_Nm=None, peak_moment_ratio=nan, peak_moment_time_s=None,
                       peak_motor_torque_Nm=[], motor_torque_limit_Nm=[], peak_motor_torque_ratio=nan,
                       joint_range_ok=True, feasible=ok, peak_ratios=ratios)
