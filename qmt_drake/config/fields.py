"""One validation layer for every file a user writes: scenarios, sweep specs, design tasks.

Each check raises QmtInputError with one line that names the input (`where.key`) and the fix. Numbers
are checked as numbers: a YAML `true` is not 1 and a string is not 0.5. `read_yaml_mapping` refuses a
mapping with a duplicated key (PyYAML keeps the last value silently).
"""

from __future__ import annotations

import math
import numbers
import re
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from qmt_drake.errors import QmtInputError

MISSING = object()
# An input YAML file (scenario, sweep spec, design task) is a few kB (the shipped ones are under 8 kB);
# parsing is ~4 us a byte here (10,000 task poses, 380 kB: 1.6 s), so a larger file is refused unread.
MAX_YAML_BYTES = 256 * 1024
# Values of an input written out (aliases expanded): the shipped files hold a few thousand.
MAX_YAML_VALUES = 1_000_000


class _UniqueKeyLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # libyaml's parser when present: fast
    """SafeLoader that refuses a duplicated key in any mapping, and an alias bomb: aliases (`*name`) are
    read, but a file whose values, written out, pass MAX_YAML_VALUES (the "billion laughs": a few lines
    that expand into billions of values) or that refers to itself is refused."""

    def construct_document(self, node):
        _refuse_alias_bombs(node)
        return super().construct_document(node)

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                dup = key in seen
            except TypeError:  # unhashable key: let PyYAML report it
                dup = False
            if dup:
                line = key_node.start_mark.line + 1
                raise QmtInputError(f"duplicated key '{key}' at line {line}; give each key once")
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


# YAML 1.2 reads 1e5 and 1e-5 (no dot) as numbers; PyYAML follows YAML 1.1 and reads them as text. Every
# scenario, sweep and task file goes through this loader, so one number rule holds for all of them.
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"), list("-+0123456789"))


def _refuse_alias_bombs(root) -> None:
    """Aliases are read (yaml.safe_dump writes them for a repeated list), but the values they stand for
    are counted as if written out: a file whose expansion passes MAX_YAML_VALUES (the "billion laughs")
    or an alias to its own enclosing value (a cycle) is refused in one line."""
    size: dict[int, int] = {}
    stack, open_ = [(root, False)], set()
    while stack:
        node, children_done = stack.pop()
        key = id(node)
        kids = ([x for pair in node.value for x in pair] if isinstance(node, yaml.MappingNode)
                else list(node.value) if isinstance(node, yaml.SequenceNode) else [])
        if children_done:
            open_.discard(key)
            size[key] = 1 + sum(size[id(k)] for k in kids)
            if size[key] > MAX_YAML_VALUES:
                raise QmtInputError(f"the value at line {node.start_mark.line + 1} expands through aliases to over "
                                    f"{MAX_YAML_VALUES:,} values; write the values out or check the file")
            continue
        if key in size:
            continue
        if key in open_:
            raise QmtInputError(f"the value at line {node.start_mark.line + 1} contains an alias to itself; "
                                "write the values out")
        open_.add(key)
        stack.append((node, True))
        stack.extend((k, False) for k in kids if id(k) not in size)


def yaml_problem(exc: Exception, text: str = "") -> str:
    """PyYAML's error as one phrase with where it is: its problem and line/column (its first line alone,
    e.g. 'while scanning for the next token', says neither); a tab there named, YAML's commonest slip."""
    problem, mark = getattr(exc, "problem", None), getattr(exc, "problem_mark", None)
    if not problem or mark is None:
        return str(exc).splitlines()[0]
    lines = text.splitlines()
    line = lines[mark.line] if 0 <= mark.line < len(lines) else ""
    tab = "; indent with spaces, not tabs" if line[mark.column:mark.column + 1] == "\t" else ""
    return f"{problem} at line {mark.line + 1}, column {mark.column + 1}{tab}"


