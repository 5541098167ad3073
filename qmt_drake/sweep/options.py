"""Planner options of a sweep spec's plans (`plans[i].options`), checked before any case runs.

Each option is checked against the method's row of the one planner registry (planners/registry.py:
its name among the planner's keywords, read from its signature, and its type and range) and must be
a plain value (number, string, true/false). One line naming the option and the fix, via
QmtInputError.
"""

from __future__ import annotations

from qmt_drake.config.fields import is_number, show
from qmt_drake.errors import QmtInputError
from qmt_drake.planners import registry


def planner_options(method: str, kind: str = registry.TRANSFER) -> set[str]:
    """The option names the planner of `method` accepts on scenarios of `kind`."""
    return set(registry.find(kind, method).options())


def check_options(options, method: str, at: str, kind: str = registry.TRANSFER) -> dict:
    """`options` of a plan of `method` as a checked dict (see the module docstring)."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise QmtInputError(f"{at}.options must be a mapping of planner keyword arguments, got {show(options)}")
    for k, v in options.items():
        if not (is_number(v) or isinstance(v, (str, bool))):
            raise QmtInputError(f"{at}.options.{k} must be a number, a string or true/false, got {show(v)}")
        if is_number(v) and v != v:  # NaN
            raise QmtInputError(f"{at}.options.{k} must be a finite number, got {v}")
    registry.check(kind, method, dict(options), f"{at}.options")
    return dict(options)
