"""`retime` of a DENSE joint path (a stream sampled from rest to rest, as a controller's log or a 125 Hz
export has it): TOPP-RA's grid (planners/spatial_toppra.path_grid) holds the path's knots and splits its
short pieces, so the dense path is timed as fast as the same geometry given sparsely and holds its limits
between the samples; on the old uniform grid the same path broke its limits (the re-check then slowed the
whole plan), and more grid points no longer make it slower. The planar retime uses the same grid."""

import numpy as np
import pytest
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake import load_scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.planners import plan_with
from qmt_drake.planners.spatial_toppra import GRID_CUBIC_TOL, joint_path, path_grid, plan_toppra
from qmt_drake.planners.spatial_trajectory import ToppraTrajectory, check
from qmt_drake.retime import retime_path
from qmt_drake.retime_planar import retime_planar_path
from tests.spatial_fixtures import load_or_skip
from tests.test_retime import HAND_PATH


def stream(Q_sparse, n: int) -> np.ndarray:
    """(n, dof) samples of the C2 path through Q_sparse at n evenly spaced times of a rest-to-rest time law
    (s = L (3 tau^2 - 2 tau^3)): crowded where the motion leaves and reaches rest, as a sampled stream is."""
    pp = joint_path(Q_sparse)
    tau = np.linspace(0.0, 1.0, n)
    return pp.vector_values(pp.end_time() * (3 * tau ** 2 - 2 * tau ** 3)).T


def _third(pp):
    s = np.asarray(pp.get_segment_times())
    return np.abs(pp.derivative(3).vector_values(0.5 * (s[:-1] + s[1:]))).max(axis=0)


def test_the_grid_holds_every_knot_and_splits_short_pieces_only_where_needed():
    dense = joint_path(stream(HAND_PATH, 130))
    g = path_grid(dense, 1000)
    knots = np.asarray(dense.get_segment_times())
    assert np.all(np.isin(knots, g)) and g[0] == knots[0] and g[-1] == knots[-1] and np.all(np.diff(g) > 0)
    assert np.diff(g).max() <= (knots[-1] - knots[0]) / 999 * (1 + 1e-9)  # never coarser than the uniform grid
    piece = np.searchsorted(knots, 0.5 * (g[:-1] + g[1:])) - 1
    assert np.max(_third(dense)[piece] * np.diff(g) ** 2) <= GRID_CUBIC_TOL * (1 + 1e-9)
    assert _third(dense).max() * ((knots[-1] - knots[0]) / 999) ** 2 > 1e3 * GRID_CUBIC_TOL  # uniform: far off
    # a sparse path (the hand-written 5 waypoints) keeps the uniform grid, bit for bit: its plans do not move
    sparse = joint_path(HAND_PATH)
    np.testing.assert_array_equal(path_grid(sparse, 1000), np.linspace(sparse.start_time(), sparse.end_time(), 1000))
    assert len(path_grid(sparse, 1000, "knots")) > 1000
    # a piecewise linear path (q''' = 0) on "knots": its knots, spaced no wider than the uniform grid
    line = PiecewisePolynomial.FirstOrderHold([0.0, 0.5, 2.0], np.array([[0.0, 1.0, 3.0]]))
    g = path_grid(line, 11, "knots")
    assert 0.5 in g and len(g) == 12 and np.diff(g).max() <= 0.2 + 1e-12
    with pytest.raises(QmtInputError, match="grid 'fine'"):
        path_grid(sparse, 1000, "fine")
    with pytest.raises(QmtInputError, match="at least 2 points"):
        path_grid(sparse, 1)


@pytest.fixture(scope="module")
def sc():
    return load_or_skip("ur5-suction-bins")


@pytest.fixture(scope="module")
def dense_and_sparse(sc):
    return retime_path(sc, stream(HAND_PATH, 130)), retime_path(sc, HAND_PATH)


def test_a_dense_stream_is_timed_as_fast_as_its_sparse_path_and_holds_between_samples(sc, dense_and_sparse):
    dense, sparse = dense_and_sparse
    assert dense.info["path_waypoints"] == 130 and dense.info["grid_points"] > 1000
    assert abs(dense.duration_s / sparse.duration_s - 1.0) < 0.01  # same geometry, same time (within 1 %)
    assert dense.hold_scale < 1.005  # the re-check barely slows it
    assert dense.feasible and dense.recheck["max"] <= 1.0
    # an independent sampling at 10x the re-check rate, local maxima refined: the limits hold between samples
    assert check(sc, dense.trajectory, 10 * sc.recheck_rate_hz, refine=True)["max_timed"] <= 1.0


def test_the_uniform_grid_misses_the_dense_paths_short_pieces(sc, dense_and_sparse):
    # the defect this grid fixes: TOPP-RA on 1000 evenly spaced points breaks a limit by 25 % where the
    # stream's samples crowd at its ends (the re-check then slowed the whole plan, x1.12 here, x1.6 on TALOS)
    pp = joint_path(stream(HAND_PATH, 130))
    r = plan_toppra(pp, sc.chain, velocity_limit=sc.velocity_limit_rad_s, acceleration_limit=sc.acceleration_limit_rad_s2,
                    terms=sc.terms(), grid="uniform")
    raw = ToppraTrajectory(pp, r["grid"], r["sd"])
    assert check(sc, raw, sc.recheck_rate_hz)["max_timed"] > 1.1
    assert check(sc, dense_and_sparse[0].trajectory, sc.recheck_rate_hz)["max_timed"] <= 1.0


def test_more_grid_points_do_not_make_a_dense_path_slower(sc, dense_and_sparse):
    finer = retime_path(sc, stream(HAND_PATH, 130), n_grid=3000)
    assert finer.duration_s <= dense_and_sparse[0].duration_s * (1 + 1e-4)
    assert finer.recheck["max"] <= 1.0


def test_a_planar_dense_stream_is_not_slowed_by_the_recheck_and_holds_at_50_khz():
    # the planar retime (retime_planar.py) times its path on the same grid: the thesis plan's 125 Hz stream
    # (216 samples) was slowed x1.52 to hold on the uniform grid (2.3564 s, `qmt-drake retime thesis-ch4 --path s.csv`)
    sc = load_scenario("thesis-ch4")
    base = plan_with("thesis", sc)
    Q = base.sample(np.r_[np.arange(0.0, base.motion_time_s, 1 / 125), base.motion_time_s])[0]
    p = retime_planar_path(sc, Q)
    assert p.feasible and p.extra["grid_points"] > 1000
    assert p.extra.get("slowdown_factor", 1.0) < 1.005
    assert retime_planar_path(sc, Q, n_grid=5000).motion_time_s <= p.motion_time_s * (1 + 1e-4)
    t = np.linspace(0.0, p.motion_time_s, int(p.motion_time_s * 50_000) + 1)  # 5x the re-check's 10 kHz
    q, qd, qdd = p.sample(t)
    cols = sc.limit_set.columns(q, qd, qdd)[:, sc.limit_set.ratio_mask]
    assert cols.max() <= 1.0 + 1e-6
