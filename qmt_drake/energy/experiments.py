"""Seed 001's three numerical experiments (section 3) and the paper's numbers, read from the
scenario files models/scenarios/ohsaka-fig{2,3,4}.yaml (the one source of truth; loader:
scenario.py). A user's own file of that kind works wherever a built-in name does.

Coordinate vector (X(0)', X(T)')' in metres, X2 up. c1, c2 as printed. m = 5, 40 divisions.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from qmt_drake.energy.problem import EnergyProblem


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

    def problem(self, **over) -> EnergyProblem:
        kw = dict(X0=self.coordinate_vector_m[:2], XT=self.coordinate_vector_m[2:], c1=self.c1,
                  c2=self.c2, m=self.m, divisions=self.divisions, fixed_T_s=self.fixed_T_s,
                  moving_joints=self.moving_joints)
        if self.arm is not None:
            kw["arm"] = self.arm
        kw.update(over)
        return EnergyProblem(**kw)


class _Experiments(Mapping):
    """Built-in experiments by name (loaded on first use). `x in EXPERIMENTS` is also true for a
    path to a YAML file of kind energy_time, so `qmt-drake plan FILE` routes it here."""

    def __getitem__(self, name):
        from qmt_drake.energy.scenario import builtin_energy_scenarios
        if name not in builtin_energy_scenarios():
            raise KeyError(name)
        return _load(name)

    def __iter__(self):
        from qmt_drake.energy.scenario import builtin_energy_scenarios
        return iter(builtin_energy_scenarios())

    def __len__(self):
        from qmt_drake.energy.scenario import builtin_energy_scenarios
        return len(builtin_energy_scenarios())

    def __contains__(self, name) -> bool:
        from qmt_drake.energy.scenario import is_energy_scenario
        return is_energy_scenario(name)


EXPERIMENTS = _Experiments()


@lru_cache(maxsize=16)
def _load(name_or_path: str) -> Experiment:
    from qmt_drake.energy.scenario import load_energy_scenario
    return load_energy_scenario(name_or_path)


def get_experiment(name_or_path) -> Experiment:
    """A built-in experiment by name (ohsaka-fig2/3/4) or a user's energy scenario file by path."""
    from qmt_drake.energy.scenario import resolve
    return _load(str(resolve(name_or_path).resolve()))


def paper_initial_x(problem: EnergyProblem, initial_a: dict, T_s: float) -> np.ndarray:
    """The paper's initial trajectory vector (a_ij as printed, others 0) before step III."""
    F = problem.family
    a = np.zeros((F.n, F.m))
    for (i, j), v in initial_a.items():
        if j <= F.m:
            a[i - 1, j - 1] = v
    return F.pack(a, np.zeros((F.n, F.m)), T_s)
