"""Success probability with a Wilson score interval, and the per-group tables of a sweep.

The interval is scipy's (`scipy.stats.binomtest(k, n).proportion_ci(method="wilson")`, Wilson 1927):
unlike the normal ("Wald") interval it stays inside [0, 1] and is not empty at k = 0 or k = n
(upper bound z^2 / (n + z^2) at k = 0). tests/test_sweep_stats.py checks those closed forms.
"""

from __future__ import annotations

import math
from collections import defaultdict

from scipy.stats import binomtest, norm


def wilson_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval (lower, upper) of a success probability from k successes in n trials;
    (0, 1) when n = 0."""
    if n < 0 or k < 0 or k > n:
        raise ValueError(f"need 0 <= k <= n, got k={k}, n={n}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    if n == 0:
        return 0.0, 1.0
    ci = binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
    # k = 0 and k = n make the interval touch 0 or 1 exactly (rounding could miss it by 1e-17).
    return (0.0 if k == 0 else float(ci.low), 1.0 if k == n else float(ci.high))


def cases_to_certify(target: float, confidence: float = 0.95) -> int:
    """The fewest trials whose Wilson lower bound can reach `target` at all: every one a success, the
    bound n / (n + z^2), so n >= target z^2 / (1 - target) (0.9: 35 cases, 0.5: 4). Fewer trials can
    never certify it, however the transfers go."""
    z = float(norm.ppf(0.5 + confidence / 2))
    n = max(1, math.ceil(target * z * z / (1.0 - target)))
    return n - 1 if n > 1 and wilson_interval(n - 1, n - 1, confidence)[0] >= target else n  # the rounding


def success_rows(results: list[dict], group_keys=("label",), confidence: float = 0.95) -> list[dict]:
    """Per group (e.g. plan label, or label + a grid parameter): n, carried, p and its interval.
    A case counts as carried when it held (never detached, slip < 1 mm); failed simulations count
    as not carried."""
    groups = defaultdict(list)
    for r in results:
        groups[tuple(_group_value(r, g) for g in group_keys)].append(r)
    rows = []
    for gk, rs in sorted(groups.items(), key=lambda kv: tuple(str(x) for x in kv[0])):
        n = len(rs)
        k = sum(1 for r in rs if r.get("held"))
        lo, hi = wilson_interval(k, n, confidence)
        slips = sorted(r["max_slip_m"] for r in rs if r.get("max_slip_m") is not None)
        row = dict(zip(group_keys, gk))
        row.update(n=n, carried=k, p=k / n, ci_low=lo, ci_high=hi, confidence=confidence,
                   sim_failed=sum(1 for r in rs if r.get("status") == "sim_failed"),
                   # lost without detaching (slip >= 1 mm only), told apart from parts that fell
                   detached=sum(1 for r in rs if r.get("detached_at_s") is not None),
                   lost_by_slip_only=sum(1 for r in rs if not r.get("held") and r.get("detached_at_s") is None
                                         and r.get("status") != "sim_failed"),
                   motion_time_s=_common(r.get("motion_time_s") for r in rs),
                   median_slip_m=slips[len(slips) // 2] if slips else None)
        rows.append(row)
    return rows


def _group_value(r: dict, g: str):
    return r[g] if g in r else (r.get("parameters") or {}).get(g)


def _common(values):
    vals = [v for v in values if v is not None]
    if not vals:
        return None
    return vals[0] if max(vals) - min(vals) <= 1e-12 * max(1.0, abs(vals[0])) else None
