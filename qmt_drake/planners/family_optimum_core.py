"""The one family-optimum search: the fastest member of a trajectory family within the limits.

What every kind's family optimum is: each candidate gene vector x is played at its tight time scale
(the slowest-limit time scaling: exact, searched, or in closed form per sample, as the kind has it), so
the objective is the tight duration T(x) (plus the penalties of the kind's adapter: genes out of their
bounds, a joint out of its range), a piecewise-smooth function (a max over samples). It is minimised by

  - `minimise`: Nelder-Mead (scipy) from several starts, within box bounds where the adapter gives them;
    each polished start's result is settled by the adapter (made exactly feasible, or dropped) and the
    best settled duration wins;
  - `grid_then_brent`: for one scalar shape parameter (a rest-to-rest segment's cruise/accel ratio), a
    grid and then bounded Brent around its best point.

The adapters: planners/optimum.plan_family_optimum (the planar families: genes normalised to their
bounds, a Latin-hypercube of starts, the tight scale of problem.PlanningProblem) and
planners/spatial_search.plan_family_optimum (the spatial families: the via cubic's segment-time shares,
unbounded, with its joint-range penalty; the rest-to-rest families segment by segment).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from scipy.optimize import minimize, minimize_scalar


def minimise(objective: Callable[[np.ndarray], float], starts: Sequence[np.ndarray | None], *,
             options: dict, bounds=None, settle: Callable[[Any], tuple[float, Any] | None] | None = None,
             progress: Callable[[int, float], None] | None = None) -> tuple[float, Any] | None:
    """(score, candidate) of the best start after Nelder-Mead (module docstring), None if none settled.
    starts: the start points in order (None: skipped); bounds: [(lo, hi)] per coordinate or None;
    options: scipy's Nelder-Mead options; settle(result) -> (score, candidate) or None (dropped),
    default (result.fun, result); progress(start index, score) after each settled start. The first of
    equal scores wins."""
    best = None
    for k, x0 in enumerate(starts):
        if x0 is None:
            continue
        r = minimize(objective, x0, method="Nelder-Mead", bounds=bounds, options=options)
        out = settle(r) if settle is not None else (r.fun, r)
        if out is None:
            continue
        if progress:
            progress(k, out[0])
        if best is None or out[0] < best[0]:
            best = out
    return best


def grid_then_brent(values: Callable[[Sequence[float]], np.ndarray], grid: np.ndarray, at_grid: np.ndarray, *,
                    xatol: float) -> tuple[float, float, int]:
    """(x, value, evaluations) minimising a scalar function: its values `at_grid` (some finite) on the
    sorted `grid`, then bounded Brent between the best grid point's neighbours (values(xs) -> (len(xs),))."""
    j = int(np.argmin(at_grid))
    lo, hi = grid[max(j - 1, 0)], grid[min(j + 1, len(grid) - 1)]
    r = minimize_scalar(lambda x: values([x])[0], bounds=(lo, hi), method="bounded", options={"xatol": xatol})
    x, best = (r.x, r.fun) if r.fun < at_grid[j] else (grid[j], at_grid[j])
    return x, best, len(grid) + int(r.nfev)
