"""The one planner registry: every method of every scenario kind, one table, one `plan`.

    plan(scenario, "ga", seed=0, generations=20)    # a Plan of the scenario's kind

`METHODS` is the table: one row per method and scenario kind it plans (a method that plans several
kinds, e.g. "ga" on transfer and spatial scenarios, has one row per kind, each with its own function
and options). A row names the method, its aliases, the kind, the function (`module:function`,
imported when first used, so the table itself loads no planner and no Drake), the function whose
keywords are the method's options (typed by their defaults, ranged by api_checks.OPTION_RANGES), the
keywords that are not options, which of plan()'s own arguments (seed, progress, the method's name) the
function takes, option names that mean one of its keywords (the CLI's --generations is the transfer
GA's max_generations), and options it refuses with the reason.

`check(kind, method, options)` refuses, in one QmtInputError line before any work: a method the kind
does not plan (naming the methods it takes), an option the row does not take (naming the closest
and the ones it takes), a value of the wrong type or out of range. `plan` checks, then calls the row's
function. `register_method` adds a user's method (replace=True swaps a built-in one).

Kinds: "transfer" (config.scenario.Scenario: the thesis arms, the tray), "spatial_transfer"
(spatial_task.SpatialScenario: UR5, Panda), "energy_time" (energy.experiments.Experiment, seed 001).
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from functools import partial
from typing import Any

from qmt_drake.api_checks import OPTION_RANGES, REAL_RANGES, _closest, number, option_value
from qmt_drake.config.fields import show
from qmt_drake.config.registry import check_registration
from qmt_drake.errors import QmtInputError
from qmt_drake.plan_files import scenario_kind_of

TRANSFER, SPATIAL, ENERGY = "transfer", "spatial_transfer", "energy_time"
KINDS = (TRANSFER, SPATIAL, ENERGY)
_WORDS = {TRANSFER: "planar", SPATIAL: "spatial (3-D)", ENERGY: "energy-time"}
Progress = Callable[[str], None] | None


@dataclass(frozen=True)
class Method:
    """One method on one scenario kind (module docstring). `run` is called as
    run(scenario, **{seed, progress, method as `passes` says}, **options)."""

    name: str
    kind: str
    run: str | Callable[..., Any]
    summary: str = ""
    aliases: tuple[str, ...] = ()
    options_of: str | Callable[..., Any] | None = None
    internal: tuple[str, ...] = ()
    passes: tuple[str, ...] = ()
    renamed: dict[str, str] = field(default_factory=dict)
    refused: dict[str, str] = field(default_factory=dict)

    @property
    def function(self) -> Callable[..., Any]:
        return _resolve(self.run)

    @property
    def open_options(self) -> bool:
        """The function takes **options (a registered planner): any keyword is passed on."""
        sig = inspect.signature(_resolve(self.options_of or self.run))
        return any(p.kind is p.VAR_KEYWORD for p in sig.parameters.values())

    def options(self) -> dict[str, dict]:
        """The typed options: {name: {'type', 'default', 'range' (min, max) or None}} from the
        signature of `options_of` (or `run`), minus the internal keywords."""
        sig = inspect.signature(_resolve(self.options_of or self.run))
        out = {}
        for k, p in sig.parameters.items():
            if k in self.internal or k in self.passes or p.kind not in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD):
                continue
            d = None if p.default is inspect.Parameter.empty else p.default
            lim = OPTION_RANGES.get(k) or REAL_RANGES.get(k)
            typ = p.annotation if isinstance(p.annotation, str) else getattr(p.annotation, "__name__", "")
            out[k] = {"type": typ or (type(d).__name__ if d is not None else "any"), "default": d,
                      "range": None if lim is None else (lim[0], lim[1])}
        return out


def _resolve(target: str | Callable[..., Any]) -> Callable[..., Any]:
    """'package.module:function' -> the function (its module imported now), a function -> itself."""
    if callable(target):
        return target
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


_T, _S = "qmt_drake.planners.transfer", "qmt_drake.planners.spatial_methods"
_GA_REFUSED = {"population": "the transfer GA's population is the scenario's ga.population; set it there "
                             "(the API: overrides={'ga': {'population': N}})"}
_XFER = "qmt_drake.energy.as_transfer:plan_transfer"
_ENERGY = dict(run="qmt_drake.energy.energy_plan:plan_energy_time", internal=("E",), passes=("method", "progress"))

# The table. Transfer rows first (the thesis arms, the tray), then spatial, then energy-time; within a
# kind in the order the CLI lists them.
METHODS: tuple[Method, ...] = (
    Method("ga", TRANSFER, f"{_T}:ga", "the thesis's binary GA over the scenario's trajectory family",
           options_of="qmt_drake.planners.ga:run_ga", internal=("problem", "settings"), passes=("seed", "progress"),
           renamed={"generations": "max_generations", "stall": "stall_generations"}, refused=_GA_REFUSED),
    Method("optimum", TRANSFER, f"{_T}:optimum", "the family's deterministic best (planners/family_optimum_core)", aliases=("family_optimum",),
           options_of="qmt_drake.planners.optimum:plan_family_optimum", internal=("problem",),
           passes=("seed", "progress")),
    Method("thesis", TRANSFER, f"{_T}:thesis", "the genes the thesis reported, evaluated by our model",
           internal=("scenario",), passes=("seed", "progress")),
    Method("toppra", TRANSFER, "qmt_drake.planners.baselines.toppra_plan:plan_toppra", "TOPP-RA on the path",
           internal=("scenario",)),
    Method("toppra-drake", TRANSFER, "qmt_drake.planners.baselines.toppra_plan:plan_toppra_drake",
           "Drake's TOPPRA on the path", internal=("scenario",)),
    Method("ruckig", TRANSFER, "qmt_drake.planners.baselines.ruckig_plan:plan_ruckig",
           "Ruckig's jerk-limited motion", internal=("scenario",)),
    Method("trajopt", TRANSFER, "qmt_drake.planners.baselines.trajopt_plan:plan_trajopt",
           "Drake's KinematicTrajectoryOptimization (the one trajopt, planners/trajopt_core)", internal=("scenario",)),
    # seed 001's energy-time cost on the scenario's family under its limit set (energy/cross_kind.py)
    *(Method(name, TRANSFER, "qmt_drake.energy.cross_kind:plan_energy_time_transfer",
             f"the energy-time cost over the family's genes, {how}", internal=("scenario",), passes=("method",))
      for name, how in (("snopt", "SNOPT"), ("ipopt", "IPOPT"), ("steepest", "steepest descent"))),
    Method("collocation", TRANSFER, "qmt_drake.energy.collocation_kinds:plan_collocation_transfer",
           "the energy-time cost by direct collocation of the joint-space double integrator, SNOPT",
           internal=("scenario",), passes=("progress",)),
    Method("toppra", SPATIAL, f"{_S}:plan_toppra_spatial", "TOPP-RA on the family's path", internal=("sc",)),
    Method("ruckig", SPATIAL, f"{_S}:plan_ruckig_spatial", "Ruckig rest to rest between task poses",
           internal=("sc",)),
    Method("family_optimum", SPATIAL, "qmt_drake.planners.spatial_search:plan_family_optimum",
           "the family's fastest member (planners/family_optimum_core)", aliases=("optimum",), internal=("sc",)),
    Method("ga", SPATIAL, "qmt_drake.planners.spatial_search:plan_ga_spatial", "the binary GA on the family's genes",
           internal=("sc",), passes=("seed", "progress")),
    Method("trajopt", SPATIAL, f"{_S}:plan_trajopt_spatial",
           "Drake's KinematicTrajectoryOptimization (the one trajopt, planners/trajopt_core)", internal=("sc",)),
    Method("toppra-drake", SPATIAL, "qmt_drake.planners.baselines.toppra_plan:plan_toppra_drake_spatial",
           "Drake's Toppra on the IK'd path (joint limits; the rest held by the re-check)", internal=("sc",)),
    # seed 001's energy-time cost on a spatial arm's via-cubic family under its re-check's limits (energy/cross_kind.py)
    *(Method(name, SPATIAL, "qmt_drake.energy.cross_kind:plan_energy_time_spatial", summary, internal=("sc",),
             passes=("method",))
      for name, summary in (("snopt", "the energy-time cost over the via cubic's segment times, SNOPT"),
                            ("ipopt", "the energy-time cost over the via cubic's segment times, IPOPT"),
                            ("steepest", "the energy-time cost over the via cubic's segment times, steepest descent"))),
    Method("collocation", SPATIAL, "qmt_drake.energy.collocation_kinds:plan_collocation_spatial",
           "the energy-time cost by direct collocation of the joint-space double integrator, SNOPT", internal=("sc",),
           passes=("progress",)),
    Method("snopt", ENERGY, summary="the energy-time NLP by SNOPT, multi-start", **_ENERGY),
    Method("ipopt", ENERGY, summary="the energy-time NLP by IPOPT, multi-start", **_ENERGY),
    Method("steepest", ENERGY, summary="the paper's steepest descent, multi-start", **_ENERGY),
    Method("collocation", ENERGY, summary="direct collocation, multi-start", **_ENERGY),
    # the transfer planners on seed 001's arm: the spatial planner on its joint-space transfer
    # (energy/as_transfer.py: its URDF, start and end postures, joint-torque limits, no part)
    *(Method(name, ENERGY, _XFER, f"{summary} (the arm as a minimum-time transfer)", aliases=aliases,
             options_of=of, internal=("sc",), passes=("method", "seed", "progress"))
      for name, of, summary, aliases in (
          ("toppra", f"{_S}:plan_toppra_spatial", "TOPP-RA on the joint path", ()),
          ("toppra-drake", "qmt_drake.planners.baselines.toppra_plan:plan_toppra_drake_spatial",
           "Drake's Toppra on the joint path", ()),
          ("ruckig", f"{_S}:plan_ruckig_spatial", "Ruckig rest to rest", ()),
          ("trajopt", f"{_S}:plan_trajopt_spatial", "Drake's KinematicTrajectoryOptimization", ()),
          ("family_optimum", "qmt_drake.planners.spatial_search:plan_family_optimum", "the family's fastest member",
           ("optimum",)),
          ("ga", "qmt_drake.planners.spatial_search:plan_ga_spatial", "the binary GA on the family's genes", ()))),
)
_USER: dict[tuple[str, str], Method] = {}  # register_method's rows (a built-in's name swaps it)


def rows(kind: str | None = None) -> list[Method]:
    """The table's rows (a registered row in place of the built-in of its name), of one kind if given."""
    built = [_USER.get((m.kind, m.name), m) for m in METHODS]
    extra = [m for key, m in _USER.items() if not any((b.kind, b.name) == key for b in METHODS)]
    return [m for m in built + extra if kind is None or m.kind == kind]


