"""studies.obstacles_clearance plans each task with every minimum-time spatial method, called with the scenario
alone: the energy-time methods (session 14) joined the registry, need their `method`, and made the study fail."""

import inspect

from qmt_drake.energy.energy_plan import METHODS as ENERGY_TIME_METHODS
from qmt_drake.planners.spatial_methods import PLANNERS
from studies import obstacles_clearance


def test_the_study_plans_with_the_minimum_time_methods_each_callable_with_the_scenario_alone():
    assert obstacles_clearance.METHODS[0] == "toppra"  # the detour reads the first plan as TOPP-RA's
    assert set(obstacles_clearance.METHODS) == set(PLANNERS) - set(ENERGY_TIME_METHODS)
    for m in obstacles_clearance.METHODS:
        params = list(inspect.signature(PLANNERS[m]).parameters.values())[1:]
        assert all(p.default is not inspect.Parameter.empty for p in params), m
