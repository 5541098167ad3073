"""The one search over a scale: "slow it until it holds" and "slow it until it is carried".

`search_scale(holds, lo, hi, ...)` brackets and bisects a scale x on which `holds(x)` (the caller's
predicate: a limit re-check, a co-simulation, a Monte Carlo sweep) is monotone: on a time scale k
(the plan played k times slower) the slow end holds, safe="above"; on a limit scale lam (Ruckig's
acceleration limit times lam) the small end holds, safe="below". Its named options are the variants
whose published numbers depend on them (each caller's probed sequence is kept to the bit):

- midpoint: "arithmetic" (lo + hi) / 2 or "geometric" sqrt(lo hi);
- when to stop bisecting: hi / lo - 1 <= rel_tol (default), a fixed number of `steps`, a caller's
  `done(lo, hi)`; `max_probes` caps every evaluation of the search (bracketing included);
- ends: probe the bracket's ends first, in the order given (("lo", "hi"): the planned scale first,
  ("hi", "lo"): first whether the slowest holds at all); a fast end that holds ends the search there,
  a slow end that fails ends it with nothing holding;
- grow: no bracket yet, only a start with a known verdict (`Grow`): step from it by a factor (or a
  table of factors from the start) until the verdict flips (toward holding from a failing start,
  away from it from a holding one).

Used by the planar baselines' re-check (planners/baselines/finish.py), Ruckig's limit scale (ruckig_plan.py;
spatial: planners/spatial_methods.ruckig_segments), the energy-time TOPP-RA end (energy/time_optimal.py), the
spatial --hold / scale_to_hold (`smallest_holding_scale`) and its refined raise (spatial_trajectory._raised_until),
the jerk limit (jerk.jerk_time_scale), every "slow until carried" (planners/spatial_carried.py, sweep/robust.py)
and the flip of a run's verdict (margin.py). `bisect_batch` is the same bisection for many plans at once, with
the Illinois regula falsi as a further midpoint (planners/spatial_tight.py), or a fixed number of rounds over a
whole batch (the planar GA's tight timing, planners/optimum.tight_scale).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

MIDPOINTS = ("arithmetic", "geometric")


@dataclass(frozen=True)
class Grow:
    """The bracketing phase: from `start` (its verdict `start_holds`; None: probe it), probe
    `first` (default start x factor), then keep multiplying by `factor` until the verdict flips;
    or (`table`) probe start x f for each f in turn (start / f where holding lies below).
    limit: no step from a point at or beyond it (x >= limit when factor > 1, x <= limit when < 1),
    a step is clipped to it when `clip`; unclipped, a step landing beyond it is probed, or with
    `stop_past_limit` not (status "capped"); tries: at most this many probes in this phase; follow:
    the kept end moves to each probe whose verdict is the start's (else it stays at start)."""
    start: float
    factor: float = 0.0
    table: tuple[float, ...] = ()
    start_holds: bool | None = False
    first: float | None = None
    limit: float | None = None
    clip: bool = True
    stop_past_limit: bool = False
    tries: int | None = None
    follow: bool = True


@dataclass
class ScaleSearch:
    """What a search found. lo, hi: the last bracket (lo == hi when it never had one); holding:
    the end that holds (None: none found); status: "bisected", "end" (a fast end held: the answer
    without bisecting), "no_hold" (the slow end failed), "capped" (growth reached its limit),
    "exhausted" (growth ran out of tries or probes), "stopped" (the caller's `stop`); probes: how
    many times `holds` was called (with the caller's own count passed as `probes`)."""
    lo: float
    hi: float
    holding: float | None
    status: str
    probes: int


def _midpoint(name: str):
    if name == "arithmetic":
        return lambda lo, hi: 0.5 * (lo + hi)
    if name == "geometric":
        return lambda lo, hi: math.sqrt(lo * hi)
    raise ValueError(f"midpoint must be one of {MIDPOINTS}, got {name!r}")


