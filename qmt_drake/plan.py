"""Plan: what every planner returns, re-checked independently, saved and loaded again.

`make_plan` never trusts the planner's own claim: it samples the trajectory at the scenario's
check rate (10 kHz; both one-sided values at every phase boundary) with the same limit code for
every method, and `feasible`, the peaks and the ratios come from that re-check.

Files: `write_json` (atomic) holds the keys of the CLI contract plus what `load_plan` (plan_files.py) needs to
rebuild the trajectory: the genes for a family plan, 1 kHz samples (t, q, qd) for any other, and
what it needs to recognise its scenario: the task points, the joint count and the scenario's
fingerprint. A plan loads back with the same re-check (tests/test_plan_io.py), and only against a
scenario it fits (`load_plan`: same joint count and task points, family genes within the family's
bounds, a sampled plan that starts and ends on the task's start and goal; one-line QmtInputError).

`write_csv` writes t, q1..qn, qd1..qdn, qdd1..qddn at 1 kHz or finer.

One Plan type for every scenario kind: a transfer plan is a `Plan`; a spatial (3-D) plan
(planners/spatial_plan_io.SpatialPlan) and an energy-time plan (energy/energy_plan.EnergyPlan) are
subclasses with the same surface (motion_time_s, sample, feasible, check, summary, to_json_dict,
write_json, write_csv), each file carrying its `scenario_kind`. `load_plan(path)` reads any of
them: it dispatches on that field to the loader the kind registered (`register_plan_kind`), and a
file given with a scenario of another kind is refused in one line.
"""

from __future__ import annotations

import json
import pickle
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np
import numpy.typing as npt
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.config.scenario import Scenario
from qmt_drake.families import make_family
from qmt_drake.limits import LimitReport
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.plan_identity import IDENTITY_KEY, identity, transfer_sections
from qmt_drake.problem import PlanningProblem
from qmt_drake.sampling import piecewise_grid
from qmt_drake.trajectory import FamilyTrajectory, JointTrajectory, SampledTrajectory


