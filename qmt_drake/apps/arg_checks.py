"""Checks of command-line values shared by the `qmt-drake` commands (apps/cli.py, apps/spatial_cli.py):
each raises a one-line QmtInputError naming the flag and the fix, before any long computation."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from qmt_drake.api_checks import number
from qmt_drake.carried_cells import parse_cells
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import check_one_stdout, check_output_path, write_text_atomic


def check_int(value, flag: str, minimum: int, fix: str) -> None:
    if value is not None:  # one implementation with the API's checks (api_checks.number)
        number(value, flag, minimum=minimum, fix=fix)


def check_positive_finite(value, flag: str, fix: str) -> None:
    if value is not None:
        number(value, flag, positive=True, fix=fix)


# the commands' input files (the scenario, a plan, a joint path): an output written over one destroys it
INPUT_ARGS = {"scenario": "the scenario file", "plan": "the plan file", "path": "the path file (--path)"}


def check_outputs(args, *flags: str) -> None:
    """The output paths of `flags`: at most one stdout, each writable, no two the same file, none an input."""
    paths = {flag: getattr(args, flag.lstrip("-").replace("-", "_"), None) for flag in flags}
    check_one_stdout(paths)
    for flag, path in paths.items():
        check_output_path(path, flag)
    seen = {}
    for flag, path in paths.items():
        if path is None or str(path) == "-":
            continue
        key = Path(path).resolve()
        if key in seen:  # the second write would replace the first result: it would be lost
            raise QmtInputError(f"{seen[key]} and {flag} both name {path}; give each output its own file")
        seen[key] = flag
    for attr, what in INPUT_ARGS.items():
        src = getattr(args, attr, None)
        if isinstance(src, str) and Path(src).is_file() and Path(src).resolve() in seen:
            raise QmtInputError(f"{seen[Path(src).resolve()]} {src} is {what}: writing it would replace the input; "
                                "choose another path")


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


def carried_cells_arg(args):
    """--carried-cells parsed (carried_cells.parse_cells; None when not given), refused without --carried."""
    text = getattr(args, "carried_cells", None)
    if text is None:
        return None
    if not args.carried:
        raise QmtInputError("--carried-cells: an option of --carried (the fastest-carried search); add --carried or "
                            "drop it")
    return parse_cells(text)
