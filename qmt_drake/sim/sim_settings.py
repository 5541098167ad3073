"""A scenario's `simulation:` section (config/simulation.py, plain data) turned into Drake's settings where a
co-simulation builds its plant and its Simulator.

Precedence, the same on every kind: a run option (`--time-step-ms`, `time_step_s=`, `contact_approximation=`)
over the scenario's `simulation:` over the kind's own default.

Only the fields the scenario gives are applied, each by Drake's own name: `plant_config` copies the kind's
MultibodyPlantConfig and replaces them (AddMultibodyPlant then applies it through ApplyMultibodyPlantConfig),
`apply_contact_settings` sets them on a plant the kind parsed itself (the spatial arm's, built by
model/urdf_check.load_arm_plant), and sim/cosim_run.run applies the simulator's fields through
ExtractSimulatorConfig + ApplySimulatorConfig. Applying a whole config built from Drake's defaults instead
would reset what the kinds choose on purpose (use_sampled_output_ports False, the point contact model, the
planar stiction tolerance, the Simulator's own integrator) and change every published number; giving
only the scenario's fields leaves a scenario without the section bit-identical.
"""

from __future__ import annotations

import copy
from typing import Any

from pydrake.multibody.plant import DiscreteContactApproximation, MultibodyPlantConfig

from qmt_drake.config.simulation import NO_SIMULATION, PlantSettings, Simulation

APPROXIMATION_ENUMS = {"tamsi": DiscreteContactApproximation.kTamsi, "sap": DiscreteContactApproximation.kSap,
                  "similar": DiscreteContactApproximation.kSimilar, "lagged": DiscreteContactApproximation.kLagged}


def simulation_of(scenario: Any) -> Simulation:
    """The scenario's `simulation` section (NO_SIMULATION for one without it, or an object that is no scenario)."""
    sim = getattr(scenario, "simulation", None)
    return sim if isinstance(sim, Simulation) else NO_SIMULATION


def time_step_of(run_option: float | None, scenario: Any, default: float | None) -> float | None:
    """The plant step [s] by the precedence of the module docstring (default None: the caller's own default
    applies later)."""
    if run_option is not None:
        return run_option
    step = simulation_of(scenario).plant.time_step
    return default if step is None else step


def plant_config(base: MultibodyPlantConfig, plant: PlantSettings, **run_options: Any) -> MultibodyPlantConfig:
    """`base` (the kind's own config) with the scenario's given fields, then the run's options (not None),
    replacing theirs."""
    cfg = copy.copy(base)
    for k, v in {**plant.given(), **{k: v for k, v in run_options.items() if v is not None}}.items():
        setattr(cfg, k, v)
    return cfg


def apply_contact_settings(plant, settings: PlantSettings) -> None:
    """Before Finalize: the scenario's given contact fields on a plant the kind built itself (time_step is a
    constructor argument: the kind passes time_step_of)."""
    given = settings.given()
    if "discrete_contact_approximation" in given:
        plant.set_discrete_contact_approximation(APPROXIMATION_ENUMS[given["discrete_contact_approximation"]])
    if "penetration_allowance" in given:
        plant.set_penetration_allowance(given["penetration_allowance"])
    if "stiction_tolerance" in given:
        plant.set_stiction_tolerance(given["stiction_tolerance"])
    if "sap_near_rigid_threshold" in given:
        plant.set_sap_near_rigid_threshold(given["sap_near_rigid_threshold"])
