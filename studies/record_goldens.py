"""Golden files: the outputs behind the published numbers, recorded from the code as it is, so that a
move of code can be gated on them bit for bit (issue 27, item 8).

One file per case, tests/golden/<case>.json, for every shipped scenario kind (the thesis's planar
magnet arms ch.2/3/4 and the five-via task, the CRANE-X7 tray, seed 001's energy-time arm, the UR5
with suction cup and with the magnet, the Panda with the tray) and the cheap deterministic planners
(TOPP-RA, the family optimum, Ruckig, the thesis's genes; a short seeded GA where it takes seconds):

  plan      the public surface of the Plan: method, feasible, motion_time_s, peak_ratios, and
            plan.sample(t) at RESAMPLE_POINTS times evenly over [0, T] (q, qd, qdd), exact
  plan_json plan.to_json_dict() with what varies from run to run dropped (wall clocks) or made
            portable (the scenario's path relative to the checkout); every list of more than
            DIGEST_OVER numbers (the 1 kHz samples) is replaced by its length and the SHA-256 of its JSON
  cosim     the co-simulation's summary dict (qmt_drake.simulate) of that plan, wall clocks dropped
  diagrams  GetGraphvizString() of every top-level Diagram the co-simulation built, the system ids
            (a process-wide counter) renumbered in order of first appearance

Floats are stored as Python's repr (json), which reads back to the same double: comparisons are
exact (==, NaN equal to NaN, int and float kept apart). Files are small (no 1 kHz arrays).

  PYTHONPATH=. python -m studies.record_goldens --out tests/golden            # record every case
  PYTHONPATH=. python -m studies.record_goldens --out tests/golden --check    # recompute, compare
  PYTHONPATH=. python -m studies.record_goldens --check --only ch4-toppra     # some cases (repeat --only)
  PYTHONPATH=/other/checkout python studies/record_goldens.py --check         # another checkout's code

--check prints, per case, `same` or the file and the first differing field, and exits 1 if any differ.
tests/test_golden.py recomputes the FAST subset on every test run.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import math
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder_

import qmt_drake
from qmt_drake import load_scenario, plan_with, simulate
from qmt_drake.outputs import jsonable, write_text_atomic

ROOT = Path(__file__).resolve().parents[1]
# the checkout whose qmt_drake runs (paths are made relative to it, so another checkout can be checked:
# PYTHONPATH=/other/checkout python studies/record_goldens.py --check)
CHECKOUT = Path(qmt_drake.__file__).resolve().parents[1]
DEFAULT_DIR = ROOT / "tests" / "golden"
RESAMPLE_POINTS = 41
DIGEST_OVER = 64  # a list holding more numbers than this is stored as its length and SHA-256
# a key containing one of these is a clock, not a result (found by recording twice and comparing)
VOLATILE_KEYS = ("wall", "real_time_factor", "planning_s", "solve_s")


@dataclass(frozen=True)
class Case:
    name: str
    scenario: str
    method: str
    options: dict = field(default_factory=dict)
    cosim: bool = True


# The cases; FAST is the subset tests/test_golden.py recomputes on every run (< 60 s on a loaded
# 2-core machine): one case of each co-simulation build path and each planner implementation that is cheap.
CASES = (
    Case("ch2-toppra", "thesis-ch2", "toppra"),
    Case("ch2-optimum", "thesis-ch2", "optimum"),
    Case("ch2-ruckig", "thesis-ch2", "ruckig"),
    Case("ch2-thesis", "thesis-ch2", "thesis"),
    Case("ch3-toppra", "thesis-ch3", "toppra"),
    Case("ch3-optimum", "thesis-ch3", "optimum"),
    Case("ch3-ruckig", "thesis-ch3", "ruckig"),
    Case("ch3-thesis", "thesis-ch3", "thesis"),
    Case("ch4-toppra", "thesis-ch4", "toppra"),
    Case("ch4-optimum", "thesis-ch4", "optimum"),
    Case("ch4-ruckig", "thesis-ch4", "ruckig"),
    Case("ch4-thesis", "thesis-ch4", "thesis"),
    Case("ch4-ga-seed0-short", "thesis-ch4", "ga", {"max_generations": 20}),
    Case("via5-toppra", "via5-ch4", "toppra"),
    Case("tray-toppra", "crane-tray", "toppra"),
    Case("ohsaka-fig2-snopt", "ohsaka-fig2", "snopt"),
    Case("ohsaka-fig3-snopt-one-start", "ohsaka-fig3", "snopt", {"pattern": (1, 1, 1)}),
    Case("ohsaka-fig3-snopt", "ohsaka-fig3", "snopt"),
    Case("ur5-suction-toppra", "ur5-suction-bins", "toppra"),
    Case("ur5-suction-optimum", "ur5-suction-bins", "family_optimum"),
    Case("ur5-suction-ruckig", "ur5-suction-bins", "ruckig"),
    Case("ur5-magnet-toppra", "ur5-magnet-part", "toppra"),
    Case("ur5-magnet-line-optimum", "ur5-magnet-part", "family_optimum", {"family": "line_cubic_velocity"}),
    Case("panda-tray-toppra", "panda-tray-cup", "toppra"),
    Case("panda-tray-optimum", "panda-tray-cup", "family_optimum"),
)
FAST = ("ch4-toppra", "ch4-ga-seed0-short", "ch2-ruckig", "tray-toppra", "ohsaka-fig2-snopt", "ur5-magnet-toppra")


# --- what is recorded -------------------------------------------------------------------------------

_ID = re.compile(r"(?<![A-Za-z0-9_])(_|clusters|cluster|s)(\d+)")  # digraph _N, clusterN..., clustersN..., sN
_ADDRESS = re.compile(r"0x[0-9a-fA-F]+|(?<=@)[0-9a-fA-F]{8,16}(?![0-9a-fA-F])")  # 0x..., and Drake's name@address


def normalise_graphviz(text: str) -> str:
    """System ids renumbered by first appearance (they count every System the process made before),
    each run of edge lines sorted (Drake lists them in an order that varies between processes) and
    memory addresses (0x... and the 16 hex digits of Drake's default `Type@address` names) replaced by 0x0."""
    ids: dict[str, str] = {}

    def sub(m: re.Match) -> str:
        return m.group(1) + ids.setdefault(m.group(2), str(len(ids)))
    lines, out, edges = _ADDRESS.sub("0x0", _ID.sub(sub, text)).split("\n"), [], []
    for line in lines + [""]:
        if "->" in line:
            edges.append(line)
            continue
        out += sorted(edges) + [line]
        edges = []
    return "\n".join(out[:-1])


@contextlib.contextmanager
def captured_diagrams():
    """Every Diagram built through DiagramBuilder.Build in the block, in order (the list is filled)."""
    built: list[Diagram] = []
    cls = DiagramBuilder_[float]
    original = cls.Build

    def build(self):
        d = original(self)
        built.append(d)
        return d
    cls.Build = build
    try:
        yield built
    finally:
        cls.Build = original


def _children(d: Diagram, out: set[int]) -> set[int]:
    for s in d.GetSystems():
        out.add(id(s))
        if isinstance(s, Diagram):
            _children(s, out)
    return out


def top_level(diagrams: list[Diagram]) -> list[Diagram]:
    """The diagrams that are not a subsystem of another one in the list."""
    inner: set[int] = set()
    for d in diagrams:
        _children(d, inner)
    return [d for d in diagrams if id(d) not in inner]


def _digest(values: Any) -> dict:
    text = json.dumps(values, allow_nan=True)
    return {"n": len(values), "sha256": hashlib.sha256(text.encode()).hexdigest()}


def _count_numbers(x: Any) -> int:
    if isinstance(x, list):
        return sum(_count_numbers(v) for v in x)
    return 1 if isinstance(x, (int, float)) and not isinstance(x, bool) else 0


def compact(x: Any, key: str = "") -> Any:
    """x with volatile keys dropped, the scenario path made relative and big number lists digested."""
    if isinstance(x, dict):
        out = {}
        for k, v in x.items():
            if any(w in k for w in VOLATILE_KEYS):
                continue
            out[k] = compact(v, k)
        return out
    if isinstance(x, list):
        if _count_numbers(x) > DIGEST_OVER:
            return _digest(x)
        return [compact(v, key) for v in x]
    if isinstance(x, str) and key.endswith("path") and x.startswith(str(CHECKOUT)):
        return Path(x).relative_to(CHECKOUT).as_posix()
    return x


def plan_record(plan) -> dict:
    T = float(plan.motion_time_s)
    t = np.linspace(0.0, T, RESAMPLE_POINTS)
    q, qd, qdd = plan.sample(t)
    return jsonable({"method": plan.method, "feasible": bool(plan.feasible), "motion_time_s": T,
                     "peak_ratios": dict(getattr(plan, "peak_ratios", {}) or {}),
                     "t_s": t, "q_rad": np.asarray(q), "qd_rad_s": np.asarray(qd), "qdd_rad_s2": np.asarray(qdd)})


def record(case: Case) -> dict:
    """Plan and co-simulate `case`; the golden dict (module docstring)."""
    sc = load_scenario(case.scenario)
    plan = plan_with(case.method, sc, seed=0, **case.options)
    out = {"case": case.name, "scenario": case.scenario, "method": case.method, "options": jsonable(case.options),
           "plan": plan_record(plan), "plan_json": compact(jsonable(plan.to_json_dict()))}
    if case.cosim:
        with captured_diagrams() as built:
            summary = simulate(sc, plan)
        out["cosim"] = compact(jsonable(summary))
        out["diagrams"] = [normalise_graphviz(d.GetGraphvizString()) for d in top_level(built)]
    # Through JSON and back, so that a fresh record compares with a file as the file reads.
    return json.loads(json.dumps(out, allow_nan=True))


# --- comparison ---------------------------------------------------------------------------------------

def first_difference(golden: Any, fresh: Any, path: str = "") -> str | None:
    """The path of the first field where `fresh` differs from `golden`, and both values; None if the
    two are identical (floats bit for bit, NaN equal to NaN, int and float and bool apart)."""
    if type(golden) is not type(fresh):
        return f"{path or '<root>'}: {type(golden).__name__} {golden!r:.80} -> {type(fresh).__name__} {fresh!r:.80}"
    if isinstance(golden, dict):
        for k in golden:
            if k not in fresh:
                return f"{path}.{k}: missing now"
            d = first_difference(golden[k], fresh[k], f"{path}.{k}")
            if d:
                return d
        extra = [k for k in fresh if k not in golden]
        return f"{path}.{extra[0]}: new field" if extra else None
    if isinstance(golden, list):
        for i, (a, b) in enumerate(zip(golden, fresh)):
            d = first_difference(a, b, f"{path}[{i}]")
            if d:
                return d
        return None if len(golden) == len(fresh) else f"{path}: length {len(golden)} -> {len(fresh)}"
    if isinstance(golden, float) and math.isnan(golden) and math.isnan(fresh):
        return None
    if isinstance(golden, str) and golden != fresh:
        return f"{path}: strings differ at line {_first_line_diff(golden, fresh)}"
    if golden != fresh:
        return f"{path}: {golden!r} -> {fresh!r}"
    return None


def _first_line_diff(a: str, b: str) -> str:
    la, lb = a.splitlines(), b.splitlines()
    for i, (x, y) in enumerate(zip(la, lb)):
        if x != y:
            return f"{i + 1}: {x!r:.100} -> {y!r:.100}"
    return f"{min(len(la), len(lb)) + 1} (lengths {len(la)} -> {len(lb)} lines)"


def golden_path(directory: Path, case: Case) -> Path:
    return Path(directory) / f"{case.name}.json"


def check(case: Case, directory: Path = DEFAULT_DIR) -> str | None:
    """None if a fresh record of `case` equals its golden file, else one line naming the file and the
    first differing field."""
    path = golden_path(directory, case)
    if not path.is_file():
        return f"{path}: no golden file (record it: python -m studies.record_goldens --only {case.name})"
    golden = json.loads(path.read_text())
    d = first_difference(golden, record(case))
    return None if d is None else f"{path}: first difference at {d}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(DEFAULT_DIR), help="the golden directory (default tests/golden)")
    ap.add_argument("--check", action="store_true", help="compare with the files instead of writing them")
    ap.add_argument("--only", action="append", choices=[c.name for c in CASES], help="this case only (repeatable)")
    ap.add_argument("--fast", action="store_true", help="the subset tests/test_golden.py checks")
    args = ap.parse_args(argv)
    names = args.only or (FAST if args.fast else [c.name for c in CASES])
    bad = 0
    for case in (c for c in CASES if c.name in names):
        t0 = time.process_time()
        if args.check:
            msg = check(case, Path(args.out))
            bad += msg is not None
            print(f"{case.name:30s} {'same' if msg is None else msg}  ({time.process_time() - t0:.1f} s CPU)")
        else:
            path = golden_path(Path(args.out), case)
            path.parent.mkdir(parents=True, exist_ok=True)
            write_text_atomic(path, json.dumps(record(case), indent=1, allow_nan=True) + "\n")
            print(f"{case.name:30s} -> {path}  ({time.process_time() - t0:.1f} s CPU)", flush=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