def names(kind: str) -> tuple[str, ...]:
    """The methods of one kind, in the table's order (what the CLI lists)."""
    return tuple(m.name for m in rows(kind))


def kind_of_scenario(scenario: Any) -> str:
    """The kind of a loaded scenario (plan_files.scenario_kind_of; every kind's plan module is loaded
    first, since each registers its kind when imported)."""
    for m in METHODS:
        if isinstance(m.run, str):
            importlib.import_module(m.run.partition(":")[0])
    return scenario_kind_of(scenario)


def find(kind: str, method: Any, where: str = "method") -> Method:
    """The row of `method` (its name or an alias) on `kind`; one line naming the kind's methods else."""
    if not isinstance(method, str):
        raise QmtInputError(f"{where} {show(method)} must be a planner's name (a str); use {'|'.join(names(kind))}")
    mine = [m for m in rows(kind) if method == m.name or method in m.aliases]
    if mine:
        return mine[0]
    other = [k for k in KINDS if any(m.kind == k and (method == m.name or method in m.aliases) for m in rows())]
    if other:
        theirs = " and ".join(f"{_WORDS[k]} (kind: {k})" for k in other)
        raise QmtInputError(f"{where} {method} plans {theirs} scenarios, not {_WORDS[kind]} ones; "
                            f"{_WORDS[kind]} scenarios take {'|'.join(names(kind))}")
    raise QmtInputError(f"{where} {method!r} is unknown (no planner of any kind has that name); {_WORDS[kind]} "
                        f"scenarios take {'|'.join(names(kind))}")


