"""The optional `simulation:` section of every scenario kind: Drake's plant and simulator settings as plain data.

    simulation:
      plant:                      # fields of pydrake.multibody.plant.MultibodyPlantConfig, Drake's names
        time_step: 0.001          # [s]; the kind's default when left out (planar magnet 2 ms, 1 ms --explicit;
                                  #   tray 1 ms; spatial 1 ms; seed 001 continuous)
        discrete_contact_approximation: sap     # tamsi | sap | similar | lagged
        penetration_allowance: 0.001            # [m]
        stiction_tolerance: 0.0001              # [m/s]
        sap_near_rigid_threshold: 1.0
      simulator:                  # fields of pydrake.systems.analysis.SimulatorConfig
        integration_scheme: runge_kutta3        # GetIntegrationSchemes()
        max_step_size: 0.1        # [s]
        accuracy: 0.0001
        use_error_control: true
        target_realtime_rate: 0.0
        publish_every_time_step: false

A key left out keeps what the co-simulation of that kind uses without the section (its own
MultibodyPlantConfig, its Simulator as made), so a scenario without the section runs bit for bit as
before. A run option (`--time-step-ms`, `time_step_s=`, `contact_approximation=`) overrides the section.
The section steers only how a plan is co-simulated, never what is planned: plan identities
(plan_identity.py) and Scenario.fingerprint leave it out.

The data holds numbers, strings and booleans only (None: not given); sim/sim_settings.py turns them into
Drake's MultibodyPlantConfig / SimulatorConfig where a plant or a simulator is built.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from qmt_drake.config import fields as F
from qmt_drake.errors import QmtInputError

APPROXIMATIONS = ("tamsi", "sap", "similar", "lagged")  # MultibodyPlantConfig.discrete_contact_approximation
# pydrake.systems.analysis.GetIntegrationSchemes() (config/ imports no Drake; a test checks they agree)
INTEGRATION_SCHEMES = ("bogacki_shampine3", "cenic", "explicit_euler", "implicit_euler", "radau1", "radau3",
                       "runge_kutta2", "runge_kutta3", "runge_kutta5", "semi_explicit_euler",
                       "velocity_implicit_euler")
# MultibodyPlantConfig / SimulatorConfig fields that are no setting here, each with why
_REFUSED_PLANT = {
    "use_sampled_output_ports": "the co-simulations' monitors and drives read the plant during a step and need "
                                "its current state (False), a property of how they are built, not a setting",
    "contact_model": "each hand's contact is a point-contact model (spheres on boxes, no hydroelastic "
                     "properties), fixed by the hand",
    "contact_surface_representation": "it shapes hydroelastic contact surfaces, and the hands make point contact",
    "adjacent_bodies_collision_filters": "which bodies may touch is part of the hand's model (its allowed contact "
                                         "pair), not a setting",
}
_REFUSED_SIMULATOR = {"start_time": "a co-simulation starts at the plan's t = 0 s"}
CONTACT_FIELDS = ("discrete_contact_approximation", "penetration_allowance", "stiction_tolerance",
                  "sap_near_rigid_threshold")


@dataclass(frozen=True)
class PlantSettings:
    """`simulation.plant`: MultibodyPlantConfig fields by Drake's names; None keeps the kind's own value."""

    time_step: float | None = None  # [s]; 0: a continuous plant (seed 001's arm only)
    discrete_contact_approximation: str | None = None
    penetration_allowance: float | None = None  # [m]
    stiction_tolerance: float | None = None  # [m/s]
    sap_near_rigid_threshold: float | None = None

    def given(self) -> dict:
        """{field: value} of the fields the scenario gives."""
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}


@dataclass(frozen=True)
class SimulatorSettings:
    """`simulation.simulator`: SimulatorConfig fields by Drake's names; None keeps the Simulator as made."""

    integration_scheme: str | None = None
    max_step_size: float | None = None  # [s]
    accuracy: float | None = None
    use_error_control: bool | None = None
    target_realtime_rate: float | None = None
    publish_every_time_step: bool | None = None

    def given(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}


