"""studies/bench_tray_floor's RSS plateau check: the slope over the last half of the runs is a
least-squares fit (exact on a line), a late step of heap growth is not a plateau, and the heap
figures come from glibc's own accounting (a block allocated and kept shows up in them)."""

import ctypes

import numpy as np
import pytest

from studies.bench_tray_floor import LIBC, PLATEAU_MIB, RSS_EVERY, heap_mib, rss_plateau


def rows(runs, rss, heap=None):
    k = np.arange(0, runs + 1, RSS_EVERY)
    return [{"run": int(r), "rss_mib": float(rss(r)), "heap_in_use_mib": float((heap or (lambda _: 50.0))(r)),
             "python_objects": 1000} for r in k]


def test_slope_of_a_line_and_a_flat_tail():
    p = rss_plateau(rows(600, lambda r: 200.0 + 0.01 * r, lambda r: 50.0 + 0.5 * r / 1024), 600)
    assert p["from_run"] == 300 and p["to_run"] == 600
    assert p["rss_slope_mib_per_run"] == pytest.approx(0.01, rel=1e-9)
    assert p["heap_in_use_slope_kib_per_run"] == pytest.approx(0.5, rel=1e-9)
    assert p["rss_growth_mib"] == pytest.approx(3.0) and not p["plateau"]
    # growth in the first half only (the heap reaching its working size): a plateau
    p = rss_plateau(rows(600, lambda r: 200.0 + min(r, 100) * 0.2), 600)
    assert p["plateau"] and p["rss_growth_mib"] == 0.0


def test_a_late_step_is_not_a_plateau():
    p = rss_plateau(rows(200, lambda r: 250.0 + (2 * PLATEAU_MIB if r >= 180 else 0.0)), 200)
    assert not p["plateau"]


@pytest.mark.skipif(LIBC is None, reason="glibc's mallinfo2 only")
def test_heap_in_use_sees_a_kept_block():
    libc = ctypes.CDLL("libc.so.6")
    libc.malloc.restype = ctypes.c_void_p
    libc.free.argtypes = [ctypes.c_void_p]
    before = heap_mib()["heap_in_use_mib"]
    block = libc.malloc(8 << 20)
    try:
        assert heap_mib()["heap_in_use_mib"] - before == pytest.approx(8.0, abs=0.1)
    finally:
        libc.free(block)
    assert abs(heap_mib()["heap_in_use_mib"] - before) < 0.1
