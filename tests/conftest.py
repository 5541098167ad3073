import os

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture(scope="session")
def scenarios():
    from qmt_drake.transfer_scenario import load_scenario
    return {n: load_scenario(n) for n in ("thesis-ch2", "thesis-ch3", "thesis-ch4")}


@pytest.fixture(scope="session")
def problems(scenarios):
    from qmt_drake.problem import PlanningProblem
    return {n: PlanningProblem(s) for n, s in scenarios.items()}
