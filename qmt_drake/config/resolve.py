"""Where a scenario is and what kind it is: the one resolver for every scenario kind.

A scenario is named by a built-in name (a file `models/scenarios/NAME.yaml`) or by the path of a YAML
file. Its kind is the file's top-level `kind:` (transfer scenarios have none). Every loader (transfer,
spatial, energy-time), the API and the CLI ask this module, so a name resolves the same way everywhere
and a file of the wrong kind is answered with the command that takes it.
"""

from __future__ import annotations

import difflib
from pathlib import Path

from qmt_drake.config.fields import read_yaml_mapping
from qmt_drake.config.registry import ENERGY_TIME, TRANSFER
from qmt_drake.errors import QmtInputError

MODELS_DIR = Path(__file__).resolve().parents[2] / "models"
SCENARIO_DIR = MODELS_DIR / "scenarios"
TASK_DIR = MODELS_DIR / "tasks"  # seed 003's design tasks (design/tasks.py): no `kind`, a list of `units`
DESIGN_TASK = "design_task"  # what load_scenario_data calls a design task file
SPATIAL = "spatial_transfer"  # spatial_task.SPATIAL_KIND (config imports nothing above it)
# planners/spatial_methods.METHODS (named here for the same reason; a test checks they agree)
SPATIAL_METHODS = ("toppra", "ruckig", "family_optimum", "ga", "trajopt", "toppra-drake", "snopt", "ipopt", "steepest",
                   "collocation")

# What each kind is called in a message, and the command that takes it.
_KIND_ROUTES = {
    TRANSFER: ("a transfer scenario", "`qmt-drake plan {name} --method ga|optimum|toppra|...`"),
    SPATIAL: ("a spatial (3-D) scenario", f"`qmt-drake plan {{name}} --method {'|'.join(SPATIAL_METHODS)} "
              "--json PLAN.json` and co-simulate it with `qmt-drake simulate {name} --plan PLAN.json`"),
    ENERGY_TIME: ("a seed-001 energy-time scenario", "`qmt-drake plan {name} --method snopt|steepest|ipopt|"
                  "collocation`; simulate, benchmark and sweeps take transfer scenarios"),
}


def builtin_path(name_or_path) -> Path | None:
    """The file of a built-in name (no folder, no suffix), or None."""
    if not isinstance(name_or_path, str) or "/" in name_or_path or Path(name_or_path).suffix:
        return None
    p = SCENARIO_DIR / f"{name_or_path}.yaml"
    return p if p.is_file() else None


def scenario_kind(path: str | Path) -> str:
    """A scenario file's top-level `kind` (none: 'transfer'); '' when the file cannot be read as a
    YAML mapping (the loader then says why in one line). Never raises: a probe."""
    try:
        raw = read_yaml_mapping(path)  # the loaders' reader: its size cap and alias refusal apply to the probe
    except (OSError, UnicodeDecodeError, ValueError, TypeError, QmtInputError):
        return ""
    return str(raw.get("kind", TRANSFER)) if isinstance(raw, dict) else ""


def kind_of(name_or_path) -> str:
    """The kind of a built-in name or a YAML path; '' when it is neither (never raises)."""
    if not isinstance(name_or_path, (str, Path)):
        return ""
    path = builtin_path(name_or_path) or Path(name_or_path)
    try:
        return scenario_kind(path) if path.is_file() else ""
    except OSError:  # a name too long for the file system, ...
        return ""


def builtin_scenarios(kind: str = TRANSFER) -> list[str]:
    """Names of the built-in scenarios of one kind."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml") if scenario_kind(p) == kind)


def resolve_scenario(name_or_path, kind: str | None = None) -> Path:
    """The YAML file of a built-in name or a path; with `kind`, a file of another kind is refused with
    the command that takes it. QmtInputError (one line) when it is neither a built-in nor a file."""
    if not isinstance(name_or_path, (str, Path)) or str(name_or_path) == "":
        raise QmtInputError(f"scenario {name_or_path!r}: give a built-in name ({', '.join(_all_builtins())}) "
                            "or the path of a YAML file")
    path = builtin_path(name_or_path) or Path(name_or_path)
    if path.is_dir():
        raise QmtInputError(f"scenario '{name_or_path}' is a directory; give a built-in name "
                            f"({', '.join(_all_builtins())}) or a YAML file")
    if not path.is_file():
        # every kind's built-ins: a name that exists nowhere has no kind yet (the commands guess 'transfer'),
        # and a misspelt spatial name must not be answered with the planar list alone
        names = _all_builtins()
        near = difflib.get_close_matches(str(name_or_path), names, n=1)
        hint = f"; did you mean {near[0]}?" if near else ""
        raise QmtInputError(f"scenario '{name_or_path}' is neither a built-in ({', '.join(names)}) nor a YAML "
                            f"file that exists{hint}")
    found = scenario_kind(path)
    if kind is not None and found in _KIND_ROUTES and found != kind:
        what, route = _KIND_ROUTES[found]
        raise QmtInputError(f"scenario '{name_or_path}' is {what}: plan it with {route.format(name=name_or_path)}")
    return path


def refuse_scenario_file(raw, where: str, what: str, fix: str) -> None:
    """A scenario file given where a sweep spec or a design task is expected, named as such (not as its
    first key the other file does not know, e.g. "unknown key 'actuators'")."""
    if isinstance(raw, dict) and ("arm" in raw or raw.get("kind") in (SPATIAL, ENERGY_TIME)):
        raise QmtInputError(f"{where} is a scenario file, not {what}; {fix}")


def builtin_tasks() -> list[str]:
    """Names of the built-in design tasks (models/tasks/NAME.yaml)."""
    return sorted(p.stem for p in TASK_DIR.glob("*.yaml"))


def resolve_task(name_or_path) -> Path:
    """The YAML file of a built-in design task's name (models/tasks/) or of a path; one line if neither."""
    if isinstance(name_or_path, (str, Path)) and str(name_or_path) != "":
        path = Path(name_or_path)
        if path.exists():
            return path
        named = TASK_DIR / f"{name_or_path}.yaml"
        if "/" not in str(name_or_path) and named.is_file():
            return named
    raise QmtInputError(f"task file {str(name_or_path)!r} not found; give a path or one of {', '.join(builtin_tasks())}")


def is_design_task(name_or_path) -> bool:
    """A built-in design task's name, or a YAML file without `kind` whose top level lists `units` (a design
    task: design/tasks.py); never raises."""
    if isinstance(name_or_path, str) and "/" not in name_or_path and (TASK_DIR / f"{name_or_path}.yaml").is_file():
        return True
    if not isinstance(name_or_path, (str, Path)) or builtin_path(name_or_path) is not None:
        return False
    try:
        raw = read_yaml_mapping(name_or_path) if Path(name_or_path).is_file() else None
    except (OSError, UnicodeDecodeError, ValueError, TypeError, QmtInputError):
        return False
    return isinstance(raw, dict) and "kind" not in raw and "units" in raw


def _all_builtins() -> list[str]:
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml"))
