"""Seed 001's three numerical experiments (section 3) as definitions, and the paper's numbers.

They live here, not in models/scenarios/*.yaml, because the scenario loader (qmt_drake/scenario.py)
requires a payload, moment/motor limits, a family kind from FAMILY_KINDS and GA settings, none of
which this problem has (see README.md for what the schema would need).

Coordinate vector (X(0)', X(T)')' in metres, X2 up. c1, c2 as printed. m = 5, 40 divisions.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from qmt_drake.energy.problem import EnergyProblem
from qmt_drake.errors import QmtInputError


@dataclass(frozen=True)
class Experiment:
    name: str
    description: str
    coordinate_vector_m: tuple[float, float, float, float]
    c1: float = 1.0
    c2: float = 1e5
    m: int = 5
    divisions: int = 40
    T_init_s: float = 1.0
    fixed_T_s: float | None = None
    moving_joints: tuple[int, ...] | None = None
    paper_initial_a: dict = field(default_factory=dict)   # {(i, j): value}, 1-based as printed
    reported: dict = field(default_factory=dict)

    def problem(self, **over) -> EnergyProblem:
        kw = dict(X0=self.coordinate_vector_m[:2], XT=self.coordinate_vector_m[2:], c1=self.c1,
                  c2=self.c2, m=self.m, divisions=self.divisions, fixed_T_s=self.fixed_T_s,
                  moving_joints=self.moving_joints)
        kw.update(over)
        return EnergyProblem(**kw)


EXPERIMENTS = {
    "ohsaka-fig2": Experiment(
        "ohsaka-fig2",
        "Fig. 2: T fixed at 4.6 s, only link 1 moves, z against the number of Fourier terms m; "
        "initial a_ij, b_ij all 0",
        (0.7, 0.0, 0.0, 0.7), c1=1.0, c2=1e5, fixed_T_s=4.6, moving_joints=(0,),
        reported={"z_stops_changing_for_m_ge": 5}),
    "ohsaka-fig3": Experiment(
        "ohsaka-fig3",
        "Fig. 3: eight end postures give eight local optima; X(0) is singular (stretched arm)",
        (0.7, 0.0, 0.0, 0.2), c1=1.0, c2=1e5,
        reported={"z": {"(+,-,-)": 22766.0, "(+,+,+)": 20266.0, "(-,+,-)": 18815.0},
                  "global": "(-,+,-)"}),
    "ohsaka-fig4": Experiment(
        "ohsaka-fig4",
        "Fig. 4: c1 = 1, c2 = 1, 1e4, 1e5, 1e6; initial vector a31 = 0.575, all else 0, T = 1",
        (0.68, 0.075, 0.100, 0.600), c1=1.0, c2=1e5, paper_initial_a={(3, 1): 0.575},
        reported={"T_s": {1.0: 1.900, 1e4: 0.330, 1e5: 0.188, 1e6: 0.100},
                  "c2_zero": "no stable solution"}),
}


def get_experiment(name: str) -> Experiment:
    if name not in EXPERIMENTS:
        raise QmtInputError(f"experiment '{name}' is not one of {sorted(EXPERIMENTS)}")
    return EXPERIMENTS[name]


def paper_initial_x(problem: EnergyProblem, initial_a: dict, T_s: float) -> np.ndarray:
    """The paper's initial trajectory vector (a_ij as printed, others 0) before step III."""
    F = problem.family
    a = np.zeros((F.n, F.m))
    for (i, j), v in initial_a.items():
        if j <= F.m:
            a[i - 1, j - 1] = v
    return F.pack(a, np.zeros((F.n, F.m)), T_s)
