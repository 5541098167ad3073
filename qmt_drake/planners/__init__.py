"""Planners. Every one returns a re-checked Plan (qmt_drake/plan.py); `plan_with` dispatches by
name, so the CLI, the studies and the benchmark call them all the same way.

- ga: the thesis's binary GA over the family's genes (ga.py)
- optimum: the deterministic best of the family (optimum.py)
- thesis: the genes the thesis reported, evaluated by our model
- toppra, toppra-drake, ruckig, trajopt: time-optimal baselines (their own modules)
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from qmt_drake.config.registry import check_registration
from qmt_drake.config.scenario import Scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.plan import Plan, family_plan
from qmt_drake.planners.baselines.ruckig_plan import plan_ruckig
from qmt_drake.planners.baselines.toppra_plan import plan_toppra, plan_toppra_drake
from qmt_drake.planners.baselines.trajopt_plan import plan_trajopt
from qmt_drake.planners.ga import run_ga
from qmt_drake.planners.optimum import TightTimingProblem, plan_family_optimum
from qmt_drake.problem import PlanningProblem

Progress = Callable[[str], None] | None  # a callable taking one line of text


def _ga(scenario: Scenario, *, seed: int = 0, progress: Progress = None, **options: Any) -> Plan:
    problem = PlanningProblem(scenario)
    tight = TightTimingProblem(problem) if scenario.ga.tight_timing else None
    r = run_ga(tight if tight is not None else problem, seed=seed, progress=progress, **options)
    genes = tight.realize(r.genes) if tight is not None and r.feasible else r.genes
    return family_plan(problem, genes, "ga", planner_wall_s=r.wall_s,
                       evaluations=r.evaluations, generations=r.generations,
                       extra={"seed": seed, "stop_reason": r.stop_reason,
                              "ga_settings": scenario.ga.__dict__,
                              "history_best_motion_time_s": r.history.best_cost,
                              "history_mean_fitness": r.history.mean_fitness,
                              "history_feasible_fraction": r.history.feasible_fraction})


def _optimum(scenario: Scenario, *, seed: int = 0, progress: Progress = None, **options: Any) -> Plan:
    return plan_family_optimum(PlanningProblem(scenario), seed=seed, progress=progress, **options)


def _thesis(scenario: Scenario, *, seed: int = 0, progress: Progress = None) -> Plan:
    if not scenario.reported.get("genes"):
        raise QmtInputError(f"scenario {scenario.name} has no reported.genes to evaluate")
    problem = PlanningProblem(scenario)
    return family_plan(problem, problem.genes_vector(scenario.reported["genes"]), "thesis")


def _options_only(planner: Callable[..., Plan]) -> Callable[..., Plan]:
    """A baseline planner takes the scenario and its own options (no seed, no progress)."""
    return lambda scenario, *, seed=0, progress=None, **options: planner(scenario, **options)


# The planner registry: each method registers once (register_planner); the CLI, the studies, the
# benchmark and the sweeps reach every planner through plan_with.
PLANNERS: dict[str, Callable[..., Plan]] = {}


def register_planner(name: str, planner: Callable[..., Plan], *, replace: bool = False) -> None:
    """planner(scenario, *, seed, progress, **options) -> Plan. A name registers once: an existing
    one (a built-in too) only with replace=True; the planner's signature is checked now, not at its
    first plan. One-line QmtInputError else."""
    check_registration("planner", name, name in PLANNERS, replace)
    if not callable(planner):
        raise QmtInputError(f"planner {name!r}: {type(planner).__name__} is not callable; give a function "
                            "planner(scenario, *, seed, progress, **options) -> Plan")
    try:
        inspect.signature(planner).bind(object(), seed=0, progress=None)
    except TypeError as exc:
        raise QmtInputError(f"planner {name!r} cannot be called as planner(scenario, *, seed, progress, **options) "
                            f"({exc}); add those parameters") from None
    except ValueError:  # no signature to read (a builtin): called as it is
        pass
    PLANNERS[name] = planner


def unregister_planner(name: str) -> None:
    """Remove a planner registered with register_planner (no error if absent)."""
    PLANNERS.pop(name, None)


for _name, _planner in (("ga", _ga), ("optimum", _optimum), ("thesis", _thesis),
                        ("toppra", _options_only(plan_toppra)), ("toppra-drake", _options_only(plan_toppra_drake)),
                        ("ruckig", _options_only(plan_ruckig)), ("trajopt", _options_only(plan_trajopt))):
    register_planner(_name, _planner)
METHODS = tuple(PLANNERS)


def plan_with(method: str, scenario: Scenario, *, seed: int = 0, progress: Progress = None, **options: Any) -> Plan:
    """Plan `scenario` with the registered planner `method` (METHODS) and return its Plan, re-checked
    by sampling at the scenario's check rate. seed: the GA's and the optimum's generator; progress:
    a callable taking one line; options: the planner's own keywords (its docstring lists them; an
    unknown one raises TypeError, which the CLI turns into one line). Units: SI (s, rad)."""
    if method not in PLANNERS:
        raise QmtInputError(f"unknown method '{method}'; use one of {', '.join(PLANNERS)}")
    return PLANNERS[method](scenario, seed=seed, progress=progress, **options)
