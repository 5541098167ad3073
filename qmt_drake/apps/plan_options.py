"""`qmt-drake plan`'s flags as a planner's options, checked against the one registry
(planners/registry.py) before any work, for every scenario kind.

A flag that sets a planner option names it here (FLAGS: option -> flag); `--option KEY=VALUE` gives
any other. The registry then refuses, in one line naming the flag, a method the scenario's kind does
not plan and an option the method does not take (saying which kind's planners take it), so no list of
"options of another kind" is kept here.
"""

from __future__ import annotations

from qmt_drake.apps.arg_checks import parse_options
from qmt_drake.config.resolve import kind_of
from qmt_drake.config.validate import check_scenario_kind
from qmt_drake.errors import QmtInputError
from qmt_drake.planners import registry

# option -> the flag that gives it (the registry's messages name the flag; other options: --option KEY)
FLAGS = {"generations": "--generations", "stall": "--stall", "checkpoint_path": "--checkpoint", "family": "--family",
         "c1": "--c1", "c2": "--c2", "m": "--m", "divisions": "--divisions", "coords": "--coords",
         "pattern": "--pattern", "max_iter": "--max-iter"}
DEFAULT_METHOD = {registry.TRANSFER: "ga", registry.SPATIAL: "ga", registry.ENERGY: "snopt"}


def scenario_kind(name_or_path) -> str:
    """The kind of a built-in name or a YAML path (config.resolve.kind_of; '' -> transfer, whose loader
    then says in one line why the file is none). A misspelt `kind:` is refused here, in the loaders' words:
    the registry has no row for it."""
    kind = kind_of(name_or_path) or registry.TRANSFER
    if kind not in registry.KINDS:
        check_scenario_kind({"kind": kind}, str(name_or_path))
    return kind


def _pattern(s: str | None):
    """--pattern "-+-" / "npn" as signs (+1/-1), "all" or None as None (every start)."""
    if s is None or s == "all":
        return None
    if len(s) != 3 or set(s) - {"+", "-", "p", "n"}:
        raise QmtInputError(f'--pattern "{s}" must be three signs like "--pattern=-+-" or "npn", or "all"')
    return tuple(1 if c in "+p" else -1 for c in s)


def flag_options(args) -> dict:
    """The planner options the flags give (a flag not given, at its None default, gives none) and
    --option KEY=VALUE."""
    opts = {}
    for option, flag in FLAGS.items():
        value = getattr(args, flag[2:].replace("-", "_"), None)
        if value is not None:
            opts[option] = _pattern(value) if option == "pattern" else value
    for key, value in parse_options(getattr(args, "option", None)).items():
        if key in opts:
            raise QmtInputError(f"--option {key}: given by {FLAGS[key]} too; give it once")
        opts[key] = value
    return opts


def checked_method(args, kind: str) -> tuple[registry.Method, dict]:
    """(the registry's row of --method on this kind, its options from the flags), checked in one line
    before any work: the method on the kind, each option's name, type and range, --seed only for a
    method that takes one. Sets args.method to the row's name (an alias resolved)."""
    given = flag_options(args)
    named = {k: f for k, f in FLAGS.items() if getattr(args, f[2:].replace("-", "_"), None) is not None}
    row, opts = registry.check(kind, args.method or DEFAULT_METHOD[kind], given, named)  # others: --option KEY
    if getattr(args, "seed", 0) not in (0, None) and "seed" not in row.passes:
        raise QmtInputError(f"--seed: the {kind.replace('_', ' ')} {row.name} planner draws no random numbers; drop --seed")
    args.method = row.name
    return row, opts
