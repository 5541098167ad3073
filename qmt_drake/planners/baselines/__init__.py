"""The time-optimal baselines the GA is benchmarked against, under the same limit set:
TOPP-RA (toppra_plan.py, and Drake's Toppra), Ruckig (ruckig_plan.py), Drake trajectory
optimization (trajopt_plan.py); the geometric paths they time (paths.py) and what they share
(finish.py: time budget, exact or searched slow-down, infeasible plans)."""
