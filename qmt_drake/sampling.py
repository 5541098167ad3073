"""Time grids for checking limits on many candidate trajectories at once.

Each candidate's motion is cut at its phase boundaries (where acceleration may jump). Every
piece is sampled on its own closed interval, endpoints included, at no more than 1/rate_hz
spacing, and evaluated with that piece's own formula (`t_piece` is a time strictly inside the
piece). A boundary therefore appears twice, once with each one-sided value, so the peaks of a
trapezoid, which sit exactly at its switching instants, are never missed.

`piecewise_grid(..., stride=k)` keeps every k-th sample of that grid (plus each piece's end), an
exact subset; `refine_grid` then adds back the full-rate samples around chosen coarse samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SampleGrid:
    """Flat samples of K candidates, ordered by candidate."""

    candidate: np.ndarray  # (S,) int
    t_s: np.ndarray  # (S,)
    t_piece_s: np.ndarray  # (S,) a time inside the sample's piece (selects the formula)
    start: np.ndarray  # (K,) index of each candidate's first sample (for np.maximum.reduceat)
    n_candidates: int
    piece_a_s: np.ndarray  # (S,) the piece's start
    piece_e_s: np.ndarray  # (S,) the piece's end
    fine_count: np.ndarray  # (S,) samples of the piece on the full-rate grid
    fine_index: np.ndarray  # (S,) this sample's index on that full-rate grid
    stride: int = 1


def piecewise_grid(breakpoints_s: np.ndarray, rate_hz: float, stride: int = 1) -> SampleGrid:
    """Grid over pieces [b_j, b_j+1] of each row of `breakpoints_s` (K, B), sorted per row.

    Pieces shorter than 1e-12 s are skipped. Every candidate gets at least two samples.
    `stride` > 1 keeps every stride-th sample of the rate_hz grid plus each piece's end.
    """
    b = np.asarray(breakpoints_s, dtype=float)
    K = b.shape[0]
    a, e = b[:, :-1], b[:, 1:]
    length = e - a
    real = length > 1e-12
    counts = np.where(real, np.ceil(length * rate_hz - 1e-9).astype(int) + 1, 0)
    counts[:, 0] = np.maximum(counts[:, 0], 2)  # a zero-length motion still gets two samples
    fine_counts = counts.ravel()
    if stride > 1:
        counts = np.where(counts > 0, (counts - 2) // stride + 2, 0)
    flat_counts = counts.ravel()
    total = int(flat_counts.sum())
    piece = np.repeat(np.arange(flat_counts.size), flat_counts)
    first = np.cumsum(flat_counts) - flat_counts
    local = np.arange(total) - first[piece]
    n = fine_counts[piece]
    if stride > 1:
        local = np.minimum(local * stride, n - 1)
    a_f, e_f = a.ravel()[piece], e.ravel()[piece]
    per_cand = counts.sum(axis=1)
    start = np.cumsum(per_cand) - per_cand
    return _grid(piece // a.shape[1], a_f, e_f, n, local, start, K, stride)


def _grid(cand, a_f, e_f, n, local, start, K, stride) -> SampleGrid:
    t = a_f + (e_f - a_f) * (local / np.maximum(n - 1, 1))
    return SampleGrid(cand, t, 0.5 * (a_f + e_f), start, K, a_f, e_f, n, local, stride)


def refine_grid(coarse: SampleGrid, flagged: np.ndarray) -> SampleGrid:
    """Full-rate samples within one coarse step either side of each flagged coarse sample.

    Every candidate must have at least one flagged sample (its own peak always is)."""
    k = coarse.stride
    idx = np.flatnonzero(flagged)
    offsets = np.arange(-(k - 1), k)
    local = coarse.fine_index[idx, None] + offsets[None, :]
    n = coarse.fine_count[idx, None]
    keep = (local >= 0) & (local <= n - 1)
    rows = np.broadcast_to(idx[:, None], local.shape)[keep]
    local = local[keep]
    cand = coarse.candidate[rows]
    per_cand = np.bincount(cand, minlength=coarse.n_candidates)
    start = np.cumsum(per_cand) - per_cand
    return _grid(cand, coarse.piece_a_s[rows], coarse.piece_e_s[rows], coarse.fine_count[rows],
                 local, start, coarse.n_candidates, 1)


def peak_per_candidate(values: np.ndarray, grid: SampleGrid) -> np.ndarray:
    """Maximum of `values` (S,) or (S, m) over each candidate's samples -> (K,) or (K, m)."""
    return np.maximum.reduceat(values, grid.start, axis=0)


def uniform_grid(t_s: np.ndarray) -> SampleGrid:
    """One candidate, one piece: the given rising sample times (s) as a SampleGrid (for
    limits/refine.py on a trajectory sampled at plain times, e.g. the spatial re-check)."""
    t = np.asarray(t_s, float)
    S = t.size
    T = float(t[-1]) if S else 0.0
    return SampleGrid(np.zeros(S, int), t, np.full(S, 0.5 * T), np.zeros(1, int), 1, np.zeros(S), np.full(S, T),
                      np.full(S, S), np.arange(S), 1)
