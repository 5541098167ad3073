"""Time-optimal end of the energy-time front (energy/time_optimal.py): TOPP-RA with gravity and
joint torque limits on the path of a Fourier optimum, checked by sampling, against the best uniform
time scaling of the same path and against Drake's own Toppra."""

import numpy as np
import pytest

from qmt_drake.energy.dynamics import OHSAKA_URDF, inverse_dynamics_with_gravity, make_plant
from qmt_drake.energy.multistart import initial_end_posture, initial_reduced_genes
from qmt_drake.energy.nlp import solve_nlp
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.energy.time_optimal import time_optimal_on_path
from qmt_drake.errors import QmtInputError


@pytest.fixture(scope="module")
def optimum():
    E = get_experiment("ohsaka-fig4")
    P = E.problem(m=3)
    r = solve_nlp(P, initial_reduced_genes(P, initial_end_posture(P, (1, 1, -1))), "snopt")
    assert r.success
    return E, P, r.x


def _uniform_scaling_time(P, x, lim):
    """Smallest T' such that the Fourier trajectory played in T' keeps |tau| <= lim (bisection)."""
    s = np.linspace(0, 1, 4001)
    q, qd, qdd = P.family.evaluate_s(x, s)

    def ok(k):  # k = T'/T
        return np.all(np.abs(inverse_dynamics_with_gravity(q, qd / k, qdd / k**2, P.arm, derivatives=False)) <= lim)
    lo, hi = 0.05, 20.0
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi * x[-1]


def test_toppra_with_gravity_keeps_the_limits_and_beats_uniform_scaling(optimum):
    E, P, x = optimum
    lim = np.asarray(E.torque_limit_Nm)
    r = time_optimal_on_path(P, x, lim)
    assert "Success" in r.return_code
    assert r.peak_ratio <= 1.0 + 1e-9          # checked on 20001 samples
    assert r.peak_ratio > 0.999                 # a limit binds: nothing left on the table
    assert r.slowdown < 1.06                    # toppra's gridpoint enforcement is close
    T_uniform = _uniform_scaling_time(P, x, lim)
    assert r.T_s < T_uniform                    # optimal timing beats the best uniform one
    assert r.energy_N2m2s > 0 and np.all(r.peak_torque_Nm <= lim * (1 + 1e-9))


def test_matches_drakes_toppra(optimum):
    from pydrake.multibody.optimization import Toppra
    from pydrake.trajectories import PiecewisePolynomial
    E, P, x = optimum
    lim = np.asarray(E.torque_limit_Nm)
    ours = time_optimal_on_path(P, x, lim, grid_points=400)
    s = np.linspace(0, 1, 801)
    q, qd, _ = P.family.evaluate_s(x, s)
    pp = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(s, q.T, (x[-1] * qd[0])[:, None],
                                                                  (x[-1] * qd[-1])[:, None])
    plant = make_plant(str(OHSAKA_URDF))
    top = Toppra(pp, plant, np.linspace(0, 1, 400))
    top.AddJointTorqueLimit(-lim, lim)
    s_of_t = top.SolvePathParameterization()
    assert s_of_t is not None
    T_drake = s_of_t.end_time() - s_of_t.start_time()
    assert ours.raw_T_s == pytest.approx(T_drake, rel=5e-3)


def test_limits_below_gravity_are_refused(optimum):
    E, P, x = optimum
    with pytest.raises(QmtInputError, match="cannot even hold the arm still"):
        time_optimal_on_path(P, x, [5.0, 5.0, 5.0])
    with pytest.raises(QmtInputError, match="positive"):
        time_optimal_on_path(P, x, [200.0, -1.0, 200.0])
