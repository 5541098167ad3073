"""The plug-in registries of the scenario's kinds: hands, actuators, objectives and trajectory families.

Each kind registers once, from the layer that owns it (hands.py: magnet and tray; actuators.py:
dc_motor_gear, ideal, dynamixel; problem.py and energy/objective.py: min_time, energy_time;
families/ and energy/fourier.py: the trajectory families), an entry that says what it adds (its
parser, limit terms, co-simulation, constructor, ...). config/ looks kinds up here by their
string and never imports those layers: the entries are typed Any at this level. An unknown kind
is refused in one line that lists the registered ones.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from qmt_drake.errors import QmtInputError

# The modules that register the shipped kinds (hands, actuators, objectives, families), imported by name
# the first time a registry is consulted: whoever loads or unpickles a scenario gets them, whatever else they imported, instead of
# as a side effect of `import qmt_drake`; config/ still imports nothing above itself at import time.
PROVIDERS = ("qmt_drake.hands", "qmt_drake.actuators", "qmt_drake.problem", "qmt_drake.families",
             "qmt_drake.energy.objective", "qmt_drake.energy.fourier")
_providers_loaded = False


def load_providers() -> None:
    """Import PROVIDERS (once)."""
    global _providers_loaded
    if not _providers_loaded:
        _providers_loaded = True
        for name in PROVIDERS:
            importlib.import_module(name)


def check_registration(what: str, name: Any, registered: bool, replace: Any) -> None:
    """Every register_* call: `name` a non-empty string, not yet registered unless replace=True
    (a plug-in never silently replaces a built-in). One-line QmtInputError naming the name and the fix."""
    if not isinstance(replace, bool):
        raise QmtInputError(f"{what} {name!r}: replace must be True or False, got {replace!r}")
    if not isinstance(name, str) or not name.strip():
        raise QmtInputError(f"{what}: the name must be a non-empty string, got {name!r}")
    if registered and not replace:
        raise QmtInputError(f"{what} {name!r} is already registered; pass replace=True to replace it, or "
                            "register under another name")


def check_callable_fields(what: str, entry: Any) -> None:
    """At registration, not at first use: each field of a dataclass plug-in annotated Callable holds a
    callable (None only where the annotation allows None). One-line QmtInputError naming the field."""
    if not dataclasses.is_dataclass(entry) or isinstance(entry, type):
        return
    for f in dataclasses.fields(entry):
        ann = str(f.type)  # annotations are strings here (from __future__ import annotations)
        value = getattr(entry, f.name)
        if "Callable" in ann and not callable(value) and not (value is None and "None" in ann):
            raise QmtInputError(f"{what}: {f.name} must be a callable, got {type(value).__name__} {value!r:.60}; "
                                f"see {type(entry).__name__}'s docstring")


class Registry:
    """kind -> entry (an object with a `kind` attribute) of one scenario section (e.g. 'hand')."""

    def __init__(self, section: str) -> None:
        self.section = section
        self._entries: dict[str, Any] = {}

    def register(self, entry: Any, *, replace: bool = False) -> Any:
        """Register `entry` under entry.kind; a kind registers once (replace=True to swap it). Its
        callable fields and its scenario_kind are checked now (one-line QmtInputError), not at first use."""
        kind = getattr(entry, "kind", None)
        what = f"{self.section}.kind"
        if not isinstance(kind, str) or not kind.strip():
            raise QmtInputError(f"a {self.section} plug-in needs a non-empty string `kind`, got {kind!r}")
        check_registration(what, kind, kind in self._entries, replace)
        check_callable_fields(f"{what} {kind!r}", entry)
        sk = getattr(entry, "scenario_kind", TRANSFER)
        if not isinstance(sk, str) or not sk:
            raise QmtInputError(f"{what} {kind!r}: scenario_kind {sk!r} must name a scenario kind, e.g. {TRANSFER!r}")
        self._entries[kind] = entry
        return entry

    def unregister(self, kind: str) -> None:
        self._entries.pop(kind, None)

    def kinds(self, accept: Callable[[Any], bool] | None = None) -> tuple[str, ...]:
        """The registered kinds (those whose entry `accept` takes), in registration order."""
        load_providers()
        return tuple(k for k, e in self._entries.items() if accept is None or accept(e))

    def get(self, kind: Any, where: str = "", accept: Callable[[Any], bool] | None = None) -> Any:
        """The entry of `kind`; else a one-line QmtInputError naming the input (`where`: the
        section's place, e.g. 'models/x.yaml: hand') and listing the registered kinds (those
        `accept` takes)."""
        load_providers()
        entry = self._entries.get(kind) if isinstance(kind, str) else None
        if entry is None or (accept is not None and not accept(entry)):
            known = self.kinds(accept)
            raise QmtInputError(f"{where or self.section}.kind {kind!r} is not one of "
                                f"{', '.join(known) if known else '(none registered)'} (the registered kinds)")
        return entry

    def __contains__(self, kind: object) -> bool:
        load_providers()
        return kind in self._entries

    def __getitem__(self, kind: str) -> Any:
        load_providers()
        return self._entries[kind]

    def __iter__(self) -> Iterator[str]:
        load_providers()
        return iter(self._entries)

    def __len__(self) -> int:
        load_providers()
        return len(self._entries)


DEFAULT_OBJECTIVE_KIND = "min_time"  # a transfer scenario without an objective section
TRANSFER = "transfer"  # the scenario kinds (config/scenario.scenario_kind): a transfer ...
ENERGY_TIME = "energy_time"  # ... or seed 001's energy-time experiment


@dataclass(frozen=True)
class FamilyPlugin:
    """A trajectory family: make(scenario) -> the family object (genes -> q, qd, qdd), which checks
    the scenario's gene names against its own and takes their [min, max] bounds from `family.genes`;
    scenario_kind: which scenarios use it (TRANSFER, or ENERGY_TIME for seed 001's Fourier family,
    whose genes the energy problem builds)."""

    kind: str
    make: Callable[..., Any]
    scenario_kind: str = TRANSFER


@dataclass(frozen=True)
class ObjectivePlugin:
    """An objective: make(problem data) -> the object whose cost (and, for the GA, `fitness`) a
    planner optimises; scenario_kind: which scenarios use it; summary: the cost in one line."""

    kind: str
    make: Callable[..., Any]
    scenario_kind: str = TRANSFER
    summary: str = ""


def for_scenario_kind(scenario_kind: str) -> Callable[[Any], bool]:
    """`accept` of the entries that serve scenarios of `scenario_kind`."""
    return lambda entry: entry.scenario_kind == scenario_kind


HANDS = Registry("hand")  # hands.HandPlugin
ACTUATORS = Registry("actuator")  # actuators.ActuatorPlugin
OBJECTIVES = Registry("objective")  # ObjectivePlugin
FAMILIES = Registry("family")  # FamilyPlugin

DEFAULT_HAND_KIND = "magnet"  # a scenario without a hand section: the thesis's magnet (its terms, its co-simulation)


def hand_kind(scenario: Any) -> str:
    """The kind of a scenario's hand (DEFAULT_HAND_KIND without a hand section)."""
    return str(getattr(scenario.hand, "kind", DEFAULT_HAND_KIND)) if scenario.hand is not None else DEFAULT_HAND_KIND


def hand_entry(scenario: Any) -> Any:
    """The registered hand plug-in of `scenario` (hands.HandPlugin); one line if its kind has none."""
    return HANDS.get(hand_kind(scenario), f"scenario {scenario.name}: hand")


def actuator_entry(scenario: Any) -> Any:
    """The registered actuator plug-in of `scenario` (actuators.ActuatorPlugin; None without an
    actuator section); one line if its kind has none."""
    act = scenario.actuator
    return None if act is None else ACTUATORS.get(act.kind, f"scenario {scenario.name}: actuator")
