"""Local maxima between samples: the one refinement every re-check uses (planar LimitSet.report and
the spatial re-check, planners/spatial_trajectory.check).

A limit column sampled on a grid can peak between two samples. `refine_local_maxima` takes every
sampled local maximum that comes near its column's sampled peak or near the limit and maximises the
column by a batched golden-section search on the trajectory itself, between the sample's neighbours
within its piece (sampling.SampleGrid), so the reported peak is the trajectory's local maximum, not
the largest sample. Where the column jumps inside the bracket (an acceleration switching between
samples) the search closes on the jump and returns the larger one-sided value.

`peaks_on_pieces` is the one re-check between samples of a trajectory of any kind (the protocol of
qmt_drake/trajectory.py): every piece between its breakpoints_s sampled with both ends, one-sided through
its evaluate(t, t_piece), the local maxima refined inside each piece. The planar LimitSet.report and the
spatial spatial_trajectory.between_pieces are this function with their own columns.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.sampling import SampleGrid, piecewise_grid

REFINE_RELATIVE_MARGIN = 0.02  # refine local maxima within 2% of their column's sampled peak ...
REFINE_NEAR_LIMIT = 0.98  # ... or above 98% of the limit (ratio columns) / within 0.02 rad (excess)
GOLDEN_ITERATIONS = 60  # bracket of one sample step shrinks by 0.618^60 ~ 3e-13
# A long plateau (the tray's slide ratio over a constant-acceleration phase) makes every sample a
# "local maximum" within the margin (rounding bumps): thousands, each refined for 60 iterations.
# Only the highest sampled ones per column are refined; between samples a maximum can gain only
# O(step^2 f''), so a sample far down the list cannot overtake them. The report says how many
# were refined.
REFINE_MAX_PER_COLUMN = 64


def peaks_on_pieces(columns, trajectory, rate_hz: float, near_limit, *, refine: bool = True,
                    relative_margin: float = REFINE_RELATIVE_MARGIN, skip_flat: bool = False):
    """(peak (M,), t_peak (M,) s, refined count, grid) of the columns `columns(q, qd, qdd) -> (S, M)` over a
    trajectory's pieces (module docstring; rate_hz the samples per second of each piece); `refine` and the
    keywords as refine_local_maxima."""
    grid: SampleGrid = piecewise_grid(trajectory.breakpoints_s[None, :], rate_hz)
    cols = columns(*trajectory.evaluate(grid.t_s, grid.t_piece_s))
    peak = cols.max(axis=0)
    t_peak = grid.t_s[cols.argmax(axis=0)]
    if not refine:
        return peak, t_peak, 0, grid
    peak, t_peak, refined = refine_local_maxima(lambda t, tp: columns(*trajectory.evaluate(t, tp)), grid, cols, peak,
                                                t_peak, near_limit, relative_margin=relative_margin, skip_flat=skip_flat)
    return peak, t_peak, refined, grid


def refine_local_maxima(columns_at, grid, cols, peak, t_peak, near_limit, *,
                        relative_margin: float = REFINE_RELATIVE_MARGIN, skip_flat: bool = False):
    """(peak, t_peak, refined count): golden-section maximisation of each column between the
    neighbours of its sampled local maxima that matter (module docstring).

    columns_at(t (S,), t_piece (S,)) -> (S, M) the columns at times t (s) of the pieces t_piece
    selects; cols (S, M) the columns on `grid`; peak, t_peak (M,) their sampled maxima and times;
    near_limit (M,) the value above which a local maximum is refined whatever its column's peak;
    relative_margin: also refine the local maxima within this fraction of their column's peak;
    skip_flat: leave out columns equal at every sample (a joint that does not move: every sample is a
    'local maximum', nothing to find between them), which the spatial re-check, with one column per
    joint and limit, would otherwise spend most of its time on."""
    S = cols.shape[0]
    same_prev = np.zeros(S, bool)
    same_prev[1:] = grid.piece_a_s[1:] == grid.piece_a_s[:-1]
    same_next = np.zeros(S, bool)
    same_next[:-1] = same_prev[1:]
    prev = np.where(same_prev, np.arange(S) - 1, np.arange(S))
    nxt = np.where(same_next, np.arange(S) + 1, np.arange(S))
    is_max = (cols >= cols[prev]) & (cols >= cols[nxt])
    span = np.abs(peak) * relative_margin
    wanted = is_max & ((cols >= peak - span) | (cols >= near_limit))
    if skip_flat:
        wanted &= (cols.max(axis=0) > cols.min(axis=0))[None, :]
    k, c = np.nonzero(wanted)
    if k.size == 0:
        return peak, t_peak, 0
    counts = np.bincount(c, minlength=cols.shape[1])
    if counts.max() > REFINE_MAX_PER_COLUMN:
        order = np.lexsort((-cols[k, c], c))  # by column, highest sample first
        k, c = k[order], c[order]
        rank = np.arange(k.size) - np.searchsorted(c, c)  # position within its column
        keep = rank < REFINE_MAX_PER_COLUMN
        k, c = k[keep], c[keep]
    a, b = grid.t_s[prev[k]], grid.t_s[nxt[k]]
    tp = grid.t_piece_s[k]
    inv_phi = (np.sqrt(5.0) - 1.0) / 2.0

    def f(t):
        return columns_at(t, tp)[np.arange(t.size), c]

    x1, x2 = b - inv_phi * (b - a), a + inv_phi * (b - a)
    f1, f2 = f(x1), f(x2)
    for _ in range(GOLDEN_ITERATIONS):
        left = f1 >= f2  # the maximum lies in [a, x2]
        b = np.where(left, x2, b)
        a = np.where(left, a, x1)
        x2n = np.where(left, x1, a + inv_phi * (b - a))
        x1n = np.where(left, b - inv_phi * (b - a), x2)
        f2n, f1n = np.where(left, f1, np.nan), np.where(left, np.nan, f2)
        fresh = np.where(left, x1n, x2n)
        fv = f(fresh)
        f1 = np.where(left, fv, f1n)
        f2 = np.where(left, f2n, fv)
        x1, x2 = x1n, x2n
    t_best = np.where(f1 >= f2, x1, x2)
    v_best = np.maximum(f1, f2)
    peak, t_peak = peak.copy(), t_peak.copy()
    for col in np.unique(c):
        m = c == col
        j = np.argmax(v_best[m])
        if v_best[m][j] > peak[col]:
            peak[col], t_peak[col] = v_best[m][j], t_best[m][j]
    return peak, t_peak, int(k.size)
