"""qmt_drake: quasi-minimum-time transfer motions of robot arms that carry a payload they can lose,
planned, benchmarked and executed in Drake co-simulations.

    from qmt_drake import load_scenario, plan_with, simulate, build_diagram, Plan, load_plan

`load_scenario` reads a scenario (plain typed data), `plan_with` plans it (a `Plan`, re-checked by
sampling), `simulate` executes a plan in the co-simulation and says whether the part was carried,
`build_diagram` gives the Drake Diagram itself, `load_plan` reads a plan file back; their docstrings give inputs, outputs and units
(SI). The command line is `qmt-drake` (qmt_drake/apps/cli.py); README.md and docs/ describe both.
"""

from qmt_drake import malloc_tuning  # noqa: F401 (first: glibc's thresholds, see the module)
from qmt_drake.api import Plan, Scenario, build_diagram, load_plan, load_scenario, plan_with, simulate

__version__ = "0.1.0"
__all__ = ["Plan", "Scenario", "__version__", "build_diagram", "load_plan", "load_scenario", "plan_with", "simulate"]
