"""SNOPT, IPOPT and steepest descent on seed 001's problems (small, fast cases)."""

import numpy as np
import pytest

from qmt_drake.energy.experiments import paper_initial_x
from qmt_drake.energy.kinematics import tip_position
from qmt_drake.energy.multistart import (
    PATTERNS,
    initial_end_posture,
    initial_reduced_genes,
    run_multistart,
    travel_pattern,
)
from qmt_drake.energy.nlp import solve_nlp
from qmt_drake.energy.objective import EnergyObjective
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.energy.steepest import restore_endpoint, steepest_descent


@pytest.fixture(scope="module")
def fig3():
    return get_experiment("ohsaka-fig3").problem()


def test_snopt_local_optimum_is_feasible_and_confirmed_by_ipopt(fig3):
    P = fig3
    y0 = initial_reduced_genes(P, initial_end_posture(P, (-1, 1, -1)))
    r = solve_nlp(P, y0, "snopt")
    assert r.success
    assert r.z < P.objective.reduced_value_and_gradient(y0)[0]
    np.testing.assert_allclose(tip_position(P.arm, P.family.end_posture(r.x)), P.XT, atol=1e-9)
    # sample the optimum between grid nodes too: boundary values and the end point
    q, qd, qdd = P.family.sample(r.x, np.linspace(0, r.x[-1], 997))
    np.testing.assert_allclose(q[0], P.theta0, atol=1e-12)
    assert np.abs(qd[[0, -1]]).max() < 1e-10 and np.abs(qdd[[0, -1]]).max() < 1e-8
    # the 40-division z is close to the fine-grid z at the optimum (smooth trajectory)
    fine = EnergyObjective(P.family, P.arm, P.c1, P.c2, 2000).value(r.x)
    assert abs(fine - r.z) < 0.01 * r.z
    # IPOPT warm-started at SNOPT's point stays there (same KKT point)
    r2 = solve_nlp(P, r.y, "ipopt")
    assert r2.success and abs(r2.z - r.z) <= 1e-6 * r.z


def test_steepest_descent_reaches_snopts_optimum_fig2():
    E = get_experiment("ohsaka-fig2")
    P = E.problem(m=3)
    x0 = restore_endpoint(P, paper_initial_x(P, {}, E.fixed_T_s))  # all a, b = 0, then step III
    sn = solve_nlp(P, P.family.full_to_reduced(x0), "snopt")
    sd = steepest_descent(P, x0, max_iter=2000)
    assert sd.converged, sd.stop_reason
    assert abs(sd.z - sn.z) <= 1e-3 * sn.z
    assert sd.paper_rule_iteration == sd.iterations and sd.paper_rule_z == sd.z
    # a stricter rule of the same kind runs on from there (same iterates) and gets closer
    strict = steepest_descent(P, x0, max_iter=4000, rel_tol=1e-6)
    assert strict.converged and strict.iterations > sd.iterations
    assert strict.paper_rule_iteration == sd.iterations and strict.paper_rule_z == sd.z
    assert abs(strict.z - sn.z) <= abs(sd.z - sn.z)
    np.testing.assert_allclose(P.family.end_posture(sd.x), [np.pi / 2, 0, 0], atol=1e-9)


def test_steepest_descent_keeps_constraints(fig3):
    P = fig3
    x0 = P.family.reduced_to_full(initial_reduced_genes(P, initial_end_posture(P, (1, 1, 1))))[0]
    sd = steepest_descent(P, x0, max_iter=40)
    assert sd.iterations == 40 and sd.z < sd.history_z[0]
    assert np.all(np.diff(sd.history_z) <= 0)
    np.testing.assert_allclose(tip_position(P.arm, P.family.end_posture(sd.x)), P.XT, atol=1e-11)
    np.testing.assert_allclose(P.family.accel_residual(sd.x), 0, atol=1e-11)


def test_multistart_covers_eight_patterns(fig3):
    P = fig3
    for p in PATTERNS:
        thT = initial_end_posture(P, p)
        assert travel_pattern(P.theta0, thT) == p
        np.testing.assert_allclose(tip_position(P.arm, thT), P.XT, atol=1e-9)
    # every start solves (m = 3 keeps the test short)
    P3 = get_experiment("ohsaka-fig3").problem(m=3)
    res = run_multistart(P3, "snopt")
    assert len(res) == 8 and all(r.success for r in res)
    assert all(np.linalg.norm(tip_position(P3.arm, P3.family.end_posture(r.x)) - P3.XT) < 1e-9 for r in res)
