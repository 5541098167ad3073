"""Trajectory families: genes -> joint trajectories q(t), qd(t), qdd(t).

One module per family of seed 000: `line` (ch.2 straight tip line, cubic-velocity profile),
`trapezoid` (ch.3 trapezoidal joint velocities), `via_cubic` (ch.4 joint cubics through N vias).
Each registers once in config/registry.FAMILIES (its constructor); `make_family(scenario)`
builds the one a scenario names, and the scenario loader refuses a kind nobody registered.
"""

from __future__ import annotations

from qmt_drake.config.registry import FAMILIES, FamilyPlugin
from qmt_drake.families.base import TrajectoryFamily
from qmt_drake.families.line import LineCubicVelocity
from qmt_drake.families.trapezoid import TrapezoidPtp
from qmt_drake.families.via_cubic import ViaCubic

FAMILIES.register(FamilyPlugin("line_cubic_velocity", LineCubicVelocity))  # genes T1, T2
FAMILIES.register(FamilyPlugin("trapezoid_ptp", TrapezoidPtp))  # genes T11, T21, omega_1m
FAMILIES.register(FamilyPlugin("via_cubic", ViaCubic))  # one time gene per segment: T1 .. T(vias + 1)


def make_family(scenario) -> TrajectoryFamily:
    """The trajectory family the scenario's `family.kind` names (its registered constructor)."""
    return FAMILIES.get(scenario.family.kind, str(scenario.source_path)).make(scenario)


__all__ = ["TrajectoryFamily", "LineCubicVelocity", "TrapezoidPtp", "ViaCubic", "make_family"]
