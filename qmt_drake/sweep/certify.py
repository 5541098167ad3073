"""Certify P(carried) >= target with a 95 % Wilson lower bound, cheaply, and confirm it on fresh cases
(issue 29, Must show).

`failures_allowed(n)`: the most lost cases out of n whose Wilson lower bound (sweep/stats.wilson_interval,
the one implementation) still reaches the target (-1 when even n/n misses: 34/34 gives 0.898 < 0.9).
`test_time_scale`: one time scale, its cases run in batches of the spec's Monte Carlo draws (the first m
draws do not depend on the number of cases, so a batch extends the previous one in the same store);
it stops as soon as the lost cases exceed failures_allowed(n): the lower bound is increasing in the
carried count, so no outcome of the remaining cases could reach the target (sequential testing that
never changes the verdict of the full n). A passing verdict always runs all n cases.
`certify_time_scale`: the smallest time scale (bisection to rel_tol) passing on the search draws, then a
FRESH check with draws of another seed at that scale; if the fresh check fails, the scale is raised by
`raise_step` and checked on yet another seed (each check's draws are seen once), up to fresh_tries.
"""

from __future__ import annotations

import math
from functools import cache

from qmt_drake.errors import QmtInputError
from qmt_drake.sweep.runner import run_sweep
from qmt_drake.sweep.spec import SweepSpec, load_spec
from qmt_drake.sweep.stats import wilson_interval

FRESH_SEED_STEP = 1000003  # sweep/robust.plan_for_success's fresh seed offset (seed + 1000003)


@cache
def failures_allowed(n: int, target: float = 0.9, confidence: float = 0.95) -> int:
    """Largest f with wilson_interval(n - f, n)[0] >= target; -1 when even n/n misses."""
    if n < 1:
        raise QmtInputError(f"cases per point must be >= 1, got {n}")
    f = -1
    while f + 1 <= n and wilson_interval(n - (f + 1), n, confidence)[0] >= target:
        f += 1
    return f


def smallest_cases(target: float = 0.9, confidence: float = 0.95) -> int:
    """The fewest cases n whose n/n reaches the target's lower bound (35 for 0.9 at 95 %)."""
    n = 1
    while wilson_interval(n, n, confidence)[0] < target:
        n += 1
    return n


def sequential_verdict(lost: int, run: int, n: int, target: float = 0.9, confidence: float = 0.95) -> str:
    """'fail' once lost > failures_allowed(n) (no remaining outcome reaches the target), 'pass' when all n
    are run within it, else 'open'."""
    if lost > failures_allowed(n, target, confidence):
        return "fail"
    return "pass" if run >= n else "open"


def _point_spec(spec: SweepSpec, s: float, seed: int, cases: int) -> SweepSpec:
    raw = dict(spec.raw)
    raw["parameters"] = {**(raw.get("parameters") or {}), "time_scale": float(s)}
    raw["monte_carlo"] = {"cases": int(cases), "seed": int(seed)}
    return load_spec(raw, name=f"{spec.name}-seed{seed}-ts{s:.5f}")


def test_time_scale(spec: SweepSpec, s: float, out_dir, *, seed: int, n: int, batch: int, target: float = 0.9,
                    confidence: float = 0.95, client=None, progress=None, **run_kw) -> dict:
    """Sequential test of `spec` at time scale s on the draws of `seed` (module docstring):
    {time_scale, seed, n, run, carried, lost, verdict 'pass'|'fail', stopped_early, ci_low, ci_high (of the
    cases run), best_final_ci_low (the bound if every case not run were carried), lost_indices}."""
    if failures_allowed(n, target, confidence) < 0:
        raise QmtInputError(f"{n} cases cannot certify P >= {target} (n/n gives a Wilson lower bound below it); "
                            f"use at least {smallest_cases(target, confidence)}")
    say = progress or (lambda _m: None)
    m, out = 0, None
    while True:
        m = min(n, m + max(1, int(batch)))
        out = run_sweep(_point_spec(spec, s, seed, m), out_dir, client=client, progress=False, figures=False,
                        **run_kw)
        res = sorted(out["results"], key=lambda r: r.get("index", 0))
        # a case that did not finish (worker died twice) counts as lost, as in sweep/stats.success_rows
        lost = [r.get("index") for r in res if not r.get("held")] + [f.get("index") for f in out["failures"]
                                                                     if "key" in f]
        run = len(res) + out["failed"]
        if out["failed"] and not res:  # every case refused (e.g. a plan file of another scenario): not a loss
            raise QmtInputError(f"{spec.name} x{s:.5f}: no case ran: {out['failures'][0].get('error')}")
        verdict = sequential_verdict(len(lost), run, n, target, confidence)
        say(f"{spec.name} x{s:.5f} seed {seed}: {run - len(lost)}/{run} carried of {n} -> {verdict}")
        if verdict != "open" or m >= n:
            break
    k = run - len(lost)
    lo, hi = wilson_interval(k, run, confidence)
    return {"time_scale": float(s), "seed": int(seed), "n": int(n), "run": int(run), "carried": int(k),
            "lost": len(lost), "verdict": verdict if verdict != "open" else "fail", "stopped_early": run < n,
            "ci_low": lo, "ci_high": hi, "best_final_ci_low": wilson_interval(n - len(lost), n, confidence)[0],
            "failures_allowed": failures_allowed(n, target, confidence), "lost_indices": lost,
            "motion_time_s": _motion(out, s)}


