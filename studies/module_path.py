"""The path of one CLI command through the package's modules, and how often it goes back up.

Runs `qmt-drake ARGS` in this process under a profile hook that records every call from one
qmt_drake module into another (calls inside one module, and calls into pydrake, numpy, ... are not
counted). Each module has a floor: 1 for a module that imports nothing of the package, else one more
than the highest module it imports at its top level (read from its source with `ast`, the same rule
tests/test_architecture.py keeps). A call that goes *up* is one from a module into a module on a
higher floor: code that has gone down to the plant or the limits coming back up to a command or a
planner, the back-and-forth a reader has to follow.

    python -m studies.module_path -- plan ur5-suction-bins --method toppra --out /tmp/p.json
    python -m studies.module_path --json out/module_path.json -- simulate ur5-suction-bins --plan /tmp/p.json

prints the distinct modules in the order first entered, the number of module-to-module calls, and the
calls that go up (each distinct pair once, with how often), and writes them as JSON with --json.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import io
import json
import sys
from collections import Counter
from pathlib import Path

from qmt_drake.outputs import write_text_atomic

PACKAGE = "qmt_drake"
ROOT = Path(__file__).resolve().parents[1] / PACKAGE


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _top_level_imports(path: Path, name: str) -> set[str]:
    """The package modules `path` imports at module level (not inside functions)."""
    out: set[str] = set()
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith(PACKAGE)}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else []))
            if base.startswith(PACKAGE):
                out.add(base)
                out |= {f"{base}.{a.name}" for a in node.names}
    return out


def floors() -> dict[str, int]:
    """Module name -> floor (1 = imports nothing of the package)."""
    files = {_module_name(p): p for p in ROOT.rglob("*.py")}
    deps = {m: {d for d in _top_level_imports(p, m) if d in files and d != m} for m, p in files.items()}
    floor: dict[str, int] = {}

    def of(m: str, seen: tuple = ()) -> int:
        if m not in floor:
            floor[m] = 1 + max((of(d, seen + (m,)) for d in deps[m] if d not in seen), default=0)
        return floor[m]

    for m in files:
        of(m)
    return floor


def trace(argv: list[str]) -> list[tuple[str, str]]:
    """(caller module, callee module) of every call between two package modules while the CLI runs."""
    from qmt_drake.apps.cli import main  # the CLI, imported before tracing (its import is not the path)

    calls: list[tuple[str, str]] = []

    def hook(frame, event, _arg):
        if event != "call":
            return
        callee = frame.f_globals.get("__name__", "")
        back = frame.f_back
        caller = back.f_globals.get("__name__", "") if back is not None else ""
        if callee.startswith(PACKAGE) and caller.startswith(PACKAGE) and callee != caller:
            calls.append((caller, callee))

    sys.setprofile(hook)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            rc = main(argv)
    finally:
        sys.setprofile(None)
    if rc not in (0, 3):
        raise SystemExit(f"qmt-drake {' '.join(argv)} exited {rc}; fix the command first")
    return calls


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="write the path as JSON here")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the qmt-drake arguments")
    args = ap.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    floor = floors()
    calls = trace(command)
    order = list(dict.fromkeys(m for pair in calls for m in pair))
    up = [(a, b) for a, b in calls if floor.get(b, 0) > floor.get(a, 0)]
    ups = Counter(up)
    print(f"qmt-drake {' '.join(command)}")
    print(f"modules entered: {len(order)}; module-to-module calls: {len(calls)}; calls that go up: {len(up)} "
          f"({len(ups)} distinct pairs)")
    for m in order:
        print(f"  floor {floor.get(m, 0):2d}  {m}")
    print("calls that go up (caller floor -> callee floor, count):")
    for (a, b), n in ups.most_common():
        print(f"  {a} ({floor[a]}) -> {b} ({floor[b]})  x{n}")
    if args.json:
        write_text_atomic(args.json, json.dumps({"command": command, "modules": [{"module": m, "floor": floor.get(m, 0)}
                                                                       for m in order],
                                      "calls": len(calls), "calls_up": len(up),
                                      "up_pairs": [{"from": a, "to": b, "count": n} for (a, b), n in ups.items()]}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
