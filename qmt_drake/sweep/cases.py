"""Sweep cases: plain picklable data, their keys, and the worker functions that run them.

A `Case` holds only strings, numbers and dicts: the scenario (name or path) with its YAML
overrides, a reference to its plan (`plan_key`; the plan's JSON document travels beside it), and
the simulated part, magnet, motor and simulator settings. Its `key` is a SHA-256 of exactly those
inputs, so an unchanged case of a rerun maps to the stored result and is skipped. `run_case` runs
in the worker and builds its own Drake diagram there (`simulate_transfer`): nothing Drake is ever
pickled.

Physics of the uncertainty: the plan is made once for the nominal scenario; a case varies the
simulated part (PayloadSpec), not the plan. The coil current is the calibrated current of the
NOMINAL part times `coil_current_scale`: the hardware's current does not know the part's mass
(`sim.calibrated_coil_current_A` would otherwise re-calibrate it for every drawn part).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import socket
import tempfile
import time
from dataclasses import dataclass, field

import numpy as np

from qmt_drake.errors import QmtInputError, QmtSimulationError
from qmt_drake.hands import hand_plugin
from qmt_drake.outputs import jsonable
from qmt_drake.plan_files import load_plan
from qmt_drake.planners import plan_with
from qmt_drake.sim import FEEDFORWARD_OPTIONS, calibrated_coil_current_A, motor_params_for, simulate_transfer
from qmt_drake.sweep.parameters import PARAMETERS
from qmt_drake.sweep.spec import SweepSpec
from qmt_drake.systems.payload import PayloadSpec
from qmt_drake.transfer_scenario import load_scenario

CASE_SCHEMA = 1  # bump when run_case's physics changes: every stored result is then recomputed


def stable_hash(obj) -> str:
    """SHA-256 hex of the canonical JSON of obj (sorted keys, repr of floats)."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_json_default)
    return hashlib.sha256(text.encode()).hexdigest()


def _json_default(x):
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON data: {type(x).__name__}")


@dataclass
class PlanRef:
    """What makes a plan: the scenario and its planning overrides, and the method/seed/options or
    a file's content. `key` names it in the store's plans/ folder."""

    scenario: str
    overrides: dict
    method: str | None = None
    seed: int = 0
    options: dict = field(default_factory=dict)
    file: str | None = None
    file_sha256: str | None = None

    @property
    def key(self) -> str:
        d = dataclasses.asdict(self)
        d.pop("file")  # the content counts, not where it lies
        return stable_hash(d)


@dataclass
class Case:
    """One co-simulation: plain data (see the module docstring)."""

    index: int
    label: str  # the plan's label in the spec
    scenario: str
    scenario_overrides: dict
    plan_key: str
    payload: dict  # PayloadSpec field -> absolute value or ("scale", x)
    magnet: dict  # coil_current_A / coil_current_scale / effective_gap_m
    motor_scales: dict  # DcMotorParams field -> multiplier
    sim: dict  # time_scale, time_step_s, feedforward, implicit_loop_damping
    parameters: dict  # the spec's parameter values of this case (for tables and figures)
    sample: int | None = None

    @property
    def key(self) -> str:
        return stable_hash({"schema": CASE_SCHEMA, "scenario": self.scenario,
                            "overrides": self.scenario_overrides, "plan": self.plan_key,
                            "payload": self.payload, "magnet": self.magnet,
                            "motor": self.motor_scales, "sim": self.sim})

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


def build_cases(spec: SweepSpec) -> tuple[list[Case], dict[str, PlanRef]]:
    """All cases of a spec (plans x grid points x samples) and the distinct plans they need."""
    base = load_scenario(spec.scenario)  # also validates the scenario before any long work
    check_hand_can_vary(spec, base)
    samples = spec.samples()
    cases, plans = [], {}
    index = 0
    for pdef in spec.plans:
        for point in spec.grid_points():
            for i, draw in enumerate(samples):
                values = {**spec.fixed, **point, **draw}
                case, ref = _make_case(spec, base, pdef, values, index,
                                       i if spec.distributions else None)
                if ref.file is not None and ref.key not in plans:  # loaded now, on the scenario the cases plan on:
                    load_plan(ref.file, scenario=_scenario(ref.scenario, ref.overrides))  # in a worker: exit 4
                plans.setdefault(ref.key, ref)
                cases.append(case)
                index += 1
    return cases, plans


