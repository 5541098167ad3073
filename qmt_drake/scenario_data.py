"""Every scenario file as plain typed data, and the one builder of each kind: the entry a user (or a tool)
follows from a YAML file to the objects the planners use.

    data = load_scenario_data("ur5-suction-bins")   # a frozen dataclass of what the file says
    sc = build_scenario(data)                        # the built scenario (plant, chain, IK, ...)

The kind comes from the file (config/resolve.py: its top-level `kind`, or a design task's `units`):

    kind               plain data (this module returns)        built by
    transfer           config/sections.Scenario                 transfer_scenario.build_transfer_scenario
    spatial_transfer   spatial_data.SpatialScenarioData         spatial_task.build_spatial_scenario
    energy_time        energy/experiments.EnergyScenarioData    energy/scenario.build_experiment
    design_task        design/tasks.Task                        itself (no Drake object: design/ builds per type)

Every value is checked through config/fields.py (one number rule; errors name `file: section.key`).
The data holds no Drake object: numbers, strings, paths, numpy arrays and small frozen records.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from qmt_drake.config.registry import ENERGY_TIME, TRANSFER
from qmt_drake.config.resolve import DESIGN_TASK, SPATIAL, is_design_task, kind_of, resolve_scenario
from qmt_drake.config.sections import Scenario
from qmt_drake.design.tasks import Task, load_task
from qmt_drake.energy.experiments import EnergyScenarioData
from qmt_drake.energy.scenario import build_experiment, load_energy_data
from qmt_drake.errors import QmtInputError
from qmt_drake.spatial_data import SpatialScenarioData, parse_spatial_data
from qmt_drake.spatial_task import build_spatial_scenario
from qmt_drake.transfer_scenario import TransferScenario, build_transfer_scenario, load_scenario

ScenarioData = Scenario | SpatialScenarioData | EnergyScenarioData | Task


def scenario_data_kind(name_or_path: str | Path) -> str:
    """The kind of a built-in name or a path (transfer, spatial_transfer, energy_time, design_task)."""
    if is_design_task(name_or_path):
        return DESIGN_TASK
    return kind_of(name_or_path) or TRANSFER


def load_scenario_data(name_or_path: str | Path) -> ScenarioData:
    """The plain typed data of a scenario file of any kind (module docstring); QmtInputError (one line
    naming the file and the key path) for any bad value."""
    kind = scenario_data_kind(name_or_path)
    if kind == DESIGN_TASK:
        return load_task(name_or_path)
    if kind == SPATIAL:
        return parse_spatial_data(name_or_path)
    if kind == ENERGY_TIME:
        return load_energy_data(name_or_path)
    resolve_scenario(name_or_path, TRANSFER)  # a file of an unknown kind: one line naming the command
    # every check of the loader (those against the built arm too), then the plain data only
    return load_scenario(name_or_path).data()


def build_scenario(data: ScenarioData) -> Any:
    """The built scenario of plain data: a SpatialScenario, an Experiment, a TransferScenario (its arm,
    limit set and bottle built on first use), or the data itself for a design task (design/ builds per type)."""
    if isinstance(data, SpatialScenarioData):
        return build_spatial_scenario(data)
    if isinstance(data, EnergyScenarioData):
        return build_experiment(data)
    if isinstance(data, TransferScenario):
        return data
    if isinstance(data, Scenario):
        return build_transfer_scenario(data)
    if isinstance(data, Task):
        return data
    raise QmtInputError(f"build_scenario: {type(data).__name__} is not scenario data; pass load_scenario_data(NAME)")
