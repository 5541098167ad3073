"""Wilson score interval against scipy's implementation and closed forms."""

import math

import pytest
from scipy.stats import binomtest, norm

from qmt_drake.sweep.stats import success_rows, wilson_interval


@pytest.mark.parametrize("k, n", [(0, 10), (1, 10), (5, 10), (10, 10), (197, 200), (200, 200), (3, 7)])
@pytest.mark.parametrize("conf", [0.9, 0.95, 0.99])
def test_matches_scipy(k, n, conf):
    ci = binomtest(k, n).proportion_ci(confidence_level=conf, method="wilson")
    lo, hi = wilson_interval(k, n, conf)
    assert lo == pytest.approx(ci.low, abs=1e-12)
    assert hi == pytest.approx(ci.high, abs=1e-12)


def test_closed_form_at_zero_and_all():
    z = norm.ppf(0.975)
    for n in (1, 7, 50, 200):
        assert wilson_interval(0, n)[1] == pytest.approx(z * z / (n + z * z))
        assert wilson_interval(n, n)[0] == pytest.approx(n / (n + z * z))
        assert wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0


def test_bad_counts():
    with pytest.raises(ValueError):
        wilson_interval(3, 2)
    assert wilson_interval(0, 0) == (0.0, 1.0)


def test_rows_group_and_count_failed_simulations_as_lost():
    rs = ([{"label": "a", "held": True, "max_slip_m": 1e-4, "parameters": {"s": 1.0}}] * 3
          + [{"label": "a", "held": False, "status": "sim_failed", "parameters": {"s": 1.0}}]
          + [{"label": "b", "held": True, "max_slip_m": 2e-4, "parameters": {"s": 2.0}}])
    rows = success_rows(rs, ("label", "s"))
    assert [(r["label"], r["s"], r["n"], r["carried"], r["sim_failed"]) for r in rows] == [
        ("a", 1.0, 4, 3, 1), ("b", 2.0, 1, 1, 0)]
    assert rows[0]["p"] == 0.75 and rows[0]["ci_low"] < 0.75 < rows[0]["ci_high"]
    assert not math.isnan(rows[0]["median_slip_m"])


def test_rows_tell_detachment_from_slip_only_losses():
    rs = [{"label": "a", "held": True, "max_slip_m": 1e-4, "detached_at_s": None},
          {"label": "a", "held": False, "max_slip_m": 0.3, "detached_at_s": 0.4},
          {"label": "a", "held": False, "max_slip_m": 1.2e-3, "detached_at_s": None},
          {"label": "a", "held": False, "status": "sim_failed"}]
    (row,) = success_rows(rs)
    assert (row["n"], row["carried"], row["detached"], row["lost_by_slip_only"], row["sim_failed"]) == (4, 1, 1, 1, 1)
