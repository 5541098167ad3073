"""Where the spatial trajopt puts its path points in the spline's parameter: at their joint chord shares first, and
where those find no trajectory, at the times a rest-to-rest move at constant acceleration covers the shares
(trajopt_core.rest_to_rest_fractions, spatial_methods.plan_trajopt_spatial). The deep totes' ends-only path of
seed 1 (docs/obstacles.md) had no trajectory at its chord shares and has one at those times."""

import numpy as np
import pytest

from qmt_drake.errors import QmtNoPlanError
from qmt_drake.planners import trajopt_core
from qmt_drake.planners.spatial_methods import plan_trajopt_spatial
from qmt_drake.spatial_task import load_spatial_scenario


def test_rest_to_rest_fractions_are_the_times_of_a_constant_acceleration_move():
    # independently: the move integrated numerically (acceleration +4 then -4 over unit time covers unit length)
    t = np.linspace(0.0, 1.0, 200001)
    v = np.where(t <= 0.5, 4.0 * t, 4.0 * (1.0 - t))
    x = np.r_[0.0, np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))]
    shares = np.array([0.0, 0.01, 0.3, 0.5, 0.62, 0.95, 1.0])
    np.testing.assert_allclose(trajopt_core.rest_to_rest_fractions(shares), np.interp(shares, x, t), atol=1e-6)
    f = trajopt_core.rest_to_rest_fractions(shares)
    assert f[0] == 0.0 and f[-1] == 1.0 and np.all(np.diff(f) > 0.0)


def _problem(fractions, Q, ncp=8):
    guess = np.array([[np.interp(x, fractions, Q[:, j]) for j in range(2)] for x in np.linspace(0.0, 1.0, ncp)])
    return trajopt_core.TrajoptProblem(Q, fractions, np.array([-3.0, -2.8]), np.array([3.0, 2.8]), ncp, (0.05, 60.0),
                                       guess, rest_derivatives=2, velocity_limit=np.full(2, 2.0),
                                       acceleration_limit=np.full(2, 10.0))


def test_a_point_near_the_end_in_share_is_reached_at_its_rest_to_rest_time():
    """Two joints from (-1, 0) to (1, 0), then 0.12 rad on joint 2: the middle point at chord share 0.943. At rest at
    the end the last three control points are the end, so there q(0.943) - end = w (P4 - end), w = 0.0038: joint 2
    needs P4 = 0.12 - 0.12 / w = -31 rad, outside [-2.8, 2.8] (closed form), and no spline exists. At the
    rest-to-rest time 0.832 of that share the spline passes every point, at rest at both ends, within the limits."""
    Q = np.array([[-1.0, 0.0], [1.0, 0.0], [1.0, 0.12]])
    c = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))]
    shares = c / c[-1]
    at_shares = trajopt_core.solve(_problem(shares, Q))
    idx, W = trajopt_core.basis_weights(at_shares.basis, float(shares[1]))
    assert idx[0] == 4 and Q[2, 1] + (Q[1, 1] - Q[2, 1]) / W[0][0] < -2.8  # the control point needed, out of range
    assert not at_shares.usable
    f = trajopt_core.rest_to_rest_fractions(shares)
    r = trajopt_core.solve(_problem(f, Q))
    assert r.usable
    b, T = r.trajectory, r.duration_s
    q_at = np.array([b.value(b.start_time() + x * T).ravel() for x in f])
    np.testing.assert_allclose(q_at, Q, atol=1e-6)
    ts = np.linspace(b.start_time(), b.end_time(), 4001)
    qd = np.stack([b.EvalDerivative(t, 1).ravel() for t in ts])
    qdd = np.stack([b.EvalDerivative(t, 2).ravel() for t in ts])
    assert np.abs(qd).max() <= 2.0 + 1e-6 and np.abs(qdd).max() <= 10.0 + 1e-6
    assert np.abs(qd[[0, -1]]).max() < 1e-9 and np.abs(qdd[[0, -1]]).max() < 1e-6


class _Stop(Exception):
    pass


def _unusable(problem):
    return trajopt_core.TrajoptResult(False, "SolutionResult.kInfeasibleConstraints", 13, 1.0, 0.0, None, None, {},
                                      ["a constraint"], [])


@pytest.fixture(scope="module")
def ur5():
    return load_spatial_scenario("ur5-suction-bins")


def test_the_spatial_trajopt_tries_the_rest_to_rest_times_where_the_chord_shares_find_none(monkeypatch, ur5):
    """The solves are stubbed (no SNOPT run): the first program, at the chord shares, ends unusable; the second
    is the same program with the path points at trajopt_core.rest_to_rest_fractions of those shares."""
    seen = []

    def solve(p):
        seen.append(p)
        if len(seen) == 2:
            raise _Stop
        return _unusable(p)

    monkeypatch.setattr(trajopt_core, "solve", solve)
    with pytest.raises(_Stop):
        plan_trajopt_spatial(ur5, clearance_m=0.0)
    Q = ur5.q_path_rad
    c = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))]
    np.testing.assert_array_equal(seen[0].fractions, c / c[-1])
    np.testing.assert_array_equal(seen[1].fractions, trajopt_core.rest_to_rest_fractions(c / c[-1]))
    # the tilt samples follow the fractions: the same count, the same path parameters
    assert [x for _, x in seen[1].path_constraints] == [x for _, x in seen[0].path_constraints]


def test_a_refusal_names_both_placements_and_given_fractions_are_not_replaced(monkeypatch, ur5):
    seen = []
    monkeypatch.setattr(trajopt_core, "solve", lambda p: seen.append(p) or _unusable(p))
    with pytest.raises(QmtNoPlanError, match=r"\(chord shares\) SolutionResult.kInfeasibleConstraints.*; "
                                             r"\(rest-to-rest times\) SolutionResult.kInfeasibleConstraints"):
        plan_trajopt_spatial(ur5, clearance_m=0.0)
    assert len(seen) == 2
    seen.clear()
    given = np.linspace(0.0, 1.0, len(ur5.q_path_rad))
    with pytest.raises(QmtNoPlanError, match=r"\(given\)"):
        plan_trajopt_spatial(ur5, clearance_m=0.0, point_fractions=given)
    assert len(seen) == 1
