"""The README's account of held-part 'slip': a stepping drift proportional to the plant step,
independent of friction (studies/contact_drift.py)."""

import pytest

from qmt_drake.sim import GenesPlan
from qmt_drake.config.scenario import load_scenario
from studies.contact_drift import run_case


@pytest.fixture(scope="module")
def ch4():
    sc = load_scenario("thesis-ch4")
    return sc, GenesPlan(sc, (0.622, 0.532, 0.562))


def test_held_part_drift_scales_with_step_not_friction(ch4):
    sc, plan = ch4
    fine = run_case(sc, plan, 1e-3, {})
    coarse = run_case(sc, plan, 2e-3, {})
    grippy = run_case(sc, plan, 2e-3, {"friction": 0.6})
    # Relative speed of a stuck part ~ step: doubling the step doubles it (within 10%).
    assert coarse["peak_relative_speed_m_s"] / fine["peak_relative_speed_m_s"] == pytest.approx(2.0, rel=0.1)
    assert coarse["max_slip_m"] / fine["max_slip_m"] == pytest.approx(2.0, rel=0.15)
    # Doubling the friction coefficient leaves it almost unchanged: the part is not sliding on friction.
    assert grippy["peak_relative_speed_m_s"] == pytest.approx(coarse["peak_relative_speed_m_s"], rel=0.03)
    assert grippy["max_slip_m"] == pytest.approx(coarse["max_slip_m"], rel=0.05)