def check_hand_can_vary(spec: SweepSpec, base) -> None:
    """One-line QmtInputError when the spec varies what the scenario's hand co-simulation does not
    model (e.g. a coil current for a tray), or sets a DC-motor simulator option for it."""
    plugin = hand_plugin(base)
    kind = plugin.kind
    if "actuator" in spec.sim:
        raise QmtInputError(f"sweep sim.actuator: for spatial scenarios; scenario {base.name}'s actuator is its "
                            "YAML actuator section")
    if "integral_rate_per_s" in spec.sim:  # (sweep/spatial_cases.check_spatial_spec)
        raise QmtInputError(f"sweep sim.integral_rate_per_s: for the spatial DC-motor drive; scenario {base.name}'s "
                            "gains are its YAML control section")
    if spec.sim.get("feedforward") == "shaped":
        raise QmtInputError(f"sweep sim.feedforward shaped: the spatial DC-motor drive's closed-loop-aware reference; "
                            f"scenario {base.name} is planar: use none, back-emf or full")
    for name in (*spec.fixed, *spec.grid, *spec.distributions):
        if "planar" not in PARAMETERS[name].kinds:
            raise QmtInputError(f"sweep parameter '{name}': for spatial scenarios; the {kind} hand's co-simulation "
                                f"of scenario {base.name} does not vary it")
        if name in plugin.case_refused:
            raise QmtInputError(f"sweep parameter '{name}': the {kind} hand's co-simulation does not vary it "
                                f"(scenario {base.name})")
    if plugin.case_parameters is None:
        return
    for name in (*spec.fixed, *spec.grid, *spec.distributions):
        if name not in plugin.case_parameters:
            raise QmtInputError(f"sweep parameter '{name}': the {kind} hand's co-simulation does not vary it "
                                f"(scenario {base.name}); vary {', '.join(sorted(plugin.case_parameters))}")
    extra = sorted(k for k, v in spec.sim.items() if k != "time_step_s" and not (k == "feedforward" and v == "none"))
    if extra:
        raise QmtInputError(f"sweep sim.{extra[0]}: an option of the DC-motor co-simulation; the {kind} hand's "
                            "co-simulation takes only sim.time_step_s")


def _make_case(spec, base, pdef, values, index, sample):
    overrides, payload, magnet, motor = {}, {}, {}, {}
    sim = {"time_scale": 1.0, "feedforward": spec.sim.get("feedforward", "none")}
    for k in ("time_step_s", "implicit_loop_damping"):
        if k in spec.sim:
            sim[k] = spec.sim[k]
    seed, options = pdef.get("seed", 0), dict(pdef.get("options") or {})
    for name, v in values.items():
        p = PARAMETERS[name]
        if p.target == "payload":
            payload[p.field] = ["scale", float(v)] if p.scale else float(v)
        elif p.target == "magnet":
            magnet[name if p.scale else p.field] = float(v)
        elif p.target == "motor":
            motor[p.field] = float(v)
        elif p.target == "scenario":
            section, key = p.field.split(".")
            nominal = getattr(base, section) if section == "control" else None
            if p.scale:
                if not nominal or key not in nominal:
                    raise QmtInputError(f"parameter {name}: scenario {base.name} has no {p.field} to "
                                        "scale")
                val = [float(x) * float(v) for x in nominal[key]]
            else:
                val = float(v)
            overrides.setdefault(section, {})[key] = val
        elif p.target == "sim":
            sim[p.field] = float(v)
        elif p.target == "plan":
            if p.field == "seed":
                seed = int(v)
            else:
                options[p.field.split(".", 1)[1]] = float(v)
    if "time_scale_jitter" in sim:  # the executed timing: a further stretch of the replay
        sim["time_scale"] = sim["time_scale"] * sim.pop("time_scale_jitter")
    # Control gains act in the co-simulation only; every other override changes the plan.
    plan_overrides = {k: v for k, v in overrides.items() if k != "control"}
    if "file" in pdef:
        ref = PlanRef(spec.scenario, plan_overrides, file=pdef["file"], file_sha256=plan_file_hash(pdef["file"]))
    else:
        ref = PlanRef(spec.scenario, plan_overrides, method=pdef["method"],
                      seed=seed if pdef["method"] in ("ga", "optimum") else 0, options=options)
    case = Case(index=index, label=pdef["label"], scenario=spec.scenario, scenario_overrides=overrides,
                plan_key=ref.key, payload=payload, magnet=magnet, motor_scales=motor, sim=sim,
                parameters=dict(values), sample=sample)
    return case, ref


