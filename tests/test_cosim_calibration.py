"""The calibrated co-simulation against the rows on either side of the thesis's slip boundaries:
Table 2.3 (ch.2 line, v_xmax = 0.07 m/s) and Table 4.2 (ch.4 GA move scaled in time)."""

import math

import pytest

from qmt_drake.sim import GenesPlan, planned_peak_moment_Nm, simulate_transfer
from qmt_drake.transfer_scenario import load_scenario


@pytest.mark.parametrize("T1, T2, thesis_success", [(1.167, 1.690, True), (1.105, 1.752, False)])
def test_table_2_3_boundary_rows(T1, T2, thesis_success):
    sc = load_scenario("thesis-ch2")
    r = simulate_transfer(sc, GenesPlan(sc, (T1, T2)), keep_series=False)
    assert r.held == thesis_success


@pytest.mark.parametrize("moment_Nm, thesis_success", [(0.633e-3, True), (0.727e-3, False)])
def test_table_4_2_boundary_rows(moment_Nm, thesis_success):
    sc = load_scenario("thesis-ch4")
    plan = GenesPlan(sc, (0.622, 0.532, 0.562))
    scale = math.sqrt(planned_peak_moment_Nm(sc, plan) / moment_Nm)
    r = simulate_transfer(sc, plan, time_scale=scale, keep_series=False)
    assert r.peak_moment_planned_Nm == pytest.approx(moment_Nm, rel=1e-6)
    assert r.held == thesis_success
