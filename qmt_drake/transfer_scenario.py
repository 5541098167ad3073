"""The transfer scenario built: the plain data of config/ (config/sections.Scenario) plus what it turns
into, and the one loader of transfer scenarios.

    sc = load_scenario("thesis-ch4")   # config/scenario.load_transfer_data + the checks below
    sc.arm, sc.limit_set, sc.bottle    # built on first use by qmt_drake/builders.py, once per object

`TransferScenario` is the data (same fields, same fingerprint) with the built objects as cached
properties that call the builders by plain import: a reader (or a tool) follows `sc.arm` to
builders.build_arm, and config/ stays plain data that calls nothing registered. The loader then
checks what needs the built arm, one line each: the lists that go per joint (motor limits, gains,
motors, servos) against its joint count, the hand's own check (the tray: its points reachable, the
bottle at rest), and the `uncertainty` distributions (sweep/parameters.py, whose vocabulary it is).

Scenarios pickle (sweeps ship them to worker processes): the built objects (Drake objects) are left
out of the pickled state and rebuilt on first use; `dataclasses.replace` gives a new TransferScenario
whose objects are built again from its own data.
"""

from __future__ import annotations

from collections.abc import Sized
from dataclasses import fields
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from qmt_drake.builders import build_arm, build_bottle, build_limit_set
from qmt_drake.config.registry import ACTUATORS, hand_entry
from qmt_drake.config.scenario import Scenario, load_transfer_data
from qmt_drake.errors import QmtInputError
from qmt_drake.limits import LimitSet
from qmt_drake.model.arm import ArmModel
from qmt_drake.sweep.parameters import validate_uncertainty
from qmt_drake.systems.tray_object import BottleSpec

_BUILT = ("arm", "limit_set", "bottle")  # the cached properties, not data


class TransferScenario(Scenario):
    """A transfer Scenario (its data fields unchanged) with the objects it is built into."""

    @cached_property
    def arm(self) -> ArmModel:
        """The ArmModel of the URDF with the carried part welded to the hand (builders.build_arm)."""
        return build_arm(self)

    @cached_property
    def limit_set(self) -> LimitSet:
        """The scenario's LimitSet (builders.build_limit_set)."""
        return build_limit_set(self)

    @cached_property
    def bottle(self) -> BottleSpec | None:
        """Tray scenarios: the BottleSpec of the payload and the tray hand (builders.build_bottle); None otherwise."""
        return build_bottle(self)

    @property
    def gear_ratio(self) -> np.ndarray:
        return np.asarray(self.arm.gear_ratio, dtype=float)

    def __getstate__(self) -> dict[str, Any]:
        return {k: v for k, v in self.__dict__.items() if k not in _BUILT}  # Drake objects: rebuilt on use

    def data(self) -> Scenario:
        """The plain data (config/sections.Scenario), without the built objects."""
        return Scenario(**{f.name: getattr(self, f.name) for f in fields(Scenario)})


def load_scenario(name_or_path: str | Path, overrides: dict | None = None) -> TransferScenario:
    """Load a built-in transfer scenario by name or a YAML file by path; `overrides` is merged into the
    raw YAML mapping first (nested dicts merge key by key). Bad input: one-line QmtInputError naming the
    file and the key (module docstring)."""
    return build_transfer_scenario(load_transfer_data(name_or_path, overrides))


def build_transfer_scenario(data: Scenario) -> TransferScenario:
    """The TransferScenario of plain data, checked against its built arm (module docstring); its
    objects are built on first use (the arm now, by the checks)."""
    sc = TransferScenario(**{f.name: getattr(data, f.name) for f in fields(Scenario)})
    where = str(sc.source_path)
    if sc.uncertainty:
        validate_uncertainty(sc.uncertainty, f"{where}: uncertainty")
    _check_against_arm(sc, where)
    check_loaded = hand_entry(sc).check_loaded
    if check_loaded is not None:
        check_loaded(sc, where)  # e.g. the tray: its points reachable, the bottle at rest
    return sc


def _check_against_arm(sc: TransferScenario, where: str) -> None:
    """Lists that go one per joint must match the arm's joint count (loads the arm once)."""
    n = sc.arm.n_dof
    checks: list[tuple[str, Sized]] = [("limits.motor_torque_limit_Nm", sc.limits.motor_torque_limit_Nm)]
    checks += [(f"control.{k}", v) for k, v in sc.control.items()]
    per_joint = ACTUATORS[sc.actuator.kind].per_joint if sc.actuator is not None else None
    if per_joint is not None:  # the actuator's list with one entry per joint (motors, servos)
        checks.append((f"actuator.{per_joint}", getattr(sc.actuator, per_joint)))
    for key, v in checks:
        if len(v) != n:
            raise QmtInputError(f"{where}: {key} has {len(v)} entries but the arm "
                                f"({sc.urdf_path.name}) has {n} joints; give one per joint")