def _motion(out: dict, s: float):
    t = (out["results"] or [{}])[0].get("plan_motion_time_s")
    return None if t is None else float(t) * s


def certify_time_scale(spec: SweepSpec | dict | str, out_dir, *, n_search: int, n_fresh: int, batch: int,
                       s_min: float = 1.0, s_max: float = 1.5, goal: float | None = 1.10, rel_tol: float = 0.01,
                       target: float = 0.9, confidence: float = 0.95, fresh_tries: int = 3,
                       raise_step: float = 0.02, step_up: float = 0.1, client=None, progress=None, **run_kw) -> dict:
    """The smallest time scale of the spec's single plan passing the sequential test on the search draws
    (the spec's seed), then confirmed on fresh draws (module docstring). Search: s_min first, then `goal`
    (answers "within the goal?" directly), then up by factors 1 + step_up until a point passes (or s_max), then
    bisection in log s to rel_tol on the bracket that holds the answer. Returns {found, certified, time_scale (certified scale, or the searched one if no fresh check
    passed), search_scale, points: [...], fresh: [...]}; found False: s_max misses on the search draws."""
    if not isinstance(spec, SweepSpec):
        spec = load_spec(spec)
    if len(spec.plans) != 1 or spec.grid or "time_scale" in spec.distributions or "time_scale" in spec.fixed:
        raise QmtInputError(f"certify: spec '{spec.name}' needs one plan, no grid and no time_scale (it is searched)")
    if not 0 < s_min < s_max:
        raise QmtInputError(f"certify: need 0 < s_min < s_max, got {s_min}, {s_max}")
    kw = dict(target=target, confidence=confidence, client=client, progress=progress, batch=batch, **run_kw)
    points: list[dict] = []
    memo: dict = {}

    def passes(s: float) -> bool:
        key = round(s, 5)
        if key not in memo:
            memo[key] = test_time_scale(spec, s, out_dir, seed=spec.mc_seed, n=n_search, **kw)
            points.append(memo[key])
        return memo[key]["verdict"] == "pass"

    lo, hi = s_min, None
    if passes(s_min):
        hi = s_min
    else:
        if goal is not None and s_min < goal < s_max:
            if passes(goal):
                hi = goal
            else:
                lo = goal
        while hi is None:  # upward in steps of step_up (a passing point costs all its cases), then s_max
            s = min(s_max, lo * (1 + step_up))
            if passes(s):
                hi = s
            elif s >= s_max:
                return {"found": False, "certified": False, "time_scale": None, "search_scale": None,
                        "points": points, "fresh": []}
            else:
                lo = s
        while hi / lo - 1 > rel_tol:
            mid = math.sqrt(lo * hi)
            if passes(mid):
                hi = mid
            else:
                lo = mid
    found = hi
    fresh, s = [], hi
    for j in range(1, fresh_tries + 1):
        f = test_time_scale(spec, s, out_dir, seed=spec.mc_seed + j * FRESH_SEED_STEP, n=n_fresh, **kw)
        fresh.append(f)
        if f["verdict"] == "pass" or s >= s_max:
            break
        s = min(s_max, s * (1 + raise_step))
    ok = bool(fresh and fresh[-1]["verdict"] == "pass")
    return {"found": True, "certified": ok, "time_scale": s if ok else None, "search_scale": found,
            "lost_below": lo if found > s_min else None, "points": sorted(points, key=lambda p: p["time_scale"]),
            "fresh": fresh}
