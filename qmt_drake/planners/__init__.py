"""Planners. Every one returns a re-checked Plan (qmt_drake/plan.py); the one registry
(planners/registry.py: one table of every method on every scenario kind, one `plan`) dispatches by
name, so the CLI, the API, the studies, the benchmark and the sweeps call them all the same way.

Transfer scenarios: ga (the thesis's binary GA, ga.py), optimum (the family's deterministic best,
optimum.py), thesis (the reported genes), toppra, toppra-drake, ruckig, trajopt (baselines/).
Spatial scenarios: toppra, ruckig, family_optimum, ga, trajopt (spatial_methods.py, spatial_search.py).
Energy-time scenarios: snopt, ipopt, steepest, collocation (energy/energy_plan.py).

`plan_with(method, scenario, ...)` is registry.plan with the method first (the older call order);
`register_planner` / `unregister_planner` add a user's transfer method to the registry.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from qmt_drake.planners import registry
from qmt_drake.planners.registry import TRANSFER, Progress


def plan_with(method: str, scenario: Any, *, seed: int = 0, progress: Progress = None, **options: Any) -> Any:
    """Plan `scenario` (any kind) with `method` and return its Plan, re-checked by sampling
    (registry.plan: the method and its options checked first, one line naming the fix)."""
    return registry.plan(scenario, method, seed=seed, progress=progress, **options)


def register_planner(name: str, planner: Callable[..., Any], *, replace: bool = False) -> None:
    """planner(scenario, *, seed, progress, **options) -> Plan on transfer scenarios
    (registry.register_method); a name registers once, a built-in one only with replace=True."""
    registry.register_method(name, TRANSFER, planner, replace=replace)


def unregister_planner(name: str) -> None:
    """Remove a planner registered with register_planner (no error if absent)."""
    registry.unregister_method(name, TRANSFER)


PLANNERS = registry.functions(TRANSFER)  # the transfer rows' functions (a view of the registry, not a table)
METHODS = registry.names(TRANSFER)
