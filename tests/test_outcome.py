"""The one outcome vocabulary (qmt_drake/outcome.py): a lost part and an unfinished transfer are never carried."""

import math

import pytest

from qmt_drake.outcome import OUTCOMES, transfer_outcome, verdict_line


@pytest.mark.parametrize("lost, slipped, err, tol, want", [
    (None, False, 0.0, 1e-3, "carried"),
    (None, False, 2e-3, 1e-3, "unfinished"),
    (None, False, math.nan, 1e-3, "unfinished"),  # not measured is not arrived
    (None, True, 0.0, 1e-3, "slipped"),
    ("detached", False, 0.0, 1e-3, "detached"),
    ("slid_off", True, 5.0, 1e-3, "slid_off"),
    ("tipped", False, 0.0, 0.1, "tipped"),
])
def test_each_outcome(lost, slipped, err, tol, want):
    got = transfer_outcome(lost, slipped, err, tol)
    assert got == want and got in OUTCOMES


def test_only_carried_reads_as_carried():
    for o in OUTCOMES:
        line = verdict_line(o, 1.5)
        assert ("LOST" in line or "UNFINISHED" in line or "COLLIDED" in line) == (o != "carried")
    with pytest.raises(ValueError):
        transfer_outcome("carried", False, 0.0, 1e-3)
