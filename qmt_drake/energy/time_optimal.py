"""The time-optimal end of the energy-time front: TOPP-RA (toppra package) on the geometric path of
an energy-time optimum, under the joint torque limits |tau_i| <= tau_max,i that the scenario states
(limits.joint_torque_Nm; seed 001 states none, ours are in the YAML), gravity included.

Path: q(s) = the Fourier trajectory at t = s T, s in [0, 1] (q_s = T qd, q_ss = T^2 qdd; both
vanish at the ends by eq. 6, so the ends are rest points of the path itself). Constraint rows:
tau(q, qd, qdd) / tau_max in [-1, 1], tau by `inverse_dynamics_with_gravity` (the project's
PlanarChain), through the project's toppra constraint builder (`limits.toppra_form.rows_constraint`,
unit-norm rows: the fix for toppra's Seidel LP with gravity).

Solved by the one TOPP-RA (planners/toppra_core.parameterise) with toppra's constant-acceleration
output. The result is checked by sampling (default 20001 points, also between toppra's gridpoints): its
peak |tau_i| / tau_max,i is reported as it is; when it is above 1 (toppra enforces the limits at
its gridpoints only), the motion is played slower by the smallest factor that brings it to <= 1
(`slowdown_search`, a bisection: with gravity the ratio is not a pure lam^-2 law) and both are reported.

Units: s, N m, N^2 m^2 s.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from qmt_drake.energy.dynamics import inverse_dynamics_with_gravity
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.toppra_form import rows_constraint
from qmt_drake.planners.toppra_core import parameterise, toppra_path
from qmt_drake.timescale import Grow, search_scale


@dataclass
class TimeOptimalResult:
    T_s: float                   # motion time after the slow-down (if any)
    energy_N2m2s: float          # integral tau'tau dt of the checked motion
    peak_ratio: float            # max |tau_i| / tau_max,i of the checked motion (<= 1)
    raw_T_s: float               # toppra's own motion time
    raw_peak_ratio: float        # its sampled peak ratio (can exceed 1 between gridpoints)
    slowdown: float              # raw -> checked time factor (1 if none needed)
    return_code: str
    wall_s: float
    peak_torque_Nm: np.ndarray

    def summary(self) -> dict:
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()}


def _fourier_path(family, x):
    """q(s) = the Fourier trajectory at t = s T, s in [0, 1], as toppra's geometric path (toppra_core)."""
    T = float(family.unpack(x)[2])

    def evaluate(s, order=0):
        scalar = np.ndim(s) == 0
        q, qd, qdd = family.evaluate_s(x, np.clip(np.atleast_1d(np.asarray(s, float)), 0.0, 1.0))
        out = (q, T * qd, T * T * qdd)[order]
        return out[0] if scalar else out

    return toppra_path(evaluate, family.n, (0.0, 1.0))


def _torques(arm, traj, t, lam: float = 1.0):
    """tau along the toppra trajectory played lam times slower, at times t of the slowed motion."""
    tt = np.clip(t / lam, 0.0, traj.duration)
    q, qd, qdd = traj(tt, 0), traj(tt, 1) / lam, traj(tt, 2) / lam**2
    return inverse_dynamics_with_gravity(q, qd, qdd, arm, derivatives=False)


def slowdown_search(holds, raw_peak: float):
    """Seed 001's variant of the one search (timescale.search_scale): 1 fails; from sqrt(raw_peak) up by
    1 % until it holds, then 40 arithmetic bisection steps from [1, that]."""
    return search_scale(holds, steps=40, grow=Grow(start=1.0, factor=1.01, first=np.sqrt(raw_peak), follow=False))


def time_optimal_on_path(problem, x, torque_limit_Nm, grid_points: int = 400,
                         check_samples: int = 20001) -> TimeOptimalResult:
    """TOPP-RA on the path of the Fourier trajectory x of `problem` (module docstring)."""
    lim = np.asarray(torque_limit_Nm, dtype=float)
    n = problem.family.n
    if lim.shape != (n,) or not np.all(np.isfinite(lim)) or np.any(lim <= 0):
        raise QmtInputError(f"joint torque limits {lim.tolist()} N m must be {n} positive numbers")
    arm = problem.arm
    g0 = inverse_dynamics_with_gravity(problem.family.evaluate_s(x, np.linspace(0, 1, 201))[0],
                                       np.zeros((201, n)), np.zeros((201, n)), arm, derivatives=False)
    if np.any(np.abs(g0) > lim):
        raise QmtInputError(f"joint torque limits {lim.tolist()} N m cannot even hold the arm still on "
                            f"this path (static torque up to {np.abs(g0).max(axis=0).round(1).tolist()} N m)")
    t0 = time.perf_counter()
    Fm = np.concatenate([np.eye(n), -np.eye(n)])
    constraint = rows_constraint(
        lambda q, qd, qdd: inverse_dynamics_with_gravity(q, qd, qdd, arm, derivatives=False) / lim,
        Fm, np.ones(2 * n), n)
    sol = parameterise(_fourier_path(problem.family, x), [constraint], np.linspace(0, 1, grid_points))
    traj = sol.toppra_trajectory("ParametrizeConstAccel")
    code = sol.return_code
    wall = time.perf_counter() - t0
    if traj is None:
        return TimeOptimalResult(np.nan, np.nan, np.nan, np.nan, np.nan, np.nan, code, wall, np.full(n, np.nan))
    raw_T = float(traj.duration)

    def peak(lam):
        t = np.linspace(0.0, raw_T * lam, check_samples)
        tau = _torques(arm, traj, t, lam)
        return float(np.max(np.abs(tau) / lim)), t, tau

    raw_peak, t, tau = peak(1.0)
    lam = 1.0
    if raw_peak > 1.0:
        lam = slowdown_search(lambda k: not peak(k)[0] > 1.0, raw_peak).holding
    p, t, tau = peak(lam)
    energy = float(np.trapezoid(np.sum(tau * tau, axis=1), t))
    return TimeOptimalResult(raw_T * lam, energy, p, raw_T, raw_peak, lam, code, wall,
                             np.max(np.abs(tau), axis=0))
