"""Plans survive a save and load: the same trajectory, the same re-check."""

import numpy as np
import pytest

from qmt_drake.plan import family_plan, make_plan
from qmt_drake.plan_files import load_plan
from qmt_drake.trajectory import FamilyTrajectory, JointTrajectory


class _Opaque(JointTrajectory):
    """A family trajectory hidden behind the generic interface, so it is stored as samples."""

    def __init__(self, family, genes):
        self.inner = FamilyTrajectory(family, genes)
        self.duration_s = self.inner.duration_s
        self.breakpoints_s = self.inner.breakpoints_s
        self.n_dof = self.inner.n_dof

    def evaluate(self, t_s, t_piece_s):
        return self.inner.evaluate(t_s, t_piece_s)


@pytest.mark.parametrize("name", ["thesis-ch3", "thesis-ch4"])
def test_sampled_plan_round_trip_keeps_jumps_and_peaks(problems, tmp_path, name):
    P = problems[name]
    g = P.genes_vector(P.scenario.reported["genes"])
    orig = make_plan(P.scenario, "opaque", _Opaque(P.family, g))
    assert type(orig.trajectory) is _Opaque
    path = tmp_path / "p.json"
    orig.write_json(path)
    back = load_plan(path, scenario=P.scenario)
    assert back.motion_time_s == pytest.approx(orig.motion_time_s, abs=1e-12)
    assert back.check.peak_moment_ratio == pytest.approx(orig.check.peak_moment_ratio, rel=1e-6)
    np.testing.assert_allclose(back.check.peak_motor_torque_Nm, orig.check.peak_motor_torque_Nm,
                               rtol=1e-6)
    t = np.linspace(0, orig.motion_time_s, 997)
    for a, b in zip(orig.sample(t), back.sample(t)):
        np.testing.assert_allclose(b, a, atol=1e-6 * max(1.0, np.abs(a).max()))


def test_family_plan_round_trip(problems, tmp_path):
    P = problems["thesis-ch4"]
    p = family_plan(P, P.genes_vector(P.scenario.reported["genes"]), "thesis")
    p.write_json(tmp_path / "f.json")
    back = load_plan(tmp_path / "f.json")
    assert back.genes == p.genes and back.check == p.check


def test_sampling_outside_the_plan_holds_its_end_states():
    """Before t = 0 the start, after T the goal, at rest: never the polynomial extrapolated."""
    import numpy as np

    from qmt_drake.planners import plan_with
    from qmt_drake.transfer_scenario import load_scenario
    plan = plan_with("thesis", load_scenario("thesis-ch4"))
    T = plan.motion_time_s
    q, qd, qdd = plan.sample(np.array([-1.0, -1e-3, 0.0, T, T + 1e-3, T + 5.0]))
    q0, qT = plan.sample(np.array([0.0]))[0][0], plan.sample(np.array([T]))[0][0]
    np.testing.assert_array_equal(q[:3], np.tile(q0, (3, 1)))
    np.testing.assert_array_equal(q[3:], np.tile(qT, (3, 1)))
    assert not np.any(qd[[0, 1, 4, 5]]) and not np.any(qdd[[0, 1, 4, 5]])
