"""The transfer (planar) scenarios' own planners behind the registry (planners/registry.py): the GA,
the family optimum and the thesis's reported genes, each building the scenario's PlanningProblem and
returning a re-checked Plan (plan.family_plan). The baselines (TOPP-RA, Ruckig, trajopt) take the
scenario themselves (planners/baselines/)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from qmt_drake.config.scenario import Scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.plan import Plan, family_plan
from qmt_drake.planners.ga import run_ga
from qmt_drake.planners.optimum import TightTimingProblem, plan_family_optimum
from qmt_drake.problem import PlanningProblem

Progress = Callable[[str], None] | None  # a callable taking one line of text


def ga(scenario: Scenario, *, seed: int = 0, progress: Progress = None, **options: Any) -> Plan:
    """The thesis's binary GA (planners/ga.run_ga; options: its keywords) over the scenario's family."""
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


def optimum(scenario: Scenario, *, seed: int = 0, progress: Progress = None, **options: Any) -> Plan:
    """The family's deterministic best (planners/optimum.plan_family_optimum; options: its keywords)."""
    return plan_family_optimum(PlanningProblem(scenario), seed=seed, progress=progress, **options)


def thesis(scenario: Scenario, *, seed: int = 0, progress: Progress = None) -> Plan:
    """The genes the thesis reported (scenario `reported.genes`), evaluated by our model (seed and
    progress: unused, the call every transfer planner takes)."""
    if not scenario.reported.get("genes"):
        raise QmtInputError(f"scenario {scenario.name} has no reported.genes to evaluate")
    problem = PlanningProblem(scenario)
    return family_plan(problem, problem.genes_vector(scenario.reported["genes"]), "thesis")
