"""Plan files read back: `load_plan(path[, scenario])` for every scenario kind, the library's guard
against running a plan made for another scenario (`check_plan_fits`), and the transfer kind of the
one Plan (plan.PlanKind: its summary, file and CSV, registered here with its loader).

Each scenario kind registers its PlanKind once (plan.register_plan_kind): transfer here, spatial in
planners/spatial_plan_io.py, energy-time in energy/energy_plan.py. `load_plan` reads the file's
`scenario_kind` and hands it to that kind's loader; a file given with a scenario of another kind, or
of another scenario of the same kind, is refused in one line. A transfer plan must fit its scenario:
the same joint count and task points, family genes within the family's bounds, a sampled plan that
starts and ends on the task's start and goal.

A transfer plan's facts block (flat beside the common keys, plan.py's docstring): genes, the magnet's
limit peaks (moment, motor torque, joint range), payload, link lengths, planner bookkeeping, the
scenario's fingerprint, task points, `extra`, and `trajectory`: {kind: family, family} (the genes
rebuild it) or {kind: samples, t_s, q_rad, qd_rad_s, qdd_rad_s2, breakpoints_s} (1 kHz per piece, both
values at each phase boundary). A sampled plan whose trajectory has an exact file form (`rebuild_spec`: the
planar Ruckig plan's Ruckig inputs, trajopt's B-spline, TOPP-RA's path and profile, Drake Toppra's
q(s) and s(t), a Drake PiecewisePolynomial's coefficients (collocation), their slow-down factor
and segments) also has `rebuild`, and is loaded from
that: the same trajectory bit for bit, so it re-checks at the same value (the quintic between the samples is
~1e-8 rad/s^2 off, enough to move a plan at 0.999999999 of its limit past 1). Its samples stay (to plot, and
the loader refuses a file whose `rebuild` disagrees with them by more than REBUILD_TOL).
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.plan import (
    ENERGY_PLAN_KIND,
    KIND_MODULES,
    PLAN_KINDS,
    TRANSFER_PLAN_KIND,
    Motion,
    Plan,
    PlanKind,
    PlanLoader,
    check_plan_file_kind,
    family_plan,
    make_plan,
    plan_file_kind,
    plan_file_words,
    plan_kind,
    register_plan_kind,
)
from qmt_drake.plan_identity import IDENTITY_KEY, check_identity, identity, transfer_sections
from qmt_drake.problem import PlanningProblem
from qmt_drake.sampling import piecewise_grid
from qmt_drake.trajectory import (
    ConcatenatedTrajectory,
    FamilyTrajectory,
    JointTrajectory,
    PolynomialTrajectory,
    SampledTrajectory,
    TimeScaledTrajectory,
    polynomial_from_spec,
)
from qmt_drake.transfer_scenario import TransferScenario, load_scenario

__all__ = ["PLAN_KINDS", "Motion", "PlanKind", "PlanLoader", "check_plan_fits", "load_plan", "plan_file_kind",
           "plan_file_words", "read_plan_file", "register_plan_kind", "scenario_kind_of"]

PLAN_ENDPOINT_TOL_M = 1e-6
REBUILD_TOL = 1e-9  # rad, rad/s, rad/s^2: a `rebuild` against the samples written with it (only rounding differs)

# Leaf kinds of `rebuild` (module docstring), each registered by the module that knows its trajectory and imported
# by that name on first use (as plan.plan_kind does for the scenario kinds: that module imports this one).
REBUILD_MODULES = {"ruckig": "qmt_drake.planners.baselines.ruckig_plan", "bspline": "qmt_drake.planners.baselines.trajopt_plan",
                   "path_timing": "qmt_drake.planners.baselines.paths",
                   "drake_timed": "qmt_drake.planners.baselines.toppra_plan", "filtered_toppra": "qmt_drake.jerk_filter"}
REBUILDERS: dict[str, Callable[[dict, Any], JointTrajectory]] = {}


def register_rebuild(kind: str, rebuild: Callable[[dict, Any], JointTrajectory]) -> None:
    """rebuild(spec, scenario) -> the trajectory whose `file_spec()` gave spec (spec["kind"] == kind)."""
    REBUILDERS[kind] = rebuild


def rebuild_spec(traj: JointTrajectory) -> dict | None:
    """The exact file form of a transfer trajectory: time scaling and segments around leaves that have a
    `file_spec()`; None when a part has none (then only its samples are stored)."""
    if isinstance(traj, TimeScaledTrajectory):
        inner = rebuild_spec(traj.inner)
        return None if inner is None else {"kind": "time_scaled", "k": traj.factor, "inner": inner}
    if isinstance(traj, ConcatenatedTrajectory):
        parts = [rebuild_spec(p) for p in traj.parts]
        return None if any(p is None for p in parts) else {"kind": "sequence", "parts": parts}
    spec = getattr(traj, "file_spec", None)
    return spec() if callable(spec) else None


def trajectory_from_rebuild(spec: dict, scenario: TransferScenario) -> JointTrajectory:
    """The trajectory a `rebuild` dict describes; ValueError/KeyError/TypeError/RuntimeError if malformed."""
    kind = spec["kind"]
    if kind == "time_scaled":
        k = float(spec["k"])
        if not (np.isfinite(k) and k > 0):
            raise ValueError("'k' must be a positive number")
        return TimeScaledTrajectory(trajectory_from_rebuild(spec["inner"], scenario), k)
    if kind == "sequence":
        return ConcatenatedTrajectory([trajectory_from_rebuild(p, scenario) for p in spec["parts"]])
    if kind == "polynomial":
        return PolynomialTrajectory(polynomial_from_spec(spec["pp"]), np.asarray(spec["breakpoints_s"], dtype=float),
                                    holds_end_value=bool(spec["holds_end_value"]))
    if kind not in REBUILDERS and kind in REBUILD_MODULES:
        importlib.import_module(REBUILD_MODULES[kind])
    if kind not in REBUILDERS:
        raise ValueError(f"unknown rebuild kind {kind!r}")
    return REBUILDERS[kind](spec, scenario)


def read_plan_file(path: str | Path) -> dict:
    """The JSON mapping of a plan file (any scenario kind) with 'scenario' and 'trajectory' keys;
    one-line QmtInputError naming the file otherwise."""
    path = Path(path)
    if path.is_dir():
        raise QmtInputError(f"plan file {path} is a directory; give the JSON file written by "
                            "`qmt-drake plan ... --json PATH`")
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise QmtInputError(f"plan file {path} does not exist") from None
    except OSError as exc:
        raise QmtInputError(f"plan file {path} cannot be read ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise QmtInputError(f"plan file {path} is not a UTF-8 JSON text file") from None
    except json.JSONDecodeError as exc:
        raise QmtInputError(f"plan file {path} is not valid JSON ({exc})") from None
    legacy_energy = isinstance(d, dict) and d.get("kind") == ENERGY_PLAN_KIND  # before `trajectory` was written
    if not isinstance(d, dict) or "scenario" not in d or not (isinstance(d.get("trajectory"), dict) or legacy_energy):
        raise QmtInputError(f"plan file {path} lacks the 'scenario' or 'trajectory' key; write it "
                            "with `qmt-drake plan ... --json PATH`")
    bad = [k for k in ("scenario", "method") if k in d and not (isinstance(d[k], str) and d[k].strip())]
    if bad:  # names every summary line prints ("ur5-suction-bins 5 x1: carried")
        raise QmtInputError(f"plan file {path}: its {bad[0]} {d[bad[0]]!r} is not a name (edited by hand?); write it again")
    return d


def scenario_kind_of(scenario: Any) -> str:
    """The kind of a scenario object (transfer, spatial_transfer, energy_time); QmtInputError if it is
    none that load_scenario returns."""
    for kind in dict.fromkeys([*PLAN_KINDS, *KIND_MODULES]):  # registered first: no import for those
        if isinstance(scenario, plan_kind(kind).scenario_type):
            return kind
    raise QmtInputError(f"{type(scenario).__name__} is not a scenario; load one with qmt_drake.load_scenario")


def load_plan(path: str | Path, scenario: Any = None) -> Plan:
    """Read a plan file of any scenario kind (written by `Plan.write_json` or `qmt-drake plan --json`);
    the scenario is reloaded from the file unless one is given. The plan must fit the scenario: a
    file of another scenario kind, or of another scenario of the same kind, is refused with one
    line naming the file (QmtInputError). Returns the one Plan type (of the file's kind), re-checked on
    the scenario."""
    path = Path(path)
    d = read_plan_file(path)
    kind = plan_file_kind(d)
    if kind not in PLAN_KINDS and kind not in KIND_MODULES:
        raise QmtInputError(f"plan file {path} has scenario_kind {kind!r}; known: "
                            f"{', '.join({**KIND_MODULES, **PLAN_KINDS})}")
    if scenario is not None:
        check_plan_file_kind(d, path, scenario_kind_of(scenario), getattr(scenario, "name", "?"))
    return plan_kind(kind).load(path, d, scenario)


def _load_transfer_plan(path: Path, d: dict, scenario: TransferScenario | None) -> Plan:
    """A transfer plan file against its scenario (module docstring)."""
    if scenario is None:
        src = d.get("scenario_path")
        scenario = load_scenario(src if isinstance(src, str) and Path(src).is_file() else str(d["scenario"]))
    _check_plan_fits(d, path, scenario)
    traj = d["trajectory"]
    why = d.get("extra", {}).get("infeasible") if isinstance(d.get("extra"), dict) else None
    if why and d.get("motion_time_s") == 0.0:  # `plan` wrote the arm at rest: its method found no timing
        raise QmtInputError(f"plan file {path} holds no motion: its planner found no timing ({why}); change the "
                            "scenario's limits and plan again")
    try:
        if traj.get("kind") == "family":
            if traj.get("family", scenario.family.kind) != scenario.family.kind:
                raise QmtInputError(f"plan file {path} is a {traj.get('family')} plan but scenario "
                                    f"{scenario.name} uses family {scenario.family.kind}; plan again "
                                    "for this scenario")
            problem = PlanningProblem(scenario)
            if not isinstance(d.get("genes"), dict):
                raise ValueError("'genes' must map gene names to values")
            genes = problem.genes_vector(d["genes"])
            _check_genes(genes, scenario, path)
            plan = family_plan(problem, genes, str(d.get("method", "loaded")))
        elif traj.get("kind") == "samples":
            t, q, qd, qdd = (np.asarray(traj[k], dtype=float)
                             for k in ("t_s", "q_rad", "qd_rad_s", "qdd_rad_s2"))
            if q.ndim != 2 or not q.shape == qd.shape == qdd.shape or q.shape[0] != t.size:
                raise ValueError("t_s, q_rad, qd_rad_s and qdd_rad_s2 disagree in shape")
            if t.size < 2 or not all(np.all(np.isfinite(a)) for a in (t, q, qd, qdd)) \
                    or np.any(np.diff(t) < 0) or t[0] != 0.0 or not t[-1] > 0:
                raise ValueError("samples must be finite with t_s rising from 0 to a positive motion time")
            if q.shape[1] != scenario.arm.n_dof:
                raise QmtInputError(f"plan file {path} has {q.shape[1]} joints but scenario "
                                    f"{scenario.name}'s arm has {scenario.arm.n_dof}; plan again for it")
            _check_endpoints(q[0], q[-1], scenario, f"plan file {path}")
            traj_obj: JointTrajectory = SampledTrajectory(t, q, qd, qdd, traj.get("breakpoints_s"))
            if "rebuild" in d:  # the exact form (module docstring), held to its samples
                traj_obj = _rebuilt(d["rebuild"], scenario, (t, q, qd, qdd), path)
            plan = make_plan(scenario, str(d.get("method", "loaded")), traj_obj, genes=d.get("genes"))
        else:
            raise ValueError(f"unknown trajectory kind {traj.get('kind')!r}")
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, QmtInputError):
            raise
        raise QmtInputError(f"plan file {path}: cannot rebuild its trajectory ({exc})") from None
    if plan.n_dof != scenario.arm.n_dof:
        raise QmtInputError(f"plan file {path} has {plan.n_dof} joints but scenario "
                            f"{scenario.name}'s arm has {scenario.arm.n_dof}")
    # After the checks that name one misfit (joints, task points, genes, start and goal): any other
    # difference of content (limits, payload, hand, ...) refuses it too, whatever the names say.
    check_identity(d, path, transfer_sections(scenario), scenario.name)
    for k in ("planner_wall_s", "evaluations", "generations"):
        v = d.get(k, getattr(plan, k))
        setattr(plan, k, v if isinstance(v, (int, float)) and not isinstance(v, bool) else getattr(plan, k))
    plan.extra = d.get("extra", {}) if isinstance(d.get("extra", {}), dict) else {}
    return plan



def _check_plan_fits(d: dict, path: Path, scenario: TransferScenario) -> None:
    """What the file says about its scenario against the one it is run with (files written
    before these keys existed skip the checks they lack)."""
    n = d.get("n_dof")
    if n is not None and n != scenario.arm.n_dof:
        raise QmtInputError(f"plan file {path} has {n} joints but scenario {scenario.name}'s arm has "
                            f"{scenario.arm.n_dof}; plan again for this scenario")
    pts = d.get("task_points_m")
    if pts is not None:
        try:
            pts = np.asarray(pts, dtype=float)
        except (TypeError, ValueError):
            raise QmtInputError(f"plan file {path}: task_points_m is not a list of points") from None
        mine = np.asarray(scenario.task.points_m, float)
        if pts.shape != mine.shape or not np.allclose(pts, mine, rtol=0.0, atol=1e-12):
            raise QmtInputError(f"plan file {path} was made for task points {pts.tolist()} but scenario "
                                f"{scenario.name} has {mine.tolist()}; plan again for this scenario")


def _check_genes(genes: np.ndarray, scenario: TransferScenario, path: Path) -> None:
    lo, hi = scenario.family.gene_bounds[:, 0], scenario.family.gene_bounds[:, 1]
    for name, g, a, b in zip(scenario.family.gene_names, genes, lo, hi):
        if not np.isfinite(g) or g < a * (1 - 1e-12) or g > b * (1 + 1e-12):
            raise QmtInputError(f"plan file {path}: gene {name} = {g:g} lies outside the family's bounds "
                                f"[{a:g}, {b:g}] of scenario {scenario.name}; plan again or widen "
                                f"family.genes.{name}")


def _check_endpoints(q_start: np.ndarray, q_end: np.ndarray, scenario: TransferScenario, path: Path | str) -> None:
    arm = scenario.arm
    ends = arm.tip_position(np.stack([q_start, q_end]))
    want = np.asarray(scenario.task.points_m, float)[[0, -1]]
    err = np.linalg.norm(np.asarray(ends)[:, :2] - want, axis=1)
    if np.any(err > PLAN_ENDPOINT_TOL_M):
        raise QmtInputError(f"{path} starts/ends {err[0] * 1e3:.3g}/{err[1] * 1e3:.3g} mm away from "
                            f"scenario {scenario.name}'s start and goal points; plan again for this scenario")


def check_plan_fits(plan: Motion, scenario: TransferScenario) -> None:
    """One-line QmtInputError unless `plan` (anything with n_dof, motion_time_s and sample) has the
    scenario's joint count and starts and ends within PLAN_ENDPOINT_TOL_M of its task's start and
    goal points: the library's own guard against running a plan made for another scenario."""
    n = int(getattr(plan, "n_dof", scenario.arm.n_dof))
    if n != scenario.arm.n_dof:
        raise QmtInputError(f"the plan has {n} joints but scenario {scenario.name}'s arm has "
                            f"{scenario.arm.n_dof}; plan again for this scenario")
    q = plan.sample(np.array([0.0, float(plan.motion_time_s)]))[0]
    _check_endpoints(q[0], q[-1], scenario, f"the {getattr(plan, 'method', '')} plan".replace("the  ", "the "))


# --- the transfer kind of the one Plan ----------------------------------------------------------------

def transfer_summary(plan: Plan) -> dict:
    """A transfer plan's CLI keys: the common ones and the magnet's limit peaks."""
    sc, c = plan.scenario, plan.check
    return {
        "scenario": sc.name,
        "scenario_kind": plan.scenario_kind,
        "method": plan.method,
        "feasible": c.feasible,
        "motion_time_s": plan.motion_time_s,
        "genes": plan.genes,
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
        "planner_wall_s": plan.planner_wall_s,
        "evaluations": plan.evaluations,
        "generations": plan.generations,
    }


def transfer_file_dict(plan: Plan) -> dict:
    """A transfer plan file's mapping (module docstring)."""
    d = transfer_summary(plan)
    d["scenario_path"] = str(plan.scenario.source_path)
    d["scenario_fingerprint"] = plan.scenario.fingerprint()
    d[IDENTITY_KEY] = identity(transfer_sections(plan.scenario))  # load_plan compares it
    d["task_points_m"] = np.asarray(plan.scenario.task.points_m, float).tolist()
    d["n_dof"] = int(plan.n_dof)
    d["extra"] = jsonable(plan.extra)
    if isinstance(plan.trajectory, FamilyTrajectory):
        d["trajectory"] = {"kind": "family", "family": plan.scenario.family.kind}
    else:
        t, q, qd, qdd = _file_samples(plan.trajectory)
        d["trajectory"] = {"kind": "samples", "t_s": t.tolist(), "q_rad": q.tolist(),
                           "qd_rad_s": qd.tolist(), "qdd_rad_s2": qdd.tolist(),
                           "breakpoints_s": plan.trajectory.breakpoints_s.tolist()}
        spec = rebuild_spec(plan.trajectory)
        if spec is not None:
            spec = jsonable(spec)
            err = _difference(_file_samples(trajectory_from_rebuild(json.loads(json.dumps(spec)), plan.scenario)),
                              (t, q, qd, qdd))
            if not err <= REBUILD_TOL:
                raise RuntimeError(f"the {plan.method} plan's file form does not rebuild it (difference {err:.3g}); a bug")
            d["rebuild"] = spec
    return d


def _file_samples(traj: JointTrajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """t, q, qd, qdd of a transfer file: 1 kHz samples per piece, each phase boundary twice (left and right)."""
    grid = piecewise_grid(traj.breakpoints_s[None, :], 1000.0)
    q, qd, qdd = traj.evaluate(grid.t_s, grid.t_piece_s)
    return grid.t_s, _boundary_values(grid.t_s, q), _boundary_values(grid.t_s, qd), qdd


def _difference(a: tuple, b: tuple) -> float:
    """Largest |difference| of two (t, q, qd, qdd); inf if their shapes differ."""
    if any(np.shape(x) != np.shape(y) for x, y in zip(a, b)):
        return float("inf")
    return max(float(np.max(np.abs(np.asarray(x) - np.asarray(y)), initial=0.0)) for x, y in zip(a, b))


def _rebuilt(spec: dict, scenario: TransferScenario, samples: tuple, path: Path) -> JointTrajectory:
    """A file's `rebuild` trajectory, refused in one line if it disagrees with the file's own samples."""
    if not isinstance(spec, dict):
        raise ValueError("'rebuild' must be a mapping")
    try:
        traj = trajectory_from_rebuild(spec, scenario)
    except RuntimeError as exc:  # Ruckig refusing the stored inputs
        raise ValueError(str(exc)) from None
    err = _difference(_file_samples(traj), samples)
    if not err <= REBUILD_TOL:
        raise QmtInputError(f"plan file {path}: its 'rebuild' disagrees with its samples (by {err:.3g}); "
                            f"write it again with `qmt-drake plan {scenario.name} --json PATH`")
    return traj


def _boundary_values(t_s: np.ndarray, x: np.ndarray) -> np.ndarray:
    """x (a continuous q or qd) with each breakpoint's two stored values (its left and right piece's, each
    evaluated ONE_SIDED_S inside its piece) replaced by their mean: the value AT the breakpoint to second order
    in that inset. A 1e-9 s inset moves q by qd * 1e-9, which the quintic between 1 ms samples turns into
    ~1e-2 rad/s^2 of acceleration near the breakpoint; qdd keeps its two sides (a jump survives)."""
    x = np.array(x, dtype=float)
    i = np.flatnonzero(np.diff(t_s) == 0.0)
    x[i] = x[i + 1] = 0.5 * (x[i] + x[i + 1])
    return x


def transfer_csv(plan: Plan, path: Any, rate_hz: float) -> None:
    """t, q1..qn, qd1..qdn, qdd1..qddn at rate_hz and the end time (rad, rad/s, rad/s^2)."""
    t = np.union1d(np.arange(0.0, plan.motion_time_s, 1.0 / rate_hz), [plan.motion_time_s])
    q, qd, qdd = plan.sample(t)
    n = plan.n_dof
    header = ",".join(["t"] + [f"q{i+1}" for i in range(n)] + [f"qd{i+1}" for i in range(n)]
                      + [f"qdd{i+1}" for i in range(n)])
    rows = np.column_stack([t, q, qd, qdd])
    lines = [header] + [",".join(f"{v:.10g}" for v in r) for r in rows]
    write_text_atomic(path, "\n".join(lines) + "\n")


register_plan_kind(TRANSFER_PLAN_KIND, TransferScenario, _load_transfer_plan, summary=transfer_summary,
                   file_dict=transfer_file_dict, write_csv=transfer_csv)