def _flag(where: str | dict, key: str) -> str:
    """How a message names option `key`: `where` a prefix ('plan_with option' -> 'plan_with option key')
    or the CLI's {option: flag} map (an option it lacks: '--option key')."""
    if isinstance(where, dict):
        return where.get(key, f"--option {key}")
    return f"{where} {key}"


def check(kind: str, method: Any, options: dict, where: str | dict = "plan_with option") -> tuple[Method, dict]:
    """(row, options under the function's own keywords): `method` and `options` checked against the
    row (module docstring), before any work."""
    row = find(kind, method, "--method" if isinstance(where, dict) else "method")
    if not isinstance(options, dict):
        raise QmtInputError(f"options {show(options)} must be keyword arguments")
    out = {}
    for key, value in options.items():
        if key in row.refused:
            raise QmtInputError(f"{_flag(where, key)}: {row.refused[key]}")
        out[row.renamed.get(key, key)] = value
    params = row.options()
    if row.open_options:  # a registered planner taking **options: its own call checks the rest
        return row, out
    for key in out:
        if key not in params:
            given = next((k for k, v in row.renamed.items() if v == key), key)
            why = _takers(key)
            raise QmtInputError(f"{_flag(where, given)}: not an option of the {_WORDS[kind]} {row.name} planner{why}; "
                                f"{_closest(given, params)}it takes {', '.join(sorted(params)) or 'no options'}")
    for key, value in out.items():  # types and ranges (api_checks.option_value), named as they were given
        if not callable(value):
            given = next((k for k, v in row.renamed.items() if v == key and k in options), key)
            option_value(key, value, params[key]["default"], _flag(where, given))
    return row, out