def load_yaml_text(text: str, where: str) -> Any:
    """YAML text parsed with duplicated keys refused; one-line QmtInputError naming `where`."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - SafeLoader subclass
    except QmtInputError as exc:
        raise QmtInputError(f"{where}: {exc}") from None
    except yaml.YAMLError as exc:
        raise QmtInputError(f"{where}: not valid YAML ({yaml_problem(exc, text)})") from None
    except RecursionError:
        raise QmtInputError(f"{where}: nested too deeply to read; an input file is a few levels deep") from None


def read_yaml_mapping(path: str | Path, what: str = "file", example: str | Path | None = None) -> dict:
    """The YAML mapping in `path` (duplicated keys refused); one line if it cannot be read or is
    not a mapping. `what` names the kind of file ("scenario", "sweep spec"), `example` a file to copy."""
    path = Path(path)
    if path.is_dir():
        raise QmtInputError(f"{path}: is a directory; give a {what} YAML file")
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise QmtInputError(f"{path}: cannot be read ({exc.strerror})") from None
    if size > MAX_YAML_BYTES:
        raise QmtInputError(f"{path}: {size / 1024:.0f} KiB is over the {MAX_YAML_BYTES // 1024} KiB of an input file "
                            f"(a {what} is a few kB); split it or check that it is the right file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise QmtInputError(f"{path}: not a UTF-8 text file; a {what} is a YAML text file") from None
    except OSError as exc:
        raise QmtInputError(f"{path}: cannot be read ({exc.strerror})") from None
    raw = load_yaml_text(text, str(path))
    see = f" (see {example})" if example else ""
    if raw is None:
        raise QmtInputError(f"{path}: the file is empty; a {what} is a YAML mapping{see}")
    if not isinstance(raw, dict):
        raise QmtInputError(f"{path}: a {what} file must be a YAML mapping{see}")
    return raw


def key_path(where: str, key) -> str:
    """Where a key sits, for a message: `file.yaml: key` at a file's top level, `where.key` inside a section
    (`file.yaml: hand.cup` + radius_m -> `file.yaml: hand.cup.radius_m`)."""
    return f"{where}: {key}" if str(where).endswith((".yaml", ".yml")) else f"{where}.{key}"


def merge_overrides(base: dict, extra: dict) -> dict:
    """`base` with `extra` merged in key by key (nested mappings merge; any other value replaces; a gene
    map is replaced whole, its keys being the family's genes in order): the one rule for every kind's
    `overrides`, applied to the raw YAML mapping before it is validated."""
    out = dict(base)
    for k, v in extra.items():
        nested = isinstance(v, dict) and isinstance(out.get(k), dict) and k != "genes"
        out[k] = merge_overrides(out[k], v) if nested else _plain(v)
    return out


def _plain(v):
    """A numpy array or scalar from a Python caller as the YAML's plain list or number (`com_m=np.array(...)`
    was refused as "must be a list of numbers"); the validators then check it as the file's value."""
    return v.tolist() if isinstance(v, (np.ndarray, np.generic)) else v


def show(v) -> str:
    """repr of a user value, cut to 60 characters for a one-line message."""
    s = repr(v)
    return s if len(s) <= 60 else s[:57] + "..."


def is_number(v) -> bool:
    """A real number that is not a bool (YAML `true` is not 1)."""
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))


def check_keys(d: dict, allowed: set, where: str) -> None:
    """Refuse a key outside `allowed` (a misspelt key is never dropped silently)."""
    unknown = sorted(str(k) for k in set(d) - set(allowed))
    if unknown:
        raise QmtInputError(f"{where}: unknown key '{unknown[0]}'; allowed keys are "
                            f"{', '.join(sorted(str(a) for a in allowed))}")


def mapping(d: dict, key: str, where: str, *, default=MISSING) -> dict:
    """d[key] as a mapping (None/missing -> `default` if given)."""
    if default is not MISSING and d.get(key) is None:
        return default
    v = need(d, key, where)
    if not isinstance(v, dict):
        raise QmtInputError(f"{key_path(where, key)} must be a mapping, got {show(v)}")
    return v


def need(d: dict, key: str, where: str) -> Any:
    """d[key], refusing a missing or null key."""
    if key not in d or d[key] is None:
        raise QmtInputError(f"{where}: missing key '{key}'")
    return d[key]


