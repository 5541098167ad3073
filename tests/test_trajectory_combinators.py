"""One time scaling and one concatenation (qmt_drake/trajectory.py) for a JointTrajectory (evaluate,
breakpoints) and for an object that only samples (still accepted: duration_s and sample), each checked
against closed forms (q = sin, a cubic)."""

import numpy as np
import pytest
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.planners import spatial_trajectory as st
from qmt_drake.trajectory import ConcatenatedTrajectory, PolynomialTrajectory, TimeScaledTrajectory


class Sine:
    """Sampling-only (no JointTrajectory): q = a sin(t) on [0, T], two joints."""

    def __init__(self, a=1.0, T=2.0):
        self.a, self.duration_s = a, T

    def sample(self, t):
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.duration_s)[:, None] * np.ones(2)
        return self.a * np.sin(t), self.a * np.cos(t), -self.a * np.sin(t)


def test_the_spatial_names_are_the_planar_classes():
    assert st.TimeScaled is TimeScaledTrajectory and st.SequenceTrajectory is ConcatenatedTrajectory
    assert issubclass(st.RuckigTrajectory, ConcatenatedTrajectory)


def test_time_scaling_a_sampling_only_trajectory():
    k, t = 2.5, np.linspace(0.0, 5.0, 11)
    tr = TimeScaledTrajectory(Sine(), k)
    q, qd, qdd = tr.sample(t)
    u = (t / k)[:, None]
    assert tr.duration_s == 5.0 and tr.k == k and not hasattr(tr, "breakpoints_s")
    np.testing.assert_allclose(q, np.sin(u) * np.ones(2), rtol=0, atol=1e-15)
    np.testing.assert_allclose(qd, np.cos(u) / k * np.ones(2), rtol=0, atol=1e-15)
    np.testing.assert_allclose(qdd, -np.sin(u) / k**2 * np.ones(2), rtol=0, atol=1e-15)
    with pytest.raises(ValueError):
        TimeScaledTrajectory(Sine(), float("nan"))


def test_concatenating_sampling_only_trajectories():
    tr = ConcatenatedTrajectory([Sine(1.0, 2.0), Sine(3.0, 1.0)])
    t = np.array([0.5, 1.999, 2.0, 2.5, 3.0, 4.0])
    q, _, _ = tr.sample(t)
    want = np.where(t < 2.0, np.sin(t), 3.0 * np.sin(np.clip(t - 2.0, 0.0, 1.0)))
    np.testing.assert_allclose(q[:, 0], want, rtol=0, atol=1e-15)
    assert tr.duration_s == 3.0 and list(tr.t_start) == [0.0, 2.0, 3.0]


def test_time_scaling_and_concatenating_joint_trajectories_keep_their_breakpoints():
    """A cubic q = t^3 (one joint) on [0, 1], scaled by 2 and chained after itself."""
    pp = PiecewisePolynomial.CubicWithContinuousSecondDerivatives([0.0, 0.5, 1.0], [[0.0, 0.125, 1.0]], [0.0], [3.0])
    cubic = PolynomialTrajectory(pp)
    slow = TimeScaledTrajectory(cubic, 2.0)
    both = ConcatenatedTrajectory([cubic, slow])
    np.testing.assert_allclose(slow.breakpoints_s, [0.0, 1.0, 2.0])
    np.testing.assert_allclose(both.breakpoints_s, [0.0, 0.5, 1.0, 2.0, 3.0])
    t = np.array([0.25, 1.5, 2.5])
    q, qd, qdd = both.sample(t)
    u = np.array([0.25, 0.25, 0.75])  # the cubic's own time at t
    np.testing.assert_allclose(q[:, 0], u**3, atol=1e-12)
    np.testing.assert_allclose(qd[:, 0], 3 * u**2 / np.array([1.0, 2.0, 2.0]), atol=1e-9)
    np.testing.assert_allclose(qdd[:, 0], 6 * u / np.array([1.0, 4.0, 4.0]), atol=1e-6)