def _takers(key: str) -> str:
    """' (the planar ga planner takes it)', or ' (the planners that take it: planar ga; spatial (3-D) ga)':
    the rows whose option `key` is, grouped by kind."""
    by_kind = {k: [m.name for m in rows(k) if key in m.options()] for k in KINDS}
    groups = [f"{_WORDS[k]} {_and(ms)}" for k, ms in by_kind.items() if ms]
    if not groups:
        return ""
    if len(groups) > 1:
        return f" (the planners that take it: {'; '.join(groups)})"
    return f" (the {groups[0]} planner{'s take' if len(next(ms for ms in by_kind.values() if ms)) > 1 else ' takes'} it)"


def _and(words: list[str]) -> str:
    """'a', 'a and b', 'a, b and c'."""
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} and {words[-1]}"


def plan(scenario: Any, method: str, *, seed: int = 0, progress: Progress = None, where: str | dict = "plan_with option",
         **options: Any) -> Any:
    """Plan `scenario` with `method` (a name or alias of a row of its kind) and return its Plan
    (re-checked by sampling: plan.feasible, plan.check). seed: the GA's (and the transfer optimum's)
    generator, ignored by deterministic methods; progress: a callable taking one line; options: the
    row's options (Method.options()). Everything is checked before any work (`check`)."""
    kind = kind_of_scenario(scenario)
    number(seed, "seed", minimum=0, integer=True, fix="seeds are non-negative integers")
    if progress is not None and not callable(progress):
        raise QmtInputError(f"progress {show(progress)} must be a callable taking one line, or None")
    row, opts = check(kind, method, options, where)
    own = {"seed": seed, "progress": progress, "method": row.name}
    return row.function(scenario, **{k: own[k] for k in row.passes}, **opts)


def register_method(name: str, kind: str, planner: Callable[..., Any], *, replace: bool = False,
                    passes: tuple[str, ...] = ("seed", "progress")) -> None:
    """A user's method `name` on scenario kind `kind`: planner(scenario, *, seed, progress, **options)
    -> Plan (its own keywords are its options). A name registers once per kind: an existing one (a
    built-in too) only with replace=True. One-line QmtInputError else."""
    if kind not in KINDS:
        raise QmtInputError(f"kind {show(kind)} is not a scenario kind; use {'|'.join(KINDS)}")
    taken = any(m.name == name for m in rows(kind))
    check_registration("planner", name, taken, replace)
    if not callable(planner):
        raise QmtInputError(f"planner {name!r}: {type(planner).__name__} is not callable; give a function "
                            "planner(scenario, *, seed, progress, **options) -> Plan")
    try:
        inspect.signature(planner).bind(object(), **{k: None for k in passes})
    except TypeError as exc:
        raise QmtInputError(f"planner {name!r} cannot be called as planner(scenario, *, seed, progress, **options) "
                            f"({exc}); add those parameters") from None
    except ValueError:  # no signature to read (a builtin): called as it is
        pass
    built = [m for m in METHODS if (m.kind, m.name) == (kind, name)]
    if built and built[0].function is planner:  # a built-in put back: its own row again
        _USER.pop((kind, name), None)
        return
    try:
        first = next(iter(inspect.signature(planner).parameters))
    except (ValueError, StopIteration):
        first = ""
    _USER[(kind, name)] = Method(name, kind, planner, "registered", internal=(first,), passes=passes)


def unregister_method(name: str, kind: str) -> None:
    """Remove a method registered with register_method (the built-in of that name is back)."""
    _USER.pop((kind, name), None)


class _Functions(Mapping):
    """The functions of one kind's rows by method name (read only): functions(kind)["ga"](scenario, ...)."""

    def __init__(self, kind: str) -> None:
        self.kind = kind

    def __getitem__(self, name: str) -> Callable[..., Any]:
        for m in rows(self.kind):
            if m.name == name:  # a row that shares its function with others is told which it is
                return partial(m.function, method=m.name) if "method" in m.passes else m.function
        raise KeyError(name)

    def __iter__(self) -> Iterator[str]:
        return iter(names(self.kind))

    def __len__(self) -> int:
        return len(names(self.kind))


def functions(kind: str) -> Mapping[str, Callable[..., Any]]:
    """A read-only view of one kind's functions by method name (the table's rows, not a second table)."""
    return _Functions(kind)


def aliases(kind: str) -> dict[str, str]:
    """{alias: method name} of one kind's rows."""
    return {a: m.name for m in rows(kind) for a in m.aliases}
