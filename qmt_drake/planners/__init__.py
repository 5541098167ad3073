"""Planners: every one returns a Plan (qmt_drake/plan.py) for a PlanningProblem."""