def num(d: dict, key: str, where: str, *, positive: bool = False, nonnegative: bool = False,
        minimum: float | None = None, maximum: float | None = None, default=MISSING) -> float:
    """A finite number (not a bool); positive / non-negative / within [minimum, maximum] if asked.
    A missing key takes `default` if given."""
    if default is not MISSING and d.get(key) is None:
        return default
    v = need(d, key, where)
    if not is_number(v):
        raise QmtInputError(f"{key_path(where, key)} must be a number, got {show(v)}{float_text_hint(v)}")
    v = float(v)
    if not math.isfinite(v) or (positive and v <= 0) or (nonnegative and v < 0):
        want = "positive" if positive else "non-negative" if nonnegative else "finite"
        raise QmtInputError(f"{key_path(where, key)} must be {want}, got {v}")
    if (minimum is not None and v < minimum) or (maximum is not None and v > maximum):
        raise QmtInputError(f"{key_path(where, key)} must lie in [{minimum if minimum is not None else '-inf'}, "
                            f"{maximum if maximum is not None else 'inf'}], got {v}")
    return v


def integer(d: dict, key: str, where: str, *, minimum: int, maximum: int | None = None,
            default=MISSING) -> int:
    """An integer (not a bool, not 2.0) >= minimum (and <= maximum if given)."""
    if default is not MISSING and d.get(key) is None:
        return default
    v = need(d, key, where)
    if not (isinstance(v, numbers.Integral) and not isinstance(v, bool)):
        raise QmtInputError(f"{key_path(where, key)} must be an integer, got {show(v)}")
    if v < minimum:
        raise QmtInputError(f"{key_path(where, key)} must be >= {minimum}, got {v}")
    if maximum is not None and v > maximum:
        raise QmtInputError(f"{key_path(where, key)} must be <= {maximum}, got {v}")
    return int(v)


def string(d: dict, key: str, where: str, *, choices=None, default=MISSING, what: str = "a non-empty string",
           allow_empty: bool = False) -> str:
    """A string, non-empty unless allow_empty (one of `choices` if given); `what` says what it names."""
    if default is not MISSING and d.get(key) is None:
        return default
    v = need(d, key, where)
    if not isinstance(v, str) or not (v or allow_empty):
        raise QmtInputError(f"{key_path(where, key)} must be {what}, got {show(v)}")
    if choices is not None and v not in choices:
        raise QmtInputError(f"{key_path(where, key)} {v!r} is not one of {', '.join(map(str, choices))}")
    return v


def boolean(d: dict, key: str, where: str, *, default=MISSING) -> bool:
    """true or false (not 0/1, not 'yes' as a string)."""
    if default is not MISSING and d.get(key) is None:
        return default
    v = need(d, key, where)
    if not isinstance(v, bool):
        raise QmtInputError(f"{key_path(where, key)} must be true or false, got {show(v)}")
    return v


def vector(d: dict, key: str, where: str, *, positive: bool = False, nonnegative: bool = False,
           length: int | None = None, what: str = "") -> np.ndarray:
    """A non-empty list of finite numbers (positive / non-negative if asked; `length` entries)."""
    v = need(d, key, where)
    said = f" ({what})" if what else ""  # (the default was "numbers": "a list of numbers (numbers)")
    if not isinstance(v, list) or not v or not all(is_number(x) for x in v):
        raise QmtInputError(f"{key_path(where, key)} must be a list of numbers{said}, got {show(v)}{float_text_hint(v)}")
    a = np.asarray(v, dtype=float)
    bad = ~np.isfinite(a) | ((a <= 0) if positive else (a < 0) if nonnegative else False)
    if np.any(bad):
        sign = "positive " if positive else "non-negative " if nonnegative else "finite "
        raise QmtInputError(f"{key_path(where, key)} must be a list of {sign}numbers{said}, got {a.tolist()}")
    if length is not None and len(a) != length:
        raise QmtInputError(f"{key_path(where, key)} has {len(a)} entries; give {length}{said}")
    return a


def integers(d: dict, key: str, where: str, *, minimum: int, length: int | None = None, distinct: bool = False,
             what: str = "integers") -> list[int]:
    """A non-empty list of integers (not bools, not 2.0), each >= minimum; `length` entries; `distinct`."""
    v = need(d, key, where)
    if not isinstance(v, list) or not v or not all(isinstance(x, numbers.Integral) and not isinstance(x, bool)
                                                   for x in v):
        raise QmtInputError(f"{key_path(where, key)} must be a list of integers ({what}), got {show(v)}")
    if length is not None and len(v) != length:
        raise QmtInputError(f"{key_path(where, key)} has {len(v)} entries; give {length} ({what})")
    if min(v) < minimum or (distinct and len(set(v)) != len(v)):
        raise QmtInputError(f"{key_path(where, key)} {v} must be {'distinct ' if distinct else ''}integers >= {minimum} ({what})")
    return [int(x) for x in v]


