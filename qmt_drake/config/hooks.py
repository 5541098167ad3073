"""The registry through which layers above config/ plug into the scenario without config/ importing
them: builders (what a scenario turns into: its arm model, limit set, bottle; qmt_drake/builders.py)
and section validators (a section whose vocabulary a higher layer owns: sweep/parameters.py checks
`uncertainty`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from qmt_drake.config.registry import check_registration
from qmt_drake.errors import QmtInputError

_BUILDERS: dict[str, Callable[[Any], Any]] = {}
_VALIDATORS: dict[str, Callable[[dict, str], None]] = {}


def register_validator(section: str, check: Callable[[dict, str], None], *, replace: bool = False) -> None:
    """A layer above config/ that owns a section's vocabulary registers its check here (sweep/parameters.py
    checks `uncertainty` against the sweep parameters): check(raw_section, where) raises QmtInputError.
    A section registers once (replace=True to swap it)."""
    check_registration("section validator", section, section in _VALIDATORS, replace)
    if not callable(check):
        raise QmtInputError(f"section validator {section!r}: give a function check(raw_section, where)")
    _VALIDATORS[section] = check


def registered_validator(section: str) -> Callable[[dict, str], None] | None:
    return _VALIDATORS.get(section)


def register_builders(*, replace: bool = False, **builders: Callable[[Any], Any]) -> None:
    """qmt_drake/builders.py registers how a scenario's arm, limit_set and bottle are built; each
    once (replace=True to swap one)."""
    for what, build in builders.items():
        check_registration("builder", what, what in _BUILDERS, replace)
        if not callable(build):
            raise QmtInputError(f"builder {what!r}: give a function build(scenario)")
    _BUILDERS.update(builders)


def registered_builder(what: str) -> Callable[[Any], Any] | None:
    """The builder of scenario.<what> (called with the Scenario), None if none is registered."""
    return _BUILDERS.get(what)