def plan_file_hash(path: str) -> str:
    """Hash of what defines a plan file's motion (scenario, method, genes, trajectory samples), not
    of facts that differ between identical re-plans (planner wall time, search logs in 'extra')."""
    try:
        with open(path) as fh:
            doc = json.load(fh)
    except (OSError, json.JSONDecodeError) as exc:
        raise QmtInputError(f"plan file {path} cannot be read as JSON ({exc}); write it with "
                            "`qmt-drake plan ... --json PATH`") from None
    if not isinstance(doc, dict) or "trajectory" not in doc:
        raise QmtInputError(f"plan file {path} has no 'trajectory'; write it with `qmt-drake plan ... --json PATH`")
    return stable_hash({k: doc.get(k) for k in ("scenario", "method", "genes", "trajectory")})


# ------------------------------------------------------------------------------- worker side
def make_plan_doc(ref: PlanRef) -> dict:
    """Plan once (in a worker): the plan's JSON document (Plan.to_json_dict) plus its key."""
    t0 = time.perf_counter()
    if ref.file is not None:
        with open(ref.file) as fh:
            doc = json.load(fh)
    else:
        sc = _scenario(ref.scenario, ref.overrides)
        plan = plan_with(ref.method, sc, seed=ref.seed, **ref.options)
        doc = jsonable(plan.to_json_dict())
    doc["plan_key"] = ref.key
    doc["plan_wall_s"] = time.perf_counter() - t0
    return doc


_SCENARIOS: dict = {}
_PLANS: dict = {}


def _scenario(name: str, overrides: dict):
    k = stable_hash([name, overrides])
    if k not in _SCENARIOS:
        _SCENARIOS[k] = load_scenario(name, overrides=overrides or None)
    return _SCENARIOS[k]


def plan_from_doc(doc: dict, scenario):
    """The Plan of a document written by make_plan_doc (cached per process by its key)."""
    k = doc.get("plan_key") or stable_hash(doc)
    if k not in _PLANS:
        # load_plan reads files only: one temporary file, then the same re-check as every plan.
        fd, tmp = tempfile.mkstemp(suffix=".json", prefix="qmt_plan_")
        try:
            with os.fdopen(fd, "w") as fh:
                json.dump(doc, fh)
            _PLANS[k] = load_plan(tmp, scenario=scenario)
        finally:
            os.unlink(tmp)
    return _PLANS[k]


