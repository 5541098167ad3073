"""The README's account of held-part 'slip': friction creep, converged in the plant step (the
payload's coordinates are relative to the hand; studies/contact_drift.py)."""

import pytest

from qmt_drake.sim import GenesPlan
from qmt_drake.transfer_scenario import load_scenario
from studies.contact_drift import run_case


@pytest.fixture(scope="module")
def ch4():
    sc = load_scenario("thesis-ch4")
    return sc, GenesPlan(sc, (0.622, 0.532, 0.562))


def test_held_part_creep_does_not_depend_on_the_step_but_on_friction(ch4):
    sc, plan = ch4
    fine = run_case(sc, plan, 1e-3, {})
    coarse = run_case(sc, plan, 2e-3, {})
    grippy = run_case(sc, plan, 2e-3, {"friction": 0.6})
    # Halving the step leaves the slip and the slid distance the same (within 2%): no stepping drift.
    assert coarse["max_slip_m"] == pytest.approx(fine["max_slip_m"], rel=0.02)
    assert coarse["slid_distance_m"] == pytest.approx(fine["slid_distance_m"], rel=0.02)
    # Doubling the friction coefficient at least halves it: the part creeps on friction.
    assert grippy["max_slip_m"] < 0.6 * coarse["max_slip_m"]
    assert coarse["max_slip_m"] < 0.1e-3  # a held part: a twentieth of a millimetre
