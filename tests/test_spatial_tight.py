"""Tight timing of spatial via cubics (planners/spatial_tight.py): the scale against the limits
evaluated by SpatialChain at that scale on the same samples (not through the three-evaluation
interpolation), and against scale_to_hold's bisection; on the suction cup (exact rows), the tray (its
polygon rows inside the circles: refined on the columns) and the magnet, with the arms' joint damping."""

from types import SimpleNamespace

import numpy as np
import pytest

from qmt_drake.limits.suction import GripModel
from qmt_drake.planners.spatial_methods import SpatialTightViaProblem, via_cubic
from qmt_drake.planners.spatial_tight import tight_scales
from qmt_drake.planners.spatial_trajectory import TimeScaled, scale_to_hold
from tests.spatial_fixtures import load_or_skip


@pytest.fixture(scope="module")
def sc():
    return load_or_skip("ur5-suction-bins")


def _max_ratio(sc, traj, t):
    """Largest limit ratio of traj at times t: joint speed/acceleration and every term's columns."""
    q, qd, qdd = traj.sample(t)
    state = sc.chain.evaluate(q, qd, qdd)
    cols = [np.abs(qd) / sc.velocity_limit_rad_s, np.abs(qdd) / sc.acceleration_limit_rad_s2]
    return max(float(np.max(c)) for c in cols + [t_.columns(state) for t_ in sc.terms()])


@pytest.mark.parametrize("name", ["ur5-suction-bins", "panda-tray-cup", "ur5-magnet-part"])
def test_tight_scale_puts_each_shape_exactly_on_its_limits(name):
    sc = load_or_skip(name)
    rng = np.random.default_rng(4)
    G = rng.uniform(0.2, 2.0, (5, len(sc.q_poses_rad) - 1))
    trajs = [via_cubic(sc, g) for g in G]
    k = tight_scales(sc, trajs, samples=400)
    assert np.all(np.isfinite(k)) and np.ptp(k) > 0.2  # shapes that need different scales
    for tr, kk in zip(trajs, k):
        # the limits themselves (the check's joint ratios and the terms' columns, not the toppra rows)
        # on the same path points: held at kk, broken a millionth faster
        for scale, held in ((kk, True), (kk * (1 - 1e-6), False)):
            scaled = TimeScaled(tr, scale)
            ratio = _max_ratio(sc, scaled, np.linspace(0.0, scaled.duration_s, 400))
            assert (ratio <= 1.0 + 1e-12) == held and ratio == pytest.approx(1.0, abs=1e-5)
    # scale_to_hold's bisection on its own time grid (1000 samples at the scale it finds) lands within
    # the closed form's samples' reach: peaks between 400 samples move it by a few 1e-4 at most
    for tr, kk in zip(trajs, k):
        _, kb = scale_to_hold(sc, TimeScaled(tr, 0.2), 1000 / (kk * tr.duration_s), k_max=60.0, rel_tol=1e-7)
        assert abs(0.2 * kb / kk - 1) < 3e-3


def test_no_scale_when_the_grip_cannot_hold_the_part_at_rest(sc):
    weak = SimpleNamespace(chain=sc.chain, velocity_limit_rad_s=sc.velocity_limit_rad_s,
                           acceleration_limit_rad_s2=sc.acceleration_limit_rad_s2,
                           terms=lambda: sc.terms(grip=GripModel(sc.grip.radius_m, 1.0, sc.grip.friction)))
    g = np.ones(len(sc.q_poses_rad) - 1)
    assert np.isinf(tight_scales(weak, [via_cubic(sc, g)])[0])
    assert np.isfinite(tight_scales(sc, [via_cubic(sc, g)])[0])


def test_tight_problem_costs_are_scale_free_and_realised_motions_hold(sc):
    problem = SpatialTightViaProblem(sc)
    g = np.array([0.5, 1.2, 0.5])
    ev = problem.evaluate(np.stack([g, 2.0 * g]))
    assert np.all(ev.feasible) and ev.cost[0] == pytest.approx(ev.cost[1], rel=1e-9)  # a shape, not a time
    T = problem.realize(g)
    assert T.sum() == pytest.approx(ev.cost[0], rel=1e-12) and problem.confirm(g)
    t = np.linspace(0.0, T.sum(), problem.samples)
    assert _max_ratio(sc, via_cubic(sc, T), t) == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("name", ["ur5-suction-bins", "panda-tray-cup"])
def test_batched_scales_equal_one_call_over_the_population(name):
    """SpatialTightViaProblem.scales works in batches of TIGHT_BATCH (a whole population in one call
    held ~4 MB a candidate): each candidate's scale is its own, equal to the bit to one tight_scales call."""
    sc = load_or_skip(name)
    P = SpatialTightViaProblem(sc)
    G = P.lower + (P.upper - P.lower) * np.random.default_rng(3).random((120, len(P.lower)))
    one_call = tight_scales(sc, [via_cubic(sc, g) for g in G], P.samples)
    np.testing.assert_array_equal(P.scales(G), one_call)
    assert np.isfinite(one_call).sum() > 60  # most candidates have a scale: the comparison is not of infs
