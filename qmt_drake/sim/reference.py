"""Reference trajectories for the co-simulation: a plan, slowed by a time scale, as Drake
PiecewisePolynomials, and GenesPlan (a plan straight from a scenario's family and one gene vector)."""

from __future__ import annotations

import math

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.families import make_family


def check_time_scale(time_scale) -> float:
    """A finite positive time scale, or a one-line QmtInputError."""
    if isinstance(time_scale, bool) or not isinstance(time_scale, (int, float)) \
            or not math.isfinite(time_scale) or not time_scale > 0:
        raise QmtInputError(f"time scale must be a finite positive number (1 replays the plan as planned, "
                            f"2 twice as slow), got {time_scale!r}")
    return float(time_scale)


def reference_trajectories(plan, time_scale: float = 1.0, lead_s: float = 0.2, rate_hz: float = 1000.0):
    """Cubic-Hermite q(t) and first-order-hold qdd(t) of the plan slowed by `time_scale`
    (t_sim = lead_s + time_scale * t_plan), sampled at rate_hz; returns (pp_q, pp_qdd, t_end_motion)."""
    time_scale = check_time_scale(time_scale)
    T = float(plan.motion_time_s) * time_scale
    t = np.arange(0.0, lead_s + T + 0.5 / rate_hz, 1.0 / rate_hz)
    t = np.append(t[t < lead_s + T - 1e-9], lead_s + T)
    tp = np.clip((t - lead_s) / time_scale, 0.0, float(plan.motion_time_s))
    q, qd, qdd = (np.asarray(a, float) for a in plan.sample(tp))
    moving = (t >= lead_s)[:, None]
    qd = np.where(moving, qd / time_scale, 0.0)
    qdd = np.where(moving, qdd / time_scale**2, 0.0)
    pp_q = PiecewisePolynomial.CubicHermite(t, q.T, qd.T)
    pp_qdd = PiecewisePolynomial.FirstOrderHold(t, qdd.T)
    return pp_q, pp_qdd, lead_s + T


def plan_start(plan) -> np.ndarray:
    """q(0) of a plan [rad]."""
    return np.asarray(plan.sample(np.array([0.0]))[0], float).reshape(-1)


class GenesPlan:
    """A minimal plan (the Plan contract: motion_time_s, n_dof, sample(t), method, scenario) made
    straight from a scenario's trajectory family and one gene vector; held at the goal after T0."""

    def __init__(self, scenario, genes, method: str = "genes"):
        self.family = make_family(scenario)
        self.genes = np.asarray(genes, float)
        self.method = method
        self.scenario = scenario.name
        self.motion_time_s = float(self.family.motion_time_s(self.genes[None])[0])
        self.n_dof = self.family.n_dof

    def sample(self, t):
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.motion_time_s)
        return self.family.sample(self.genes, t)
