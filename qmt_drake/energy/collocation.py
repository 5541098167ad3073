"""Free-form reference for seed 001's problem: Drake DirectCollocation on the same cost.

Plant: the continuous MultibodyPlant of the URDF (gravity), input = joint torques (N m).
Cost: integral (c1 u'u + c2) dt over the collocation knots (Drake's running cost, trapezoid on
the knot times), divided by c2 for conditioning (reported back in z units).
Constraints: x(0) = (theta0, 0); qd(T) = 0; FK(q(T)) = X(T); at both ends the torque equals the
static gravity torque (qdd = 0, the Fourier family's eq. 2/6 conditions); time steps in
[1 ms, 50 ms]; 41 knots (the paper's 40 divisions) unless told.

Started from a Fourier optimum (its states and torques at the knots), it measures what the
Fourier family (m terms) gives away against a free trajectory through the same homotopy class.
The reported z is re-evaluated on the collocation trajectory's knots; the collocated trajectory
is a cubic-Hermite state spline with first-order-hold torques, so z between knots is checked by
`z_resampled` (inverse dynamics of the state spline at 2000 points, trapezoid).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue
from pydrake.math import cos, sin
from pydrake.planning import DirectCollocation
from pydrake.solvers import SnoptSolver, SolverOptions
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.energy.dynamics import OHSAKA_URDF, inverse_dynamics_with_gravity, make_plant
from qmt_drake.energy.kinematics import tip_position
from qmt_drake.energy.problem import EnergyProblem


@dataclass
class CollocationResult:
    z: float
    z_resampled: float
    T_s: float
    success: bool
    status: str
    wall_s: float
    t_s: np.ndarray
    q_rad: np.ndarray
    u_Nm: np.ndarray


def solve_collocation(problem: EnergyProblem, x_init, knots: int = 41,
                      major_iterations: int = 400) -> CollocationResult:

    plant = make_plant(str(problem.arm.urdf_path or OHSAKA_URDF))
    ctx = plant.CreateDefaultContext()
    n = plant.num_positions()
    T0 = float(x_init[-1])
    t0 = time.perf_counter()
    dc = DirectCollocation(plant, ctx, knots, 1e-3, 0.05,
                           plant.get_actuation_input_port().get_index())
    prog = dc.prog()
    dc.AddEqualTimeIntervalsConstraints()
    u = dc.input()
    scale = 1.0 / problem.c2
    dc.AddRunningCost(scale * (problem.c1 * u.dot(u) + problem.c2))
    x0 = np.concatenate([problem.theta0, np.zeros(n)])
    prog.AddBoundingBoxConstraint(x0, x0, dc.initial_state())
    xf = dc.final_state()
    prog.AddBoundingBoxConstraint(np.zeros(n), np.zeros(n), xf[n:])
    arm = problem.arm

    def fk(qv):
        if qv.dtype == object:
            phi = np.cumsum(qv)
            return np.array([sum(arm.length_m[i] * cos(phi[i]) for i in range(n)),
                             sum(arm.length_m[i] * sin(phi[i]) for i in range(n))])
        return tip_position(arm, qv)
    prog.AddConstraint(fk, problem.XT, problem.XT, xf[:n])
    g0 = inverse_dynamics_with_gravity(problem.theta0[None], np.zeros((1, n)), np.zeros((1, n)),
                                       arm, derivatives=False)[0]
    prog.AddBoundingBoxConstraint(g0, g0, dc.input(0))

    def end_static(v):  # u(T) - g(q(T)) = 0
        qv, uv = v[:n], v[n:]
        if v.dtype == object:
            qf = ExtractValue(qv).ravel()
            tau, Jq, _, _ = inverse_dynamics_with_gravity(qf[None], np.zeros((1, n)), np.zeros((1, n)), arm)
            dq = ExtractGradient(qv)
            du = ExtractGradient(uv)
            uval = ExtractValue(uv).ravel()
            grad = du - Jq[0] @ dq
            return np.array([AutoDiffXd(uval[i] - tau[0, i], grad[i]) for i in range(n)])
        tau = inverse_dynamics_with_gravity(qv[None], np.zeros((1, n)), np.zeros((1, n)), arm, derivatives=False)[0]
        return uv - tau
    prog.AddConstraint(end_static, np.zeros(n), np.zeros(n), np.concatenate([xf[:n], dc.input(knots - 1)]))
    # initial guess: the Fourier trajectory at the knots
    tk = np.linspace(0.0, T0, knots)
    q, qd, qdd = problem.family.sample(x_init, tk)
    tau = inverse_dynamics_with_gravity(q, qd, qdd, arm, derivatives=False)
    dc.SetInitialTrajectory(PiecewisePolynomial.FirstOrderHold(tk, tau.T),
                            PiecewisePolynomial.FirstOrderHold(tk, np.hstack([q, qd]).T))
    opts = SolverOptions()
    sid = SnoptSolver().solver_id()
    opts.SetOption(sid, "Major optimality tolerance", 1e-7)
    opts.SetOption(sid, "Major iterations limit", int(major_iterations))
    res = SnoptSolver().Solve(prog, None, opts)
    wall = time.perf_counter() - t0
    xs = dc.ReconstructStateTrajectory(res)
    us = dc.ReconstructInputTrajectory(res)
    times = dc.GetSampleTimes(res)
    U = us.vector_values(times).T
    z = float(np.trapezoid(problem.c1 * np.sum(U * U, axis=1) + problem.c2, times))
    tt = np.linspace(times[0], times[-1], 2001)
    qs = xs.vector_values(tt)[:n].T
    qds = xs.vector_values(tt)[n:].T
    qdds = xs.derivative(1).vector_values(tt)[n:].T
    taus = inverse_dynamics_with_gravity(qs, qds, qdds, arm, derivatives=False)
    z_res = float(np.trapezoid(problem.c1 * np.sum(taus * taus, axis=1) + problem.c2, tt))
    return CollocationResult(z, z_res, float(times[-1]), bool(res.is_success()),
                             str(res.get_solution_result()), wall, times,
                             xs.vector_values(times)[:n].T, U)
