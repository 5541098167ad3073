"""Plan: what every planner returns, re-checked independently, saved and loaded again.

`make_plan` never trusts the planner's own claim: it samples the trajectory at the scenario's
check rate (10 kHz; both one-sided values at every phase boundary) with the same limit code for
every method, and `feasible`, the peaks and the ratios come from that re-check.

Files: `write_json` (atomic) holds the keys of the CLI contract plus what `load_plan` needs to
rebuild the trajectory: the genes for a family plan, 1 kHz samples (t, q, qd) for any other.
A plan loads back with the same re-check (tests/test_plan_io.py). `write_csv` writes t, q1..qn, qd1..qdn, qdd1..qddn at 1 kHz or finer.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.limits import LimitReport
from qmt_drake.sampling import piecewise_grid
from qmt_drake.scenario import Scenario, load_scenario
from qmt_drake.trajectory import FamilyTrajectory, JointTrajectory, SampledTrajectory


def recheck(scenario: Scenario, trajectory: JointTrajectory, rate_hz: float | None = None,
            valid: bool = True) -> LimitReport:
    """Limits of `trajectory` sampled at `rate_hz` (default: the scenario's check rate), every
    local maximum near a peak or a limit refined between the samples (LimitSet.report)."""
    return scenario.limit_set.report(trajectory, rate_hz or scenario.sampling.check_rate_hz, valid=valid)


@dataclass
class Plan:
    scenario: Scenario
    method: str
    trajectory: JointTrajectory
    check: LimitReport
    genes: dict | None = None
    planner_wall_s: float = 0.0
    evaluations: int = 0
    generations: int = 0
    extra: dict = field(default_factory=dict)  # planner-specific facts (history, notes, ...)

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

    def sample(self, t_s):
        return self.trajectory.sample(t_s)

    def to_piecewise_polynomial(self, rate_hz: float = 1000.0):
        return self.trajectory.to_piecewise_polynomial(rate_hz)

    def summary(self) -> dict:
        """The JSON keys of the CLI contract."""
        sc, c = self.scenario, self.check
        return {
            "scenario": sc.name,
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


def make_plan(scenario: Scenario, method: str, trajectory: JointTrajectory, *, genes=None,
              planner_wall_s=0.0, evaluations=0, generations=0, valid=True, extra=None) -> Plan:
    """Wrap a planner's trajectory into a Plan, re-checking it at the scenario's check rate."""
    return Plan(scenario=scenario, method=method, trajectory=trajectory,
                check=recheck(scenario, trajectory, valid=valid), genes=genes,
                planner_wall_s=float(planner_wall_s), evaluations=int(evaluations),
                generations=int(generations), extra=dict(extra or {}))


def family_plan(problem, genes, method: str, **kw) -> Plan:
    g = np.asarray(genes, dtype=float)
    valid = bool(problem.family.valid(g[None])[0])
    return make_plan(problem.scenario, method, FamilyTrajectory(problem.family, g),
                     genes=problem.genes_dict(g), valid=valid, **kw)


def load_plan(path: str | Path, scenario: Scenario | None = None) -> Plan:
    """Read a plan file written by `Plan.write_json`; the scenario is reloaded from the path
    stored in it unless one is given. Errors name the file and the problem."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
    except FileNotFoundError:
        raise QmtInputError(f"plan file {path} does not exist") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise QmtInputError(f"plan file {path} is not valid JSON ({exc})") from None
    if not isinstance(d, dict) or "trajectory" not in d or "scenario" not in d:
        raise QmtInputError(f"plan file {path} lacks the 'scenario' or 'trajectory' key; write it "
                            "with `qmt-drake plan ... --json PATH`")
    if scenario is None:
        src = d.get("scenario_path")
        scenario = load_scenario(src if src and Path(src).is_file() else d["scenario"])
    traj = d["trajectory"]
    try:
        if traj["kind"] == "family":
            from qmt_drake.problem import PlanningProblem
            problem = PlanningProblem(scenario)
            genes = problem.genes_vector(d["genes"])
            plan = family_plan(problem, genes, d.get("method", "loaded"))
        elif traj["kind"] == "samples":
            t, q, qd, qdd = (np.asarray(traj[k], dtype=float)
                             for k in ("t_s", "q_rad", "qd_rad_s", "qdd_rad_s2"))
            if q.ndim != 2 or not q.shape == qd.shape == qdd.shape or q.shape[0] != t.size:
                raise ValueError("t_s, q_rad, qd_rad_s and qdd_rad_s2 disagree in shape")
            traj_obj = SampledTrajectory(t, q, qd, qdd, traj.get("breakpoints_s"))
            plan = make_plan(scenario, d.get("method", "loaded"), traj_obj, genes=d.get("genes"))
        else:
            raise ValueError(f"unknown trajectory kind {traj['kind']!r}")
    except (KeyError, TypeError, ValueError) as exc:
        raise QmtInputError(f"plan file {path}: cannot rebuild its trajectory ({exc})") from None
    if plan.n_dof != scenario.arm.n_dof:
        raise QmtInputError(f"plan file {path} has {plan.n_dof} joints but scenario "
                            f"{scenario.name}'s arm has {scenario.arm.n_dof}")
    for k in ("planner_wall_s", "evaluations", "generations"):
        setattr(plan, k, d.get(k, getattr(plan, k)))
    plan.extra = d.get("extra", {})
    return plan


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write to a temporary file beside `path`, then rename: a crash never leaves half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def jsonable(x):
    """Plain JSON types for nested numpy data (non-finite floats become null)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    return x
