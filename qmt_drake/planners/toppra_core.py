"""The one TOPP-RA: a geometric path, toppra constraints and grid points -> the time-optimal
parameterisation -> a trajectory. Every caller goes through `parameterise` (the planar baselines,
planners/baselines/toppra_plan.py; the spatial arms, planners/spatial_toppra.py; seed 002's tray
line, tray/waypoints.py; seed 001's time-optimal end of the front, energy/time_optimal.py).

Solve: TOPP-RA's two passes over toppra's Seidel LP (planners/toppra_passes.py), the same LP calls
as toppra's TOPPRA driver with solver_wrapper="seidel" (the only solver toppra has here, hence the
one every former `TOPPRA(...)` call used), so (sdd, sd) are toppra's bit for bit
(tests/test_one_toppra.py compares them on every caller's problem).

Output, the seeds' variants as named options of the one result (`Parameterisation`):
  sd, sdd, grid          the profile itself: the spatial ToppraTrajectory and the planar
                         PathTimingTrajectory evaluate it exactly (constant s-ddot between grid points)
  duration_s             that profile's duration (the constant-s-ddot formula)
  toppra_trajectory(p)   toppra's own output trajectory, p = "ParametrizeConstAccel" (seed 002's tray
                         stream, seed 001's torque check) or "ParametrizeSpline" (toppra's default,
                         known to overshoot; kept for the planar demonstration)
  return_code            toppra's ParameterizationReturnCode as its str() (the planar plans report it)

`toppra_path` wraps any q(s) (a callable (s, order) -> q, q', q'') as toppra's AbstractGeometricPath.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from qmt_drake.planners.toppra_passes import seidel_parameterization

PARAMETRIZERS = ("ParametrizeConstAccel", "ParametrizeSpline")


@dataclass(frozen=True)
class Parameterisation:
    """The time-optimal parameterisation of `path` on `grid` (sd, sdd None when there is none)."""

    path: object  # the toppra geometric path that was parameterised
    grid: np.ndarray  # (N+1,) path positions
    sd: np.ndarray | None  # (N+1,) path speed at the grid points
    sdd: np.ndarray | None  # (N,) constant path acceleration of each interval
    return_code: str  # str(toppra's ParameterizationReturnCode)
    solve_s: float  # wall time of the two passes (s)
    _trajectories: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return self.sd is not None

    @property
    def duration_s(self) -> float:
        """Duration of the constant-s-ddot profile through (grid, sd) (s)."""
        ds = np.diff(self.grid)
        return float(np.sum(2.0 * ds / (self.sd[:-1] + self.sd[1:])))

    def toppra_trajectory(self, parametrizer: str = "ParametrizeConstAccel"):
        """toppra's output trajectory of this profile (what TOPPRA.compute_trajectory returns); None
        when there is no parameterisation."""
        if parametrizer not in PARAMETRIZERS:
            raise ValueError(f"parametrizer must be one of {PARAMETRIZERS}")
        if not self.ok:
            return None
        if parametrizer not in self._trajectories:
            # lazy: toppra loads matplotlib.pyplot, too slow for every CLI start
            import toppra.parametrizer as tparam

            self._trajectories[parametrizer] = getattr(tparam, parametrizer)(self.path, self.grid, self.sd)
        return self._trajectories[parametrizer]


def parameterise(path, constraints, gridpoints, *, sd_start: float = 0.0, sd_end: float = 0.0) -> Parameterisation:
    """The one TOPP-RA (module docstring): `path` a toppra geometric path (`toppra_path`, or one of
    toppra's interpolators), `constraints` toppra constraints (canonical linear), `gridpoints` rising
    from the path's start to its end; rest to rest by default."""
    t0 = time.perf_counter()
    grid = np.array(gridpoints, dtype=float)
    sdd, sd, code = seidel_parameterization(constraints, path, grid, sd_start, sd_end)
    return Parameterisation(path, grid, sd, sdd, code, time.perf_counter() - t0)


def toppra_path(evaluate, dof: int, interval):
    """`evaluate(s, order)` -> q(s), q'(s) or q''(s) ((S, n) for (S,) s) as toppra's AbstractGeometricPath
    on `interval` (s0, s1)."""
    # lazy: toppra loads matplotlib.pyplot, too slow for every CLI start
    from toppra.interpolator import AbstractGeometricPath

    lo, hi = float(interval[0]), float(interval[1])

    class _Path(AbstractGeometricPath):
        def __call__(self, s, order=0):
            return evaluate(s, order)

        @property
        def dof(self):
            return dof

        @property
        def path_interval(self):
            return np.array([lo, hi])

    return _Path()