@dataclass(frozen=True)
class Simulation:
    """The `simulation` section (module docstring); the default gives nothing."""

    plant: PlantSettings = field(default_factory=PlantSettings)
    simulator: SimulatorSettings = field(default_factory=SimulatorSettings)


NO_SIMULATION = Simulation()


def parse_simulation(raw, where: str, *, continuous: str | None = None, no_contact: str | None = None,
                     no_tamsi: str | None = None) -> Simulation:
    """The `simulation` mapping of a scenario file (None: NO_SIMULATION). The kind's physics refuses what
    cannot apply, one line each: `continuous` the reason a continuous plant (time_step 0) cannot carry this
    kind's hand or drive (None: allowed); `no_contact` the reason the contact fields have nothing to act on;
    `no_tamsi` the reason the TAMSI solver cannot run this kind's model."""
    if raw is None:
        return NO_SIMULATION
    w = F.key_path(where, "simulation")
    if not isinstance(raw, dict):
        raise QmtInputError(f"{w} must be a mapping with plant and/or simulator, got {F.show(raw)}")
    F.check_keys(raw, {"plant", "simulator"}, w)
    return Simulation(_plant(F.mapping(raw, "plant", w, default={}), f"{w}.plant", continuous, no_contact, no_tamsi),
                      _simulator(F.mapping(raw, "simulator", w, default={}), f"{w}.simulator"))


def _refuse(d: dict, refused: dict, where: str) -> None:
    for k in d:
        if k in refused:
            raise QmtInputError(f"{where}.{k} is not a setting of the co-simulation: {refused[k]}; remove it")


def _plant(p: dict, w: str, continuous, no_contact, no_tamsi) -> PlantSettings:
    _refuse(p, _REFUSED_PLANT, w)
    F.check_keys(p, {f.name for f in fields(PlantSettings)}, w)
    step = F.num(p, "time_step", w, nonnegative=True, default=None)
    if step == 0 and continuous:
        raise QmtInputError(f"{w}.time_step 0 (a continuous plant) cannot run this scenario: {continuous}; "
                            "give a step > 0 s or leave it out")
    given = [k for k in CONTACT_FIELDS if p.get(k) is not None]
    if given and no_contact:
        raise QmtInputError(f"{w}.{given[0]}: {no_contact}; remove it")
    approx = F.string(p, "discrete_contact_approximation", w, choices=APPROXIMATIONS, default=None)
    if approx == "tamsi" and no_tamsi:
        raise QmtInputError(f"{w}.discrete_contact_approximation tamsi: {no_tamsi}; use sap, similar or lagged")
    if step == 0 and given:
        raise QmtInputError(f"{w}.{given[0]} sets the discrete plant's contact solver, and time_step 0 makes the "
                            "plant continuous; give a step > 0 s or remove it")
    return PlantSettings(step, approx, F.num(p, "penetration_allowance", w, positive=True, default=None),
                         F.num(p, "stiction_tolerance", w, positive=True, default=None),
                         F.num(p, "sap_near_rigid_threshold", w, nonnegative=True, default=None))


def _simulator(s: dict, w: str) -> SimulatorSettings:
    _refuse(s, _REFUSED_SIMULATOR, w)
    F.check_keys(s, {f.name for f in fields(SimulatorSettings)}, w)
    return SimulatorSettings(
        F.string(s, "integration_scheme", w, choices=INTEGRATION_SCHEMES, default=None),
        F.num(s, "max_step_size", w, positive=True, default=None),
        F.num(s, "accuracy", w, positive=True, maximum=1.0, default=None),
        F.boolean(s, "use_error_control", w, default=None),
        F.num(s, "target_realtime_rate", w, nonnegative=True, default=None),
        F.boolean(s, "publish_every_time_step", w, default=None))