def recheck(scenario: Scenario, trajectory: JointTrajectory, rate_hz: float | None = None,
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


@dataclass
class Plan:
    """A planned motion of one scenario, re-checked by sampling: `motion_time_s` [s], `sample(t)` ->
    (q [rad], qd [rad/s], qdd [rad/s^2]), `feasible` and `check` (the re-check's LimitReport, its
    peak_ratios: every limit's peak / limit), `summary()` (the CLI's JSON keys), `write_json` /
    `write_csv`, and `load_plan` to read a file back. Transfer scenarios give a Plan; spatial and
    energy-time scenarios give its subclasses (module docstring), whose `scenario` is their kind's."""

    scenario: Scenario
    method: str
    trajectory: JointTrajectory
    check: LimitReport
    genes: dict | None = None
    planner_wall_s: float = 0.0
    evaluations: int = 0
    generations: int = 0
    extra: dict = field(default_factory=dict)  # planner-specific facts (history, notes, ...)
    scenario_kind: ClassVar[str] = TRANSFER_PLAN_KIND

    @property
    def feasible(self) -> bool:
        return self.check.feasible

    @property
    def motion_time_s(self) -> float:
        return self.trajectory.duration_s

    @property
    def n_dof(self) -> int:
        return self.trajectory.n_dof

    @property
    def peak_moment_ratio(self) -> float:
        return self.check.peak_moment_ratio

    def sample(self, t_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.trajectory.sample(t_s)

    def to_piecewise_polynomial(self, rate_hz: float = 1000.0) -> PiecewisePolynomial:
        return self.trajectory.to_piecewise_polynomial(rate_hz)

    def summary(self) -> dict:
        """The JSON keys of the CLI contract."""
        sc, c = self.scenario, self.check
        return {
            "scenario": sc.name,
            "scenario_kind": self.scenario_kind,
            "method": self.method,
            "feasible": c.feasible,
            "motion_time_s": self.motion_time_s,
            "genes": self.genes,
            "peak_moment_Nm": c.peak_moment_Nm,
            "moment_limit_Nm": c.moment_limit_Nm,
            "peak_moment_ratio": c.peak_moment_ratio,
            "peak_moment_time_s": c.peak_moment_time_s,
            "peak_motor_torque_Nm": c.peak_motor_torque_Nm,
            "motor_torque_limit_Nm": c.motor_torque_limit_Nm,
            "peak_motor_torque_ratio": c.peak_motor_torque_ratio,
            "joint_range_ok": c.joint_range_ok,
            "peak_ratios": dict(c.peak_ratios),  # every ratio limit term's peak / limit, by name
            "check_rate_hz": c.rate_hz,
            "payload_mass_kg": sc.payload.mass_kg,
            "payload_com_offset_m": sc.payload.com_offset_m,
            "link_lengths_m": sc.arm.link_lengths_m.tolist(),
            "planner_wall_s": self.planner_wall_s,
            "evaluations": self.evaluations,
            "generations": self.generations,
        }

    def to_json_dict(self) -> dict:
        d = self.summary()
        d["scenario_path"] = str(self.scenario.source_path)
        d["scenario_fingerprint"] = self.scenario.fingerprint()
        d[IDENTITY_KEY] = identity(transfer_sections(self.scenario))  # plan_files.load_plan compares it
        d["task_points_m"] = np.asarray(self.scenario.task.points_m, float).tolist()
        d["n_dof"] = int(self.n_dof)
        d["extra"] = jsonable(self.extra)
        if isinstance(self.trajectory, FamilyTrajectory):
            d["trajectory"] = {"kind": "family", "family": self.scenario.family.kind}
        else:
            # 1 kHz samples per piece, each phase boundary twice (left and right values).
            grid = piecewise_grid(self.trajectory.breakpoints_s[None, :], 1000.0)
            q, qd, qdd = self.trajectory.evaluate(grid.t_s, grid.t_piece_s)
            d["trajectory"] = {"kind": "samples", "t_s": grid.t_s.tolist(), "q_rad": q.tolist(),
                               "qd_rad_s": qd.tolist(), "qdd_rad_s2": qdd.tolist(),
                               "breakpoints_s": self.trajectory.breakpoints_s.tolist()}
        return d

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
        write_text_atomic(path, json.dumps(self.to_json_dict(), indent=1))

    def write_csv(self, path: str | Path, rate_hz: float = 1000.0) -> None:
        t = np.union1d(np.arange(0.0, self.motion_time_s, 1.0 / rate_hz), [self.motion_time_s])
        q, qd, qdd = self.sample(t)
        n = self.n_dof
        header = ",".join(["t"] + [f"q{i+1}" for i in range(n)] + [f"qd{i+1}" for i in range(n)]
                          + [f"qdd{i+1}" for i in range(n)])
        rows = np.column_stack([t, q, qd, qdd])
        lines = [header] + [",".join(f"{v:.10g}" for v in r) for r in rows]
        write_text_atomic(path, "\n".join(lines) + "\n")


def make_plan(scenario: Scenario, method: str, trajectory: JointTrajectory, *, genes: dict | None = None,
              planner_wall_s: float = 0.0, evaluations: int = 0, generations: int = 0, valid: bool = True,
              extra: dict | None = None) -> Plan:
    """Wrap a planner's trajectory into a Plan, re-checking it at the scenario's check rate."""
    return Plan(scenario=scenario, method=method, trajectory=trajectory,
                check=recheck(scenario, trajectory, valid=valid), genes=genes,
                planner_wall_s=float(planner_wall_s), evaluations=int(evaluations),
                generations=int(generations), extra=dict(extra or {}))


def family_plan(problem: PlanningProblem, genes: npt.ArrayLike, method: str, **kw: Any) -> Plan:
    g = np.asarray(genes, dtype=float)
    valid = bool(problem.family.valid(g[None])[0])
    return make_plan(problem.scenario, method, FamilyTrajectory(problem.family, g),
                     genes=problem.genes_dict(g), valid=valid, **kw)


# A sampled plan must start and end on the task's first and last points to this tolerance [m].
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
