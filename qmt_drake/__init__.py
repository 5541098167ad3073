"""qmt_drake: quasi-minimum-time transfer motions of robot arms that carry a payload they can lose,
planned, benchmarked and executed in Drake co-simulations.

    from qmt_drake import load_scenario, plan_with, simulate, build_diagram, Plan, load_plan

`load_scenario` reads a scenario (plain typed data), `plan_with` plans it (a `Plan`, re-checked by
sampling), `simulate` executes a plan in the co-simulation and says whether the part was carried,
`build_diagram` gives the Drake Diagram itself, `load_plan` reads a plan file back; their docstrings give inputs, outputs and units
(SI). The command line is `qmt-drake` (qmt_drake/apps/cli.py); README.md and docs/ describe both.

`import qmt_drake` is light and has no side effect: it loads no submodule (no pydrake) until a
public name is first used (module `__getattr__`, PEP 562), registers nothing and leaves the
process's allocator alone (the glibc tuning is an explicit call, `qmt_drake.malloc_tuning.tune()`,
which the `qmt-drake` command makes).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # for type checkers and readers; at run time __getattr__ loads them on first use
    from qmt_drake.api import Plan, Scenario, build_diagram, load_plan, load_scenario, plan_with, simulate
    from qmt_drake.scenario_data import build_scenario, load_scenario_data

__version__ = "0.1.0"
__all__ = ["Plan", "Scenario", "__version__", "build_diagram", "build_scenario", "load_plan", "load_scenario",
           "load_scenario_data", "plan_with", "simulate"]

# public name -> the module that defines it (imported on first use)
_PUBLIC = {name: "qmt_drake.api" for name in __all__ if name != "__version__"}
_PUBLIC.update(load_scenario_data="qmt_drake.scenario_data", build_scenario="qmt_drake.scenario_data")


def __getattr__(name: str) -> Any:
    if name in _PUBLIC:
        value = getattr(importlib.import_module(_PUBLIC[name]), name)
        globals()[name] = value  # once: later lookups do not come back here
        return value
    raise AttributeError(f"module 'qmt_drake' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
