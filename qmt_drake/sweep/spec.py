"""Sweep specifications: a grid and/or a seeded Monte Carlo over named parameters of a transfer.

A spec (YAML, see models/sweeps/) names one scenario, one or more plans, and parameters:

    name: ch4-ga-mc200
    scenario: thesis-ch4                      # built-in name or a scenario YAML path
    plans:                                    # each: method (+ seed, options) or file: PLAN.json
      - {method: ga, seed: 0, options: {max_generations: 400, stall_generations: 100}}
    sim: {feedforward: none}                  # optional: feedforward, time_step_s, implicit_loop_damping
    monte_carlo: {cases: 200, seed: 1}        # needed when a parameter has a distribution
    parameters:
      friction: {dist: normal, mean: 0.3, std: 0.03}     # a distribution (Monte Carlo)
      coil_current_scale: {dist: uniform, low: 0.95, high: 1.05}
      time_scale: [1.0, 1.05]                             # a grid (list or {values: [...]})
      time_step_s: 0.002                                  # a fixed value

Cases are plans x grid points x Monte Carlo samples; the i-th sample is the same draw for every
plan and grid point (common random numbers, so plans are compared on the same parts).

Every parameter maps to exactly one place through the table `PARAMETERS` (sweep/parameters.py,
with the distributions and the value checks); this module parses a spec (scenario, plans, sim,
parameters, monte_carlo) against it. Every problem raises QmtInputError with one line naming the
key and the fix.
"""

from __future__ import annotations

import itertools
import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from qmt_drake.config.fields import check_keys, read_yaml_mapping, show
from qmt_drake.config.resolve import kind_of, refuse_scenario_file
from qmt_drake.errors import QmtInputError
from qmt_drake.planners.registry import TRANSFER, find, names
from qmt_drake.sweep.options import check_options
from qmt_drake.sweep.parameters import (
    PARAMETERS,
    check_distribution,
    check_range,
    check_values,
    integer,
    number,
)

EXPLICIT_MAX_TIME_STEP_S = 1e-3  # sim.actuation.EXPLICIT_MAX_TIME_STEP_S (a test checks they agree)
SPEC_KEYS = {"name", "description", "uncertainty", "scenario", "plan", "plans", "sim",
             "monte_carlo", "parameters"}
PLAN_KEYS = {"method", "seed", "options", "file", "label"}
SIM_KEYS = {"feedforward", "time_step_s", "implicit_loop_damping", "actuator", "integral_rate_per_s"}  # the last: spatial
ACTUATORS = ("ideal", "dc_motor")  # sim.actuator, spatial scenarios (sim/spatial_actuation.ACTUATORS)
FEEDFORWARD = ("none", "back-emf", "full", "shaped")  # sim.FEEDFORWARD_OPTIONS keys; shaped: spatial only
MAX_CASES = 1_000_000  # beyond any budget (budgets.py): refused before the grid is built


@dataclass
class SweepSpec:
    name: str
    scenario: str
    plans: list[dict]
    sim: dict
    fixed: dict  # name -> value
    grid: dict  # name -> list of values
    distributions: dict  # name -> Distribution
    mc_cases: int = 0
    mc_seed: int = 0
    description: str = ""
    uncertainty: str = ""
    source_path: Path | None = None
    raw: dict = field(default_factory=dict)

    @property
    def parameter_names(self) -> list[str]:
        return list(self.fixed) + list(self.grid) + list(self.distributions)

    def samples(self) -> list[dict]:
        """The Monte Carlo draws (one dict per sample; [{}] without distributions)."""
        if not self.distributions:
            return [{}]
        # One generator per parameter, seeded by (seed, name): the first N draws do not depend on
        # the other parameters or on the number of cases, so a larger run extends a smaller one
        # and reuses its stored cases.
        cols = {k: d.sample(np.random.default_rng([self.mc_seed, zlib.crc32(k.encode())]), self.mc_cases,
                            PARAMETERS[k]) for k, d in self.distributions.items()}
        return [{k: _plain(v[i]) for k, v in cols.items()} for i in range(self.mc_cases)]

    def grid_points(self) -> list[dict]:
        keys = list(self.grid)
        return [dict(zip(keys, combo)) for combo in itertools.product(*(self.grid[k] for k in keys))]

    @property
    def n_cases(self) -> int:
        """plans x grid points x samples, counted without building the grid."""
        return len(self.plans) * math.prod(len(v) for v in self.grid.values()) * max(self.mc_cases, 1)


def _plain(v):
    return int(v) if isinstance(v, (np.integer, int)) else float(v)


def load_spec(path_or_dict, *, name: str | None = None) -> SweepSpec:
    """A validated SweepSpec from a YAML file path or a mapping (errors: QmtInputError)."""
    if isinstance(path_or_dict, dict):
        raw, where, path = path_or_dict, f"sweep spec '{name or path_or_dict.get('name', '?')}'", None
    else:
        path = Path(path_or_dict)
        where = str(path)
        if not path.is_file():
            raise QmtInputError(f"sweep spec {path} does not exist; give the path of a YAML file "
                                "(examples in models/sweeps/)")
        raw = read_yaml_mapping(path, "sweep spec", example="models/sweeps/tiny-ch4.yaml")
    return spec_from_dict(raw, where, path, name)


