"""Seed 001's cost z = integral_0^T (c1 tau' tau + c2) dt (eq. 3, 7), tau from eq. (1) with gravity,
and its exact gradient with respect to the genes.

Quadrature: trapezoid rule on N equal divisions of [0, T] (N + 1 nodes). The paper divides T into
40 parts (`PAPER_DIVISIONS`) without naming its rule; the trapezoid rule is the natural reading
and is exact for the c2 term. `FINE_DIVISIONS` (2000) gives the integral to ~1e-7 relative on the
paper's examples and is reported beside the 40-division value. In normalised time s = t/T:
z = T sum_k w_k (c1 tau_k' tau_k + c2), sum_k w_k = 1.

The gradient chains the exact inverse-dynamics Jacobians (dynamics.py) through the exact basis
derivatives (fourier.py); tests/test_energy_objective.py checks it against central differences.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qmt_drake.config.registry import ENERGY_TIME, OBJECTIVES, ObjectivePlugin
from qmt_drake.energy.dynamics import VerticalArm, inverse_dynamics_with_gravity
from qmt_drake.energy.fourier import Basis, FourierVelocityFamily, basis
from qmt_drake.errors import QmtInputError

PAPER_DIVISIONS = 40
FINE_DIVISIONS = 2000


def trapezoid_weights(nodes: int) -> np.ndarray:
    """(nodes,) trapezoid weights of nodes equally spaced nodes on [0, 1] (multiply by T for [0, T])."""
    w = np.full(nodes, 1.0 / (nodes - 1))
    w[[0, -1]] *= 0.5
    return w


def energy_time_cost(tau: np.ndarray, T: float, c1: float, c2: float, w: np.ndarray) -> float:
    """z = integral_0^T (c1 tau'tau + c2) dt [N^2 m^2 s] of tau (S, n) [N m] on S equally spaced times,
    by the trapezoid weights w (trapezoid_weights(S)): the one implementation of seed 001's cost, also
    used on every other arm (energy/cross_kind.py); c1 = 1, c2 = 0 gives the energy integral alone."""
    return float(T * (w @ (c1 * np.sum(tau * tau, axis=1) + c2)))


def check_weights(c1: float, c2: float) -> None:
    if not (np.isfinite(c1) and np.isfinite(c2)) or c1 < 0 or c2 < 0:
        raise QmtInputError(f"cost weights c1 = {c1}, c2 = {c2} must be finite and >= 0 "
                            "(the paper takes both positive)")
    if c1 == 0:
        raise QmtInputError("c1 = 0 makes z = c2 T, which has no minimum with T > 0; give c1 > 0")
    if c2 == 0:
        raise QmtInputError("c2 = 0 has no stable solution (seed 001: energy alone makes the "
                            "quasi-static motion with T -> infinity optimal); give c2 > 0")


@dataclass
class EnergyObjective:
    """z and dz/dx on an N-division trapezoid grid for one family and arm."""

    family: FourierVelocityFamily
    arm: VerticalArm
    c1: float = 1.0
    c2: float = 1e5
    divisions: int = PAPER_DIVISIONS

    def __post_init__(self) -> None:
        check_weights(self.c1, self.c2)
        if int(self.divisions) != self.divisions or self.divisions < 2:
            raise QmtInputError(f"time divisions {self.divisions} must be an integer >= 2")
        s = np.linspace(0.0, 1.0, int(self.divisions) + 1)
        self.w = trapezoid_weights(s.size)
        self.B: Basis = basis(s, self.family.m)
        self.evaluations = 0

    def torques(self, x):
        q, qd, qdd = self.family.evaluate_s(x, None, self.B)
        return inverse_dynamics_with_gravity(q, qd, qdd, self.arm, derivatives=False)

    def value(self, x) -> float:
        T = self.family.unpack(x)[2]
        tau = self.torques(x)
        self.evaluations += 1
        return energy_time_cost(tau, T, self.c1, self.c2, self.w)

    def energy_integral(self, x) -> float:
        """integral of tau' tau dt (N^2 m^2 s) alone."""
        T = self.family.unpack(x)[2]
        return energy_time_cost(self.torques(x), T, 1.0, 0.0, self.w)

    def value_and_gradient(self, x):
        """z and dz/dx for the paper's trajectory vector x (2nm+1,)."""
        F, B = self.family, self.B
        a, b, T = F.unpack(x)
        q, qd, qdd = F.evaluate_s(x, None, B)
        tau, Jq, Jqd, Jqdd = inverse_dynamics_with_gravity(q, qd, qdd, self.arm)
        self.evaluations += 1
        h = self.c1 * np.sum(tau * tau, axis=1) + self.c2
        z = float(T * (self.w @ h))
        r = (2.0 * self.c1 * T) * self.w[:, None] * tau            # dz/dtau_k (S, n)
        gq = np.einsum("si,sij->sj", r, Jq)                        # dz/dq_k
        gqd = np.einsum("si,sij->sj", r, Jqd)
        gqdd = np.einsum("si,sij->sj", r, Jqdd)
        da = T * (gq.T @ B.Pa) + gqd.T @ B.Va + (gqdd.T @ B.Aa) / T
        db = T * (gq.T @ B.Pb) + gqd.T @ B.Vb + (gqdd.T @ B.Ab) / T
        # at fixed s: dq/dT = (q - theta0)/T, dqd/dT = 0, dqdd/dT = -qdd/T
        dT = float(self.w @ h) + np.sum(gq * (q - F.theta0)) / T - np.sum(gqdd * qdd) / T
        return z, F.pack(da, db, dT)

    def _tau_jacobian(self, x):
        """dtau_k/dx on the grid, (S, n, 2nm+1), in the gene order of `family.pack`."""
        F, B = self.family, self.B
        _, _, T = F.unpack(x)
        q, qd, qdd = F.evaluate_s(x, None, B)
        tau, Jq, Jqd, Jqdd = inverse_dynamics_with_gravity(q, qd, qdd, self.arm)
        S, n = q.shape
        # dtau_k/da_ij (S, n_out, n_joint, m)
        da = (T * Jq[..., None] * B.Pa[:, None, None, :] + Jqd[..., None] * B.Va[:, None, None, :]
              + Jqdd[..., None] * B.Aa[:, None, None, :] / T)
        db = (T * Jq[..., None] * B.Pb[:, None, None, :] + Jqd[..., None] * B.Vb[:, None, None, :]
              + Jqdd[..., None] * B.Ab[:, None, None, :] / T)
        dT = np.einsum("soi,si->so", Jq, (q - F.theta0) / T) - np.einsum("soi,si->so", Jqdd, qdd / T)
        return np.concatenate([da.reshape(S, n, -1), db.reshape(S, n, -1), dT[..., None]], axis=2)

    def gauss_newton_diagonal(self, x) -> np.ndarray:
        """diag of 2 c1 T sum_k w_k (dtau_k/dx)' (dtau_k/dx): the Jacobi metric for scaled steepest descent (steepest.py,
        metric="diagonal")."""
        Jx = self._tau_jacobian(x)
        wk = 2.0 * self.c1 * self.family.unpack(x)[2] * self.w
        return np.einsum("s,soi->i", wk, Jx * Jx)

    def reduced_value_and_gradient(self, y):
        x, J = self.family.reduced_to_full(y)
        z, g = self.value_and_gradient(x)
        return z, g @ J


OBJECTIVES.register(ObjectivePlugin(ENERGY_TIME, EnergyObjective, scenario_kind=ENERGY_TIME,
                                    summary="z = integral (c1 tau'tau + c2) dt (seed 001)"))
