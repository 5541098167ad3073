"""qmt_drake: quasi-minimum-time transfer motions of robot arms that carry a payload they can lose.

Entry points: `qmt_drake.config.scenario.load_scenario`, `qmt_drake.problem.PlanningProblem`,
`qmt_drake.planners`, `qmt_drake.plan.Plan`; the command line is `qmt-drake` (qmt_drake/cli.py).
"""

__version__ = "0.1.0"
