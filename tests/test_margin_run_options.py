"""The verdict study's plant step and contact approximation are run options of the spatial co-simulation
(margin_runs.spatial_plant_options): they win over a scenario's `simulation:` section, as a run option does
everywhere else (sim/sim_settings: run option > section > kind default). The module-global swap they replace
(kept below as it was on main 1d491b2) lost to the section."""

from contextlib import contextmanager
from types import SimpleNamespace

import pytest
from pydrake.multibody.plant import DiscreteContactApproximation

import qmt_drake.sim.spatial_cosim as spatial_cosim
from qmt_drake.api import load_scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.margin import half_step_verdict
from qmt_drake.margin_runs import APPROXIMATIONS, spatial_plant_options, spatial_run
from qmt_drake.sim.spatial_cosim import build_spatial_cosim, spatial_time_step
from tests.spatial_fixtures import shipped_toppra

SECTION = {"plant": {"time_step": 2e-3, "discrete_contact_approximation": "lagged"}}


@contextmanager
def old_spatial_plant_settings(time_step_s=None, approximation=None):  # margin_runs on main 1d491b2 (abridged)
    saved = spatial_cosim.TIME_STEP_S, spatial_cosim.DiscreteContactApproximation
    try:
        if time_step_s is not None:
            spatial_cosim.TIME_STEP_S = float(time_step_s)
        if approximation is not None:
            spatial_cosim.DiscreteContactApproximation = SimpleNamespace(kSap=APPROXIMATIONS[approximation])
        yield
    finally:
        spatial_cosim.TIME_STEP_S, spatial_cosim.DiscreteContactApproximation = saved


def _plant(cosim):
    return cosim.plant.time_step(), cosim.plant.get_discrete_contact_approximation()


@pytest.fixture(scope="module")
def case():
    sc = load_scenario("ur5-suction-bins", overrides={"simulation": SECTION})
    return sc, load_scenario("ur5-suction-bins"), shipped_toppra("ur5-suction-bins", 400).trajectory


def test_the_studys_half_step_cell_runs_at_its_step_over_the_section(case):
    sc, plain, traj = case
    assert _plant(build_spatial_cosim(sc, traj)) == (2e-3, DiscreteContactApproximation.kLagged)  # the section
    cell = spatial_plant_options(0.5e-3, "similar")
    assert cell == {"time_step_s": 0.5e-3, "contact_approximation": "similar"}
    assert _plant(build_spatial_cosim(sc, traj, **cell)) == (0.5e-3, DiscreteContactApproximation.kSimilar)
    assert _plant(build_spatial_cosim(plain, traj, **cell)) == (0.5e-3, DiscreteContactApproximation.kSimilar)
    with old_spatial_plant_settings(0.5e-3, "similar"):  # the swap: the section won
        assert _plant(build_spatial_cosim(sc, traj)) == (2e-3, DiscreteContactApproximation.kLagged)
        assert _plant(build_spatial_cosim(plain, traj)) == (0.5e-3, DiscreteContactApproximation.kSimilar)


def test_the_margins_half_step_run_halves_the_sections_step_and_keeps_the_run_options(case, monkeypatch):
    sc, _, traj = case
    built = []

    def simulate(sc_, traj_, **kw):  # build the run's plant, record it, skip the run
        built.append(_plant(build_spatial_cosim(sc_, traj_, **kw)))
        return {"outcome": "carried", "held": True, "final_goal_error_rad": 0.0, "max_grip_ratio_while_held": 0.5}
    monkeypatch.setattr(spatial_cosim, "simulate_spatial", simulate)
    for options, half in (({}, 1e-3), (spatial_plant_options(approximation="similar"), 1e-3),
                          (spatial_plant_options(0.5e-3, "similar"), 0.25e-3)):
        h = spatial_time_step(sc, options.get("time_step_s"))  # the step the run used (margin_runs.with_margin)
        r = half_step_verdict(spatial_run(sc, traj, **options), {"held": True}, h)
        approximation = APPROXIMATIONS[options.get("contact_approximation", "lagged")]
        assert r["half_step_s"] == half and built[-1] == (half, approximation), options


def test_a_bad_contact_approximation_stops_in_one_line(case):
    sc, _, traj = case
    for call in (lambda: spatial_plant_options(approximation="implicit"),
                 lambda: build_spatial_cosim(sc, traj, contact_approximation="implicit")):
        with pytest.raises(QmtInputError, match="contact approximation 'implicit': use one of tamsi, sap") as e:
            call()
        assert "\n" not in str(e.value)
