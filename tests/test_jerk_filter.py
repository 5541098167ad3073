"""`--jerk-limited`: TOPP-RA's path timing through one or two box FIRs (qmt_drake/jerk_filter.py), in closed
form; its jerk within the limits between samples, its duration, its exact plan file; the old slow-down kept
as the fallback (qmt_drake/jerk.py)."""

import json

import numpy as np
import pytest
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.export import export_plan
from qmt_drake.jerk import filter_base, is_c2, jerk_limited_plan, peak_jerk
from qmt_drake.jerk_filter import FilteredTiming, exact_peak_jerk, joint_jerk
from qmt_drake.plan_files import load_plan
from qmt_drake.planners.spatial_trajectory import TimeScaled, check
from tests.spatial_fixtures import load_or_skip, shipped_toppra

N_GRID = 300


@pytest.fixture(scope="module")
def sc():
    return load_or_skip("ur5-suction-bins")


@pytest.fixture(scope="module")
def plan(sc):
    return shipped_toppra("ur5-suction-bins", N_GRID)


@pytest.fixture(scope="module")
def base(plan):
    return plan.trajectory.inner if isinstance(plan.trajectory, TimeScaled) else plan.trajectory


@pytest.fixture(scope="module")
def jl(sc, plan):
    return jerk_limited_plan(sc, plan)


def _away_from_breakpoints(f, n, margin):
    t = np.linspace(0.0, f.duration_s, n)[1:-1]
    bp = f.breakpoints_s
    return t[np.min(np.abs(t[:, None] - bp[None, :]), axis=1) > margin]


@pytest.mark.parametrize("windows", [(0.05,), (0.06, 0.011)])
def test_closed_form_derivatives_match_finite_differences_of_the_exact_position(base, windows):
    f = FilteredTiming(base, windows)
    h = 1e-5
    t = _away_from_breakpoints(f, 801, 3 * h)
    assert t.size > 100
    lo, mid, hi = (f.timing(t + d) for d in (-h, 0.0, h))
    for m in range(3):  # s_f', s_f'', s_f''' against central differences of the order below
        fd = (hi[m] - lo[m]) / (2 * h)
        scale = np.abs(mid[m + 1]).max()
        assert np.abs(fd - mid[m + 1]).max() <= 1e-5 * scale, m
    q = [f.sample(t + d) for d in (-h, 0.0, h)]  # the joints: qd, qdd and the jerk likewise
    for m in range(2):
        fd = (q[2][m] - q[0][m]) / (2 * h)
        assert np.abs(fd - q[1][m + 1]).max() <= 1e-5 * np.abs(q[1][m + 1]).max(), m
    fd = (q[2][2] - q[0][2]) / (2 * h)
    jerk = f.jerk(t)
    assert np.abs(fd - jerk).max() <= 1e-5 * np.abs(jerk).max()


def test_the_position_is_the_window_average_of_toppras_own_timing(base):
    # the base's s(t) inverts ToppraTrajectory.time_at (its own code), and s_f is its mean over the window
    t = np.linspace(0.0, base.duration_s, 397)
    f = FilteredTiming(base, 0.05)
    np.testing.assert_allclose(base.time_at(f.base_position(t)), t, atol=1e-9)
    x = np.linspace(-0.05, 0.0, 20001)
    for tk in (0.3, 1.0, f.duration_s - 0.01):
        s = f.base_position(tk + x)
        avg = np.sum(0.5 * (s[1:] + s[:-1]) * np.diff(x)) / 0.05  # trapezoid
        assert f.timing(tk)[0][0] == pytest.approx(avg, abs=1e-9)
    # at rest at both ends, at the path's ends
    s, v, a, _ = f.timing([0.0, f.duration_s])
    assert s[0] == base.grid[0] and s[1] == pytest.approx(base.grid[-1], abs=1e-12)
    assert np.all(np.abs(v) < 1e-12) and np.all(np.abs(a) < 1e-9)


def test_jerk_limited_plan_keeps_the_jerk_between_samples_and_every_limit(sc, plan, jl):
    info = jl.info
    assert info["jerk_limited"] == "box_filter" and info["peak_jerk_ratio_before"] > 50.0
    assert info["peak_jerk_ratio"] <= 1.0
    for rate in (sc.recheck_rate_hz, 10 * sc.recheck_rate_hz):  # sampled, and at 10x the re-check rate
        assert peak_jerk(sc, jl.trajectory, rate)["peak_jerk_ratio"] <= info["peak_jerk_ratio"] * (1 + 1e-9)
    # the exact jerk on a 100 kHz grid never exceeds the one the plan states
    t = np.linspace(0.0, jl.duration_s, int(jl.duration_s * 1e5))
    dense = np.abs(joint_jerk(jl.trajectory, t)).max(axis=0) / sc.jerk_limit_rad_s3
    assert dense.max() <= info["peak_jerk_ratio"] * (1 + 1e-9)
    assert jl.recheck["max"] <= 1.0 and jl.feasible and np.max(jl.pose_error) < 1e-9
    assert check(sc, jl.trajectory, 10 * sc.recheck_rate_hz)["max_timed"] <= 1.0 + 1e-6