def spec_from_dict(raw: dict, where: str, path: Path | None = None, name: str | None = None) -> SweepSpec:
    refuse_scenario_file(raw, where, "a sweep spec", "a spec names its scenario (scenario: PATH) with plans and "
                         "parameters (models/sweeps/*.yaml)")
    _check_keys(raw, SPEC_KEYS, where)
    scenario = raw.get("scenario")
    if not isinstance(scenario, str) or not scenario:
        raise QmtInputError(f"{where}: 'scenario' must name a built-in scenario or a scenario YAML path")
    if path is not None and not Path(scenario).is_absolute() and Path(scenario).suffix:
        beside = path.parent / scenario
        if beside.is_file():
            scenario = str(beside.resolve())
    sweep_name = str(name or raw.get("name") or (path.stem if path else "sweep"))
    if not sweep_name.replace("-", "").replace("_", "").replace(".", "").isalnum():
        raise QmtInputError(f"{where}: name '{sweep_name}' must be letters, digits, '-', '_' or '.' "
                            "(it names the output folder)")

    if ("plan" in raw) == ("plans" in raw):
        raise QmtInputError(f"{where}: give exactly one of 'plan' (a mapping) or 'plans' (a list)")
    plans = [raw["plan"]] if "plan" in raw else raw["plans"]
    if not isinstance(plans, list) or not plans:
        raise QmtInputError(f"{where}: 'plans' must be a non-empty list of plan mappings")
    kind = kind_of(scenario) or TRANSFER  # the planner registry's rows of this kind plan it
    plans = [_check_plan(p, f"{where}: plans[{i}]", path, kind) for i, p in enumerate(plans)]
    labels = [p["label"] for p in plans]
    if len(set(labels)) != len(labels):
        raise QmtInputError(f"{where}: two plans share the label '{_first_dup(labels)}'; give each "
                            "a distinct 'label'")

    sim = raw.get("sim") or {}
    if not isinstance(sim, dict):
        raise QmtInputError(f"{where}: 'sim' must be a mapping of {', '.join(sorted(SIM_KEYS))}")
    _check_keys(sim, SIM_KEYS, f"{where}: sim")
    sim = dict(sim)
    if sim.setdefault("feedforward", "none") not in FEEDFORWARD:
        raise QmtInputError(f"{where}: sim.feedforward must be one of {', '.join(FEEDFORWARD)}, "
                            f"got {sim['feedforward']!r}")
    if sim.get("actuator", "ideal") not in ACTUATORS:
        raise QmtInputError(f"{where}: sim.actuator must be one of {', '.join(ACTUATORS)}, got {show(sim['actuator'])}")
    if "time_step_s" in sim:
        sim["time_step_s"] = number(sim["time_step_s"], f"{where}: sim.time_step_s", positive=True)
        check_range(sim["time_step_s"], PARAMETERS["time_step_s"], f"{where}: sim.time_step_s")
    if not isinstance(sim.get("implicit_loop_damping", True), bool):
        raise QmtInputError(f"{where}: sim.implicit_loop_damping must be true or false, got "
                            f"{show(sim['implicit_loop_damping'])}")
    for k in ("description", "uncertainty"):
        if raw.get(k) is not None and not isinstance(raw[k], str):
            raise QmtInputError(f"{where}: '{k}' must be a string, got {show(raw[k])}")

    params = raw.get("parameters") or {}
    if not isinstance(params, dict):
        raise QmtInputError(f"{where}: 'parameters' must map parameter names to a value, a list "
                            "of values or a distribution")
    fixed, grid, dists = {}, {}, {}
    fields_used = {}
    for pname, v in params.items():
        at = f"{where}: parameters.{pname}"
        if pname not in PARAMETERS:
            raise QmtInputError(f"{at}: unknown parameter '{pname}'; known parameters are "
                                f"{', '.join(PARAMETERS)}")
        p = PARAMETERS[pname]
        slot = (p.target, p.field)
        if slot in fields_used:
            raise QmtInputError(f"{at}: sets the same quantity as '{fields_used[slot]}'; keep one")
        fields_used[slot] = pname
        if isinstance(v, dict) and "dist" in v:
            dists[pname] = check_distribution(v, p, at)
        elif isinstance(v, dict) and set(v) == {"values"}:
            grid[pname] = check_values(v["values"], p, at)
        elif isinstance(v, dict):
            raise QmtInputError(f"{at}: a mapping must be a distribution ({{dist: normal, mean: .., "
                                "std: ..}}) or {values: [...]}")
        elif isinstance(v, list):
            grid[pname] = check_values(v, p, at)
        else:
            fixed[pname] = check_values([v], p, at)[0]
    if sim.get("implicit_loop_damping") is False:
        steps = [sim.get("time_step_s", 0.0), fixed.get("time_step_s", 0.0), *grid.get("time_step_s", [])]
        if max(steps) > EXPLICIT_MAX_TIME_STEP_S or ("time_step_s" in dists):
            raise QmtInputError(f"{where}: sim.implicit_loop_damping false steps the motor loop explicitly, "
                                f"known unstable above {EXPLICIT_MAX_TIME_STEP_S * 1e3:g} ms; use time_step_s "
                                f"<= {EXPLICIT_MAX_TIME_STEP_S:g} (fixed or a list) or drop implicit_loop_damping")
    if "time_step_s" in sim and "time_step_s" in params:
        raise QmtInputError(f"{where}: time_step_s is given both in sim and in parameters; keep one")

    mc = raw.get("monte_carlo")
    mc_cases, mc_seed = 0, 0
    if dists:
        if not isinstance(mc, dict) or "cases" not in mc:
            raise QmtInputError(f"{where}: parameters {', '.join(dists)} have distributions; add "
                                "monte_carlo: {cases: N, seed: S}")
        _check_keys(mc, {"cases", "seed"}, f"{where}: monte_carlo")
        mc_cases = integer(mc["cases"], f"{where}: monte_carlo.cases", minimum=1)
        mc_seed = integer(mc.get("seed", 0), f"{where}: monte_carlo.seed", minimum=0)
    elif mc is not None:
        raise QmtInputError(f"{where}: monte_carlo is given but no parameter has a distribution; "
                            "give one (e.g. friction: {dist: normal, mean: 0.3, std: 0.03}) or "
                            "drop monte_carlo")
    spec = SweepSpec(name=sweep_name, scenario=scenario, plans=plans, sim=sim, fixed=fixed, grid=grid,
                     distributions=dists, mc_cases=mc_cases, mc_seed=mc_seed,
                     description=str(raw.get("description", "")),
                     uncertainty=str(raw.get("uncertainty", "")), source_path=path, raw=raw)
    if spec.n_cases > MAX_CASES:
        raise QmtInputError(f"{where}: {spec.n_cases} cases is too many (at most {MAX_CASES}); narrow the "
                            "grid or lower monte_carlo.cases")
    return spec