def run_case(case: Case, plan_doc: dict) -> dict:
    """Simulate one case in this process; the result is JSON data (never raises for a failed
    simulation: status 'sim_failed' counts as not carried)."""
    t0 = time.perf_counter()
    sc = _scenario(case.scenario, case.scenario_overrides)
    plan_sc = _scenario(case.scenario, {k: v for k, v in case.scenario_overrides.items() if k != "control"})
    plan = plan_from_doc(plan_doc, plan_sc)
    plugin = hand_plugin(sc)
    if plugin.case_overrides is not None:
        return _run_hand_case(case, plan, sc, plugin, t0)
    nominal = PayloadSpec.for_scenario(sc)
    spec = dataclasses.replace(nominal, **{
        k: (getattr(nominal, k) * v[1] if isinstance(v, (list, tuple)) else v) for k, v in case.payload.items()})
    current = case.magnet.get("coil_current_A")
    if current is None:
        current = calibrated_coil_current_A(sc, nominal) * case.magnet.get("coil_current_scale", 1.0)
    sim = dict(case.sim)
    kw = dict(FEEDFORWARD_OPTIONS[sim.pop("feedforward", "none")])
    out = {"key": case.key, "index": case.index, "label": case.label, "plan_key": case.plan_key,
           "parameters": case.parameters, "sample": case.sample, "method": plan.method,
           "motion_time_s": float(plan.motion_time_s) * float(sim.get("time_scale", 1.0)),
           "plan_motion_time_s": float(plan.motion_time_s), "plan_feasible": bool(plan.feasible),
           "coil_current_A": float(current), "payload_mass_kg": spec.mass_kg,
           "payload_com_offset_m": spec.com_offset_m, "friction": spec.friction,
           "host": socket.gethostname(), "pid": os.getpid()}
    try:
        r = simulate_transfer(sc, plan, keep_series=False, payload_spec=spec, coil_current_A=current,
                              motor_params=scaled_motor_params(sc, case.motor_scales),
                              magnet_effective_gap_m=case.magnet.get("effective_gap_m"), **sim, **kw)
    except QmtSimulationError as exc:
        out.update(status="sim_failed", held=False, error=str(exc))
    else:
        d = r.summary_dict()
        out.update(status="ok", **{k: d[k] for k in (
            "held", "max_slip_m", "max_tilt_rad", "max_gap_m", "detached_at_s", "max_tracking_error_rad",
            "peak_motor_torque_ratio", "peak_moment_ratio_planned", "energy_J", "time_step_s",
            "sim_time_s", "sim_wall_s")})
    out["wall_s"] = time.perf_counter() - t0
    return out


def _run_hand_case(case: Case, plan, sc, plugin, t0: float) -> dict:
    """A case of a hand plug-in with its own case runner (the tray): the plan and the controller
    keep the nominal scenario, the drawn payload is simulated (plugin.case_overrides)."""
    drawn = plugin.case_overrides(sc, case.payload)
    overrides = {k: dict(v) for k, v in case.scenario_overrides.items()}
    for section, values in drawn.items():
        overrides.setdefault(section, {}).update(values)
    physical = _scenario(case.scenario, overrides)
    sim = dict(case.sim)
    sim.pop("feedforward", None)
    out = {"key": case.key, "index": case.index, "label": case.label, "plan_key": case.plan_key,
           "parameters": case.parameters, "sample": case.sample, "method": plan.method,
           "motion_time_s": float(plan.motion_time_s) * float(sim.get("time_scale", 1.0)),
           "plan_motion_time_s": float(plan.motion_time_s), "plan_feasible": bool(plan.feasible),
           "payload_mass_kg": physical.payload.mass_kg, "payload_com_offset_m": physical.payload.com_offset_m,
           "friction": physical.hand.friction, "host": socket.gethostname(), "pid": os.getpid()}
    try:
        d = plugin.simulate(sc, plan, physical=physical, **sim)
    except QmtSimulationError as exc:
        out.update(status="sim_failed", held=False, outcome="failed", error=str(exc))
    else:
        out.update(status="ok", **{k: d.get(k) for k in (
            "held", "outcome", "max_slip_m", "max_tilt_rad", "lost_at_s", "max_tracking_error_rad",
            "final_goal_error_rad", "time_step_s", "sim_time_s", "sim_wall_s")})
    out["wall_s"] = time.perf_counter() - t0
    return out


def scaled_motor_params(scenario, motor_scales: dict):
    """The scenario's DC motors with constants scaled (e.g. {'torque_constant_Nm_per_A': 0.5}); None
    (the scenario's own) without scales or for an ideal actuator."""
    if not motor_scales:
        return None
    mp = motor_params_for(scenario)
    return dataclasses.replace(mp, **{k: getattr(mp, k) * v for k, v in motor_scales.items()})
