"""Trajectory families: genes -> joint trajectories q(t), qd(t), qdd(t).

One module per family of seed 000: `line` (ch.2 straight tip line, cubic-velocity profile),
`trapezoid` (ch.3 trapezoidal joint velocities), `via_cubic` (ch.4 joint cubics through N vias).
`make_family(scenario)` builds the one a scenario names.
"""

from __future__ import annotations

from qmt_drake.families.base import TrajectoryFamily
from qmt_drake.families.line import LineCubicVelocity
from qmt_drake.families.trapezoid import TrapezoidPtp
from qmt_drake.families.via_cubic import ViaCubic

_KINDS = {
    "line_cubic_velocity": LineCubicVelocity,
    "trapezoid_ptp": TrapezoidPtp,
    "via_cubic": ViaCubic,
}


def make_family(scenario) -> TrajectoryFamily:
    return _KINDS[scenario.family.kind](scenario)


__all__ = ["TrajectoryFamily", "LineCubicVelocity", "TrapezoidPtp", "ViaCubic", "make_family"]
