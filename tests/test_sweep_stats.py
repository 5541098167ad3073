"""Wilson score interval against scipy's implementation and closed forms."""

import math

import pytest
from scipy.stats import norm

from qmt_drake.sweep.stats import success_rows, wilson_interval


@pytest.mark.parametrize("k, n", [(1, 10), (5, 10), (197, 200), (3, 7)])
@pytest.mark.parametrize("conf", [0.9, 0.95, 0.99])
def test_matches_wilsons_closed_form(k, n, conf):
    """Wilson (1927): centre (p + z^2/2n) / (1 + z^2/n), half-width z / (1 + z^2/n) sqrt(p(1-p)/n + z^2/4n^2)."""
    z = norm.ppf(0.5 + conf / 2)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    lo, hi = wilson_interval(k, n, conf)
    assert lo == pytest.approx(centre - half, abs=1e-12)
    assert hi == pytest.approx(centre + half, abs=1e-12)


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
