"""Planner options of a sweep spec's plans (`plans[i].options`), checked before any case runs.

Each option must be a keyword argument of the method's planner (its signature is read, so a new
option needs no change here) and a plain value (number, string, true/false); the GA's generation
counts are integers (max_generations >= 1, stall_generations >= 0). One line naming the option and
the fix, via QmtInputError.
"""

from __future__ import annotations

import importlib
import inspect

from qmt_drake.config.fields import is_number, show
from qmt_drake.errors import QmtInputError

# method -> (module, function, keyword arguments that are not user options)
PLANNERS = {
    "ga": ("qmt_drake.planners.ga", "run_ga", {"problem", "settings", "seed", "progress",
                                               "progress_every_s", "checkpoint_path", "checkpoint_every"}),
    "optimum": ("qmt_drake.planners.optimum", "plan_family_optimum", {"problem", "seed", "progress"}),
    "toppra": ("qmt_drake.planners.baselines.toppra_plan", "plan_toppra", {"scenario"}),
    "toppra-drake": ("qmt_drake.planners.baselines.toppra_plan", "plan_toppra_drake", {"scenario"}),
    "ruckig": ("qmt_drake.planners.baselines.ruckig_plan", "plan_ruckig", {"scenario"}),
    "trajopt": ("qmt_drake.planners.baselines.trajopt_plan", "plan_trajopt", {"scenario"}),
    "thesis": None,  # the scenario's reported genes: no options
}
GA_COUNTS = {"max_generations": 1, "stall_generations": 0}


def planner_options(method: str) -> set[str]:
    """The option names the planner of `method` accepts."""
    entry = PLANNERS.get(method)
    if entry is None:
        return set()
    module, func, internal = entry
    sig = inspect.signature(getattr(importlib.import_module(module), func))
    return {n for n, p in sig.parameters.items()
            if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD) and n not in internal}


def check_options(options, method: str, at: str) -> dict:
    """`options` of a plan of `method` as a checked dict (see the module docstring)."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise QmtInputError(f"{at}.options must be a mapping of planner keyword arguments, got {show(options)}")
    allowed = planner_options(method)
    for k, v in options.items():
        if k not in allowed:
            names = ", ".join(sorted(allowed)) or "none"
            raise QmtInputError(f"{at}.options: '{k}' is not an option of the {method} planner; its options "
                                f"are {names}")
        if not (is_number(v) or isinstance(v, (str, bool))):
            raise QmtInputError(f"{at}.options.{k} must be a number, a string or true/false, got {show(v)}")
        if is_number(v) and v != v:  # NaN
            raise QmtInputError(f"{at}.options.{k} must be a finite number, got {v}")
        if method == "ga" and k in GA_COUNTS and (isinstance(v, bool) or not isinstance(v, int)
                                                  or v < GA_COUNTS[k]):
            raise QmtInputError(f"{at}.options.{k} must be an integer >= {GA_COUNTS[k]}, got {show(v)}")
    return dict(options)
