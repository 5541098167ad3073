"""Checks of command-line values shared by the `qmt-drake` commands (apps/cli.py, apps/spatial_cli.py):
each raises a one-line QmtInputError naming the flag and the fix, before any long computation."""

from __future__ import annotations

import json
import math
import sys

from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import check_one_stdout, check_output_path, write_text_atomic


def check_int(value, flag: str, minimum: int, fix: str) -> None:
    if value is not None and value < minimum:
        raise QmtInputError(f"{flag} {value} must be >= {minimum}; {fix}")


def check_positive_finite(value, flag: str, fix: str) -> None:
    if value is not None and not (math.isfinite(value) and value > 0):
        raise QmtInputError(f"{flag} {value} must be a finite positive number; {fix}")


def check_outputs(args, *flags: str) -> None:
    paths = {flag: getattr(args, flag.lstrip("-").replace("-", "_"), None) for flag in flags}
    check_one_stdout(paths)
    for flag, path in paths.items():
        check_output_path(path, flag)


def given(args, names) -> list[str]:
    """The options among `names` the user gave (not at their None default), as --flags."""
    return ["--" + n.replace("_", "-") for n in names if getattr(args, n, None) is not None]


def parse_value(v: str):
    """An --option VALUE as int, else float, else the string."""
    for cast in (int, float):
        try:
            return cast(v)
        except ValueError:
            pass
    return v


def parse_options(pairs) -> dict:
    """--option KEY=VALUE pairs (None: none) as {KEY: parse_value(VALUE)}."""
    out = {}
    for kv in pairs or []:
        k, eq, v = kv.partition("=")
        if not eq or not k:
            raise QmtInputError(f"--option {kv!r} must be KEY=VALUE (e.g. jerk_limit=10)")
        out[k] = parse_value(v)
    return out


def progress(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def emit_json(data: dict, target: str | None) -> None:
    """Write `data` to the file `target` atomically, or print it for '-'; nothing for None."""
    if target is None:
        return
    text = json.dumps(data, indent=1)
    if target == "-":
        print(text)
    else:
        write_text_atomic(target, text + "\n")
