"""Seed 001's numerical experiments (section 3): the Experiment record that energy/scenario.py loads
from models/scenarios/ohsaka-fig{2,3,4}.yaml (the one source of truth; `get_experiment` and
`EXPERIMENTS` live there), and the paper's initial trajectory. EnergyScenarioData is the file's plain
data (the arm as its URDF path); an Experiment is that data with the arm read (energy/scenario.build_experiment).

Coordinate vector (X(0)', X(T)')' in metres, X2 up. c1, c2 as printed. m = 5, 40 divisions.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from qmt_drake.config.simulation import NO_SIMULATION, Simulation
from qmt_drake.energy.problem import EnergyProblem


@dataclass(frozen=True)
class EnergyScenarioData:
    """An energy-time scenario file (`kind: energy_time`) validated, as plain data: no arm read yet."""

    name: str
    description: str
    coordinate_vector_m: tuple[float, float, float, float]
    c1: float
    c2: float
    m: int
    divisions: int
    T_init_s: float
    fixed_T_s: float | None
    moving_joints: tuple[int, ...] | None  # 1-based, as in the file
    paper_initial_a: dict  # {(i, j): value}, 1-based as printed
    reported: dict
    torque_limit_Nm: tuple[float, ...] | None
    urdf: Path  # arm.urdf (absolute); its tip link 'tip'
    source_path: Path
    simulation: Simulation = NO_SIMULATION  # `simulation` (config/simulation.py): the execution's Drake settings


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
    moving_joints: tuple[int, ...] | None = None   # 0-based here (1-based in the YAML)
    paper_initial_a: dict = field(default_factory=dict)   # {(i, j): value}, 1-based as printed
    reported: dict = field(default_factory=dict)
    torque_limit_Nm: tuple[float, ...] | None = None     # |tau_i| bound for the time-optimal end
    arm: object = None                                   # VerticalArm (None: the Ohsaka arm)
    source_path: Path | None = None
    simulation: Simulation = NO_SIMULATION               # `simulation`: the execution's plant step, simulator

    def problem(self, **over) -> EnergyProblem:
        kw = dict(X0=self.coordinate_vector_m[:2], XT=self.coordinate_vector_m[2:], c1=self.c1,
                  c2=self.c2, m=self.m, divisions=self.divisions, fixed_T_s=self.fixed_T_s,
                  moving_joints=self.moving_joints)
        if self.arm is not None:
            kw["arm"] = self.arm
        kw.update(over)
        return EnergyProblem(**kw)


def paper_initial_x(problem: EnergyProblem, initial_a: dict, T_s: float) -> np.ndarray:
    """The paper's initial trajectory vector (a_ij as printed, others 0) before step III."""
    F = problem.family
    a = np.zeros((F.n, F.m))
    for (i, j), v in initial_a.items():
        if j <= F.m:
            a[i - 1, j - 1] = v
    return F.pack(a, np.zeros((F.n, F.m)), T_s)