def search_scale(holds: Callable[[float], bool], lo: float | None = None, hi: float | None = None, *,
                 safe: str = "above", midpoint: str = "arithmetic", rel_tol: float = 0.0,
                 steps: int | None = None, done: Callable[[float, float], bool] | None = None,
                 max_probes: int | None = None, ends: tuple[str, ...] = (), grow: Grow | None = None,
                 stop: Callable[[float, bool, float], bool] | None = None, probes: int = 0) -> ScaleSearch:
    """Bracket (`ends` or `grow`) and bisect (module docstring). Without `grow`, [lo, hi] is the
    bracket: its safe end holds and the other fails unless `ends` probes them. stop(x, held, kept):
    called after each growth probe that did not flip the verdict (kept: the end it would replace);
    True ends the search with status "stopped"."""
    if safe not in ("above", "below"):
        raise ValueError(f"safe must be 'above' or 'below', got {safe!r}")
    mid_of = _midpoint(midpoint)
    n = probes

    def probe(x: float) -> bool:
        nonlocal n
        n += 1
        return bool(holds(x))

    def result(a: float, b: float, status: str, holding: float | None) -> ScaleSearch:
        return ScaleSearch(a, b, holding, status, n)

    for end in ends:  # probe the given ends in order
        x = lo if end == "lo" else hi
        ok = probe(x)
        fast = (end == "lo") == (safe == "above")
        if fast and ok:
            return result(lo, hi, "end", x)
        if not fast and not ok:
            return result(lo, hi, "no_hold", None)
    if grow is not None:
        g = grow
        if not g.table and not g.factor > 0.0:  # (an empty table would step by 0 for ever)
            raise ValueError(f"Grow needs a factor > 0 or a non-empty table, got {g!r}")
        kept = g.start
        kept_holds = probe(kept) if g.start_holds is None else g.start_holds
        up = kept_holds != (safe == "above") if g.table else g.factor > 1.0
        tries = len(g.table) if g.table and g.tries is None else g.tries
        x, tried = kept, 0
        while True:
            if tries is not None and tried >= tries or max_probes is not None and n >= max_probes:
                return result(min(kept, x), max(kept, x), "exhausted", kept if kept_holds else None)
            if g.table:
                x = g.start * g.table[tried] if up else g.start / g.table[tried]
            elif tried == 0 and g.first is not None:
                x = g.first
            else:
                if g.limit is not None and (x >= g.limit if up else x <= g.limit):
                    return result(min(kept, x), max(kept, x), "capped", kept if kept_holds else None)
                step = x * g.factor
                if g.limit is not None and g.stop_past_limit and not g.clip and (step > g.limit if up else step < g.limit):
                    return result(min(kept, x), max(kept, x), "capped", kept if kept_holds else None)
                x = step
                if g.limit is not None and g.clip:
                    x = min(x, g.limit) if up else max(x, g.limit)
            ok = probe(x)
            tried += 1
            if ok != kept_holds:
                break
            if stop is not None and stop(x, ok, kept):
                return result(min(kept, x), max(kept, x), "stopped", kept if kept_holds else None)
            if g.follow:
                kept = x
        lo, hi = min(kept, x), max(kept, x)
    holding_hi = safe == "above"

    def more() -> bool:
        if steps is not None:
            return n - start_n < steps
        if max_probes is not None and n >= max_probes:
            return False
        if done is not None:
            return not done(lo, hi)
        return hi / lo - 1.0 > rel_tol

    start_n = n
    while more():
        mid = mid_of(lo, hi)
        if probe(mid) == holding_hi:
            hi = mid
        else:
            lo = mid
    return result(lo, hi, "bisected", hi if holding_hi else lo)


def smallest_holding_scale(lo: float, hi: float, holds: Callable[[float], bool], rel_tol: float) -> float:
    """The smallest time scale in [lo, hi] that holds, to rel_tol, given that hi holds and lo does not
    (arithmetic midpoints); returns a scale that holds."""
    return search_scale(holds, lo, hi, rel_tol=rel_tol).holding


def bisect_batch(excess: Callable[[np.ndarray, np.ndarray], np.ndarray], lo: np.ndarray, hi: np.ndarray,
                 g_lo: np.ndarray | None = None, g_hi: np.ndarray | None = None, *, rel_tol: float | None,
                 max_steps: int, midpoint: str = "illinois", safe: str = "below") -> np.ndarray:
    """Many searches at once: for each i, the root of excess (g <= 0 holds, g > 0 fails; safe "below":
    increasing through 0 from lo to hi, g_lo <= 0 and g_hi > 0; safe "above": decreasing, the hi end holds)
    until hi <= lo (1 + rel_tol) or max_steps rounds (rel_tol None: max_steps rounds of every search, the
    whole batch evaluated each round); returns the holding ends. excess(x, i) evaluates the open searches i
    at x in one batch (a verdict only, -1.0 holds and 1.0 fails, does for midpoint "arithmetic").
    midpoint "illinois": regula falsi with the Illinois halving of the end kept twice (arithmetic
    when the secant leaves the bracket; needs g_lo, g_hi, updated in place); "arithmetic": plain
    bisection (g_lo, g_hi unused)."""
    if midpoint not in ("illinois", "arithmetic"):
        raise ValueError(f"batched midpoint must be 'illinois' or 'arithmetic', got {midpoint!r}")
    if safe not in ("above", "below"):
        raise ValueError(f"safe must be 'above' or 'below', got {safe!r}")
    if midpoint == "illinois" and (g_lo is None or g_hi is None):
        raise ValueError("the Illinois midpoint needs the ends' values g_lo and g_hi")
    kept = np.zeros(len(lo), dtype=int)  # +1: lo kept last step, -1: hi kept
    every = np.arange(len(lo))
    for _ in range(max_steps):
        if rel_tol is None:
            i = every
        else:
            open_ = hi > lo * (1.0 + rel_tol)
            if not np.any(open_):
                break
            i = np.flatnonzero(open_)
        lo_i, hi_i = lo[i], hi[i]
        half = 0.5 * (lo_i + hi_i)
        if midpoint == "arithmetic":  # the ends' values play no part
            gm = excess(half, i)
            left = gm <= 0.0 if safe == "below" else gm > 0.0  # the lo end moves to the midpoint
            lo[i], hi[i] = np.where(left, half, lo_i), np.where(left, hi_i, half)
            continue
        m = (lo_i * g_hi[i] - hi_i * g_lo[i]) / (g_hi[i] - g_lo[i])
        m = np.where((m > lo_i) & (m < hi_i), m, half)
        gm = excess(m, i)
        left = gm <= 0.0 if safe == "below" else gm > 0.0
        j, k = i[left], i[~left]
        g_hi[j] = np.where(kept[j] == 1, 0.5 * g_hi[j], g_hi[j])  # lo moves again: halve hi's value
        g_lo[k] = np.where(kept[k] == -1, 0.5 * g_lo[k], g_lo[k])
        lo[j], g_lo[j], kept[j] = m[left], gm[left], 1
        hi[k], g_hi[k], kept[k] = m[~left], gm[~left], -1
    return lo if safe == "below" else hi