def sequence(d: dict, key: str, where: str, *, default=MISSING, min_length: int = 0, length: int | None = None,
             item: type | None = None, what: str = "values") -> list:
    """d[key] as a list (None/missing -> `default` if given) of at least min_length (exactly `length`)
    entries, each an `item` if given; `what` names the entries in the message."""
    if default is not MISSING and d.get(key) is None:
        return default
    v = need(d, key, where)
    ok = isinstance(v, list) and len(v) >= min_length and (length is None or len(v) == length)
    if not ok or (item is not None and not all(isinstance(x, item) for x in v)):
        count = f"{length} " if length is not None else f">= {min_length} " if min_length else ""
        raise QmtInputError(f"{key_path(where, key)} must be a list of {count}{what}, got {show(v)}")
    return v


def float_text_hint(v) -> str:
    """The fix when YAML 1.1 read a number as text (PyYAML takes 1e-5 without a dot for a string)."""
    items = v if isinstance(v, list) else [v]
    for x in items:
        if isinstance(x, str):
            try:
                float(x)
            except ValueError:
                continue
            return f"; YAML reads {x} as text: write it with a decimal point, e.g. {float(x):.1e}"
    return ""



def direction(d: dict, key: str, where: str, *, what: str = "a direction [x, y, z]") -> np.ndarray:
    """A unit vector from a nonzero list of 3 finite numbers (a zero vector has no direction)."""
    v = vector(d, key, where, length=3, what=what)
    n = float(np.linalg.norm(v))
    if not n > 1e-9:
        raise QmtInputError(f"{key_path(where, key)} {v.tolist()} has no direction; give a nonzero vector, e.g. [0, 0, 1]")
    return v / n


def principal_inertia(d: dict, key: str, where: str) -> np.ndarray:
    """Principal central moments of inertia [kg m^2] a rigid body can have: positive, and each at most the
    sum of the other two (the triangle inequality, I_k = sum over the mass of the squared distances to
    axis k, so I_1 + I_2 >= I_3)."""
    v = vector(d, key, where, positive=True, length=3, what="principal moments [kg m^2]")
    for k in range(3):
        if v[k] > v[(k + 1) % 3] + v[(k + 2) % 3] * (1 + 1e-9):
            raise QmtInputError(f"{key_path(where, key)} {v.tolist()}: no rigid body has these principal moments (moment "
                                f"{k + 1} exceeds the sum of the other two); check the values and their axes")
    return v


def radians(d: dict, key: str, where: str, *, length: int | None = None, what: str = "angles [rad]") -> np.ndarray:
    """Angles [rad]; a value beyond 2 pi in magnitude is refused as probably degrees."""
    v = vector(d, key, where, length=length, what=what)
    if np.any(np.abs(v) > 2 * math.pi + 1e-9):
        raise QmtInputError(f"{key_path(where, key)} {v.tolist()}: angles beyond 2 pi look like degrees; give radians "
                            f"(e.g. {np.radians(v).round(4).tolist()})")
    return v


def xml_file(path: Path, root: str, where: str, what: str) -> Path:
    """An existing file whose text has the XML element `root` (a URDF has <robot>): a directory, a missing
    file or another kind of file (HTML, binary) is refused naming it."""
    if path.is_dir():
        raise QmtInputError(f"{where}: {path} is a directory; give the {what} file in it")
    if not path.is_file():
        raise QmtInputError(f"{where}: {path} does not exist; give the path of a {what} file")
    try:
        with path.open("rb") as f:
            head = f.read(1 << 16).decode("utf-8", errors="replace")
    except OSError as exc:
        raise QmtInputError(f"{where}: {path} cannot be read ({exc.strerror})") from None
    if f"<{root}" not in head:
        raise QmtInputError(f"{where}: {path} is not a {what} (no <{root}> element in it); give a {what} file")
    return path
