"""Planners. Every one returns a re-checked Plan (qmt_drake/plan.py); `plan_with` dispatches by
name, so the CLI, the studies and the benchmark call them all the same way.

- ga: the thesis's binary GA over the family's genes (ga.py)
- optimum: the deterministic best of the family (optimum.py)
- thesis: the genes the thesis reported, evaluated by our model
- toppra, toppra-drake, ruckig, trajopt: time-optimal baselines (their own modules)
"""

from __future__ import annotations

from qmt_drake.errors import QmtInputError
from qmt_drake.plan import family_plan
from qmt_drake.planners.baselines.ruckig_plan import plan_ruckig
from qmt_drake.planners.baselines.toppra_plan import plan_toppra, plan_toppra_drake
from qmt_drake.planners.baselines.trajopt_plan import plan_trajopt
from qmt_drake.planners.ga import run_ga
from qmt_drake.planners.optimum import TightTimingProblem, plan_family_optimum
from qmt_drake.problem import PlanningProblem

METHODS = ("ga", "optimum", "thesis", "toppra", "toppra-drake", "ruckig", "trajopt")


def plan_with(method: str, scenario, *, seed: int = 0, progress=None, **options):

    if method == "ga":
        problem = PlanningProblem(scenario)
        searched = TightTimingProblem(problem) if scenario.ga.tight_timing else problem
        r = run_ga(searched, seed=seed, progress=progress, **options)
        genes = searched.realize(r.genes) if scenario.ga.tight_timing and r.feasible else r.genes
        return family_plan(problem, genes, "ga", planner_wall_s=r.wall_s,
                           evaluations=r.evaluations, generations=r.generations,
                           extra={"seed": seed, "stop_reason": r.stop_reason,
                                  "ga_settings": scenario.ga.__dict__,
                                  "history_best_motion_time_s": r.history.best_cost,
                                  "history_mean_fitness": r.history.mean_fitness,
                                  "history_feasible_fraction": r.history.feasible_fraction})
    if method == "optimum":
        return plan_family_optimum(PlanningProblem(scenario), seed=seed, progress=progress,
                                   **options)
    if method == "thesis":
        if not scenario.reported.get("genes"):
            raise QmtInputError(f"scenario {scenario.name} has no reported.genes to evaluate")
        problem = PlanningProblem(scenario)
        return family_plan(problem, problem.genes_vector(scenario.reported["genes"]), "thesis")
    if method == "toppra":
        return plan_toppra(scenario, **options)
    if method == "toppra-drake":
        return plan_toppra_drake(scenario, **options)
    if method == "ruckig":
        return plan_ruckig(scenario, **options)
    if method == "trajopt":
        return plan_trajopt(scenario, **options)
    raise QmtInputError(f"unknown method '{method}'; use one of {', '.join(METHODS)}")