def describe_uncertainty(spec: SweepSpec) -> str:
    """One line stating the distributions (and fixed values) the cases were drawn from."""
    parts = []
    for k, d in spec.distributions.items():
        a = d.args
        if d.kind == "uniform":
            parts.append(f"{k} ~ U[{a['low']:g}, {a['high']:g}]")
        else:
            lo, hi = a.get("low"), a.get("high")
            cut = "" if lo is None and hi is None else f" cut to [{lo:g}, {hi:g}]"
            parts.append(f"{k} ~ N({a['mean']:g}, {a['std']:g}^2){cut}")
    parts += [f"{k} = {v:g}" for k, v in spec.fixed.items()]
    return "; ".join(parts) if parts else "none (nominal)"


# ------------------------------------------------------------------------------------ checks
def _check_plan(p, at: str, spec_path: Path | None, kind: str = TRANSFER) -> dict:
    if not isinstance(p, dict):
        raise QmtInputError(f"{at}: a plan must be a mapping with 'method' (+ seed, options) or 'file'")
    _check_keys(p, PLAN_KEYS, at)
    out = {"options": {}, "seed": 0}
    if ("method" in p) == ("file" in p):
        raise QmtInputError(f"{at}: give exactly one of 'method' ({', '.join(names(kind))}) or 'file'")
    if "label" in p and (not isinstance(p["label"], (str, int)) or isinstance(p["label"], bool)
                         or not str(p["label"]).strip()):
        raise QmtInputError(f"{at}.label must be a non-empty string, got {show(p['label'])}")
    if "file" in p:
        if not isinstance(p["file"], str) or not p["file"].strip() or "\0" in p["file"]:
            raise QmtInputError(f"{at}.file must be the path of a plan JSON file, got {show(p['file'])}")
        if p.get("options") is not None:
            raise QmtInputError(f"{at}: options are for a 'method'; a plan 'file' is used as written")
        f = Path(str(p["file"]))
        if not f.is_absolute() and spec_path is not None and (spec_path.parent / f).is_file():
            f = spec_path.parent / f
        if not f.is_file():
            raise QmtInputError(f"{at}: plan file {f} does not exist; write one with "
                                "`qmt-drake plan ... --json PATH`")
        out["file"] = str(f.resolve())
        out["label"] = str(p.get("label", f.stem))
        return out
    out["method"] = find(kind, p["method"], f"{at}: method").name
    out["seed"] = integer(p.get("seed", 0), f"{at}.seed", minimum=0)
    out["options"] = check_options(p.get("options"), out["method"], at, kind)
    default = out["method"] + (f"-seed{out['seed']}" if out["method"] == "ga" else "")
    out["label"] = str(p.get("label", default))
    return out


_check_keys = check_keys


def _first_dup(xs):
    seen = set()
    for x in xs:
        if x in seen:
            return x
        seen.add(x)
