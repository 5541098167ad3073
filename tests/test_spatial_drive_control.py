"""The spatial drives' controller model: a drawn plant under the nominal controller, every hand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pydrake.systems.controllers import InverseDynamicsController

from qmt_drake.sim.spatial_cosim import build_spatial_cosim
from qmt_drake.sweep.spatial_cases import perturbed_scenario
from tests.spatial_fixtures import load_or_skip


class Hold:
    """A plan that stays at q [rad] for duration_s (the spatial trajectory interface)."""

    def __init__(self, q, duration_s):
        self.q, self.duration_s = np.asarray(q, float), duration_s

    def sample(self, t):
        t = np.atleast_1d(t)
        z = np.zeros((len(t), len(self.q)))
        return np.tile(self.q, (len(t), 1)), z, z.copy()


@pytest.fixture(scope="module")
def suction():
    return load_or_skip("ur5-suction-bins")


@pytest.mark.parametrize("physics", ["weld", "contact"])
def test_controller_model_stays_nominal_when_the_plant_is_drawn(suction, physics):
    """A sweep case simulates a drawn part (here 1.5x the mass) under the controller built from the nominal
    scenario (controller_sc). The contact hand used to build its ideal controller from the drawn scenario:
    its inverse dynamics then knew the drawn mass, which a real controller cannot. The controller's plant
    (the arm with the part welded, sim/spatial_cosim.add_ideal_controller) must carry the nominal part."""
    sc = dataclasses.replace(suction, hand_physics=physics)
    drawn = perturbed_scenario(sc, {"mass_scale": 1.5})
    assert drawn.body.mass_kg == pytest.approx(1.5 * sc.body.mass_kg)
    hold = Hold(sc.q_poses_rad[0], 0.1)
    co = build_spatial_cosim(drawn, hold, controller_sc=sc)
    (ctrl,) = [s for s in co.diagram.GetSystems() if isinstance(s, InverseDynamicsController)]
    mp = ctrl.get_multibody_plant_for_control()
    assert mp.GetBodyByName("carried").default_mass() == sc.body.mass_kg
    # and without controller_sc the controller is the simulated scenario's (a run on its own model)
    co = build_spatial_cosim(drawn, hold)
    (ctrl,) = [s for s in co.diagram.GetSystems() if isinstance(s, InverseDynamicsController)]
    assert ctrl.get_multibody_plant_for_control().GetBodyByName("carried").default_mass() == drawn.body.mass_kg