def test_duration_is_the_scaled_toppra_time_plus_the_windows(plan, base, jl):
    K, windows = jl.hold_scale, jl.info["jerk_filter_windows_s"]
    assert jl.duration_s == pytest.approx(base.duration_s * K + sum(windows), rel=1e-12)
    assert K == pytest.approx(plan.hold_scale * jl.info["jerk_time_scale"], rel=1e-12)
    assert len(windows) in (1, 2) and all(w > 0 for w in windows)


def test_several_times_faster_than_slowing_the_plan(sc, plan, jl):
    # the old --jerk-limited (jerk.slowed_plan: 11.1x on the full grid) needs a k over 4x this plan's ratio:
    # the plan played that much slower still reads over the jerk limit at the re-check rate
    k4 = 4.0 * jl.duration_s / plan.duration_s
    assert peak_jerk(sc, TimeScaled(plan.trajectory, k4), sc.recheck_rate_hz)["peak_jerk_ratio"] > 1.0
    assert jl.duration_s < 1.3 * plan.duration_s


def test_plan_file_reloads_exactly_and_exports(sc, jl, tmp_path):
    jl.write_json(tmp_path / "jl.json")
    d = json.loads((tmp_path / "jl.json").read_text())
    assert d["rebuild"]["kind"] == "time_scaled" and d["rebuild"]["inner"]["kind"] == "filtered_toppra"
    again, twice = (load_plan(tmp_path / "jl.json", sc) for _ in range(2))
    assert isinstance(again.trajectory.inner, FilteredTiming)
    assert again.trajectory.inner.windows_s == jl.trajectory.inner.windows_s and again.hold_scale == jl.hold_scale
    t = np.linspace(0.0, jl.duration_s, 3001)
    for a, b, c in zip(jl.trajectory.sample(t), again.trajectory.sample(t), twice.trajectory.sample(t)):
        np.testing.assert_array_equal(b, c)  # the file's numbers (repr) rebuild the same trajectory bit for bit
        assert np.abs(a - b).max() <= 1e-12 * max(1.0, np.abs(a).max())  # = the plan: its path's cubic to rounding
    assert again.duration_s == jl.duration_s
    assert again.recheck["max"] == pytest.approx(jl.recheck["max"], abs=1e-9)
    rep = export_plan(sc, again, "csv", 1000.0, tmp_path / "s.csv", "cubic")
    assert rep["n_samples"] > 0 and rep["plan_peak_jerk"]["peak_jerk_ratio"] <= 1.0
    for bad in ([-0.01], [], "wide", [0.01, 0.01, 0.01]):  # an edited file is refused in one line
        d["rebuild"]["inner"]["windows_s"] = bad
        (tmp_path / "bad.json").write_text(json.dumps(d))
        with pytest.raises(QmtInputError, match="cannot rebuild its trajectory"):
            load_plan(tmp_path / "bad.json", sc)


def test_exact_peak_reads_both_sides_of_a_jump(sc, base):
    f = FilteredTiming(base, 0.02)  # one box: s_f''' steps at every grid time and its shift
    exact = exact_peak_jerk(sc, f, 100.0)["peak_jerk_ratio"]
    assert exact >= peak_jerk(sc, f, 1e5)["peak_jerk_ratio"] * (1 - 1e-9)


def test_the_filter_is_not_used_where_it_cannot_bound_the_jerk(sc, plan):
    s = np.array([0.0, 1.0, 2.5, 3.0])
    q = np.array([[0.0, 1.0, 0.2, 0.9], [0.0, -1.0, 0.5, 0.1]])
    z = np.zeros(2)
    assert is_c2(PiecewisePolynomial.CubicWithContinuousSecondDerivatives(s, q, z, z))
    assert not is_c2(PiecewisePolynomial.CubicShapePreserving(s, q, zero_end_point_derivatives=True))
    base, why = filter_base(TimeScaled(TimeScaled(plan.trajectory, 1.0), 1.0))  # not one TOPP-RA timing
    assert base is None and "not one TOPP-RA timing" in why
    base, k = filter_base(plan.trajectory)
    assert base is plan.trajectory.inner and k == plan.hold_scale
