"""Randomized bad inputs for every command (in the style of ruckig's randomized input tests).

`generate(command, klass, rng, ctx)` makes one bad command line (YAML files it needs are written
into ctx.tmp) for each class of issue 21: wrong types, out-of-range numbers, huge sizes, bad
paths, unknown / duplicated / misspelt keys. The generator is numpy's default_rng seeded with
SEED + the index of (command, class), so every run makes the same inputs. `run(argv)` calls the
CLI's main() in this process with the heavy entry points (planners, co-simulation, searches,
sweeps) replaced by a stub that raises `Accepted`: a bad input that slips through is caught in
milliseconds instead of starting minutes of work.

`python -m tests.inputs_fuzz --write docs/bad_inputs.md` regenerates the table of the note; the
test checks the file is what this makes.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import functools
import importlib
import io
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

from qmt_drake.apps.cli import main
from qmt_drake.config.scenario import SCENARIO_DIR

ROOT = Path(__file__).resolve().parents[1]
SEED = 20261125
N_PER_CLASS = 200
CLASSES = ("types", "ranges", "sizes", "paths", "keys")
COMMANDS = ("plan", "simulate", "design", "sweep", "benchmark")
WORDS = ("abc", "fast", "ten", "none", "1,5", "0x1g", "--", "1e", "NaN?", "", "[1]", "{}")
SCENARIOS = ("thesis-ch4", "thesis-ch2", "crane-tray")
TASK_DIR = ROOT / "models" / "tasks"
TASKS = ("peg_in_hole", "task1_welding_plate")
SPEC = {"name": "fuzz", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
        "sim": {"feedforward": "none"},
        "parameters": {"friction": [0.25, 0.35], "time_scale": [1.0, 0.8],
                       "coil_current_scale": {"dist": "uniform", "low": 0.95, "high": 1.05}},
        "monte_carlo": {"cases": 3, "seed": 1}}
# mappings whose keys are names the user chooses (a new key there is a new gene, not a misspelling)
FREE_KEY_MAPPINGS = {("family", "genes"), ("reported", "genes"), ("reported",), ("parameters",)}


class Accepted(Exception):
    """A bad input reached the work it should have been refused before."""


class Ctx:
    """Scratch folder, a plain file, and counters for file names."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = Path(tmp)
        self.afile = self.tmp / "a_file"
        self.afile.write_text("x")
        (self.tmp / "a_dir").mkdir(exist_ok=True)
        self.n = 0
        self._base = {}

    def name(self, suffix: str) -> Path:
        self.n += 1
        return self.tmp / f"in{self.n:05d}{suffix}"

    def scenario(self, name: str) -> dict:
        if name not in self._base:
            raw = yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text())
            raw["arm"]["urdf"] = str((SCENARIO_DIR / raw["arm"]["urdf"]).resolve())
            self._base[name] = raw
        return copy.deepcopy(self._base[name])

    def task(self, name: str) -> dict:
        if name not in self._base:
            self._base[name] = yaml.safe_load((TASK_DIR / f"{name}.yaml").read_text())
        return copy.deepcopy(self._base[name])

    def write(self, d, suffix=".yaml", text: str | None = None) -> str:
        p = self.name(suffix)
        p.write_text(text if text is not None else yaml.safe_dump(d, sort_keys=False))
        return str(p)


# ------------------------------------------------------------------------------ YAML mutations
def _leaves(d, path=()):
    """(path, value) of every scalar (and list-of-scalar element) in a nested mapping."""
    if isinstance(d, dict):
        for k, v in d.items():
            yield from _leaves(v, path + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield from _leaves(v, path + (i,))
    else:
        yield path, d


def _mappings(d, path=()):
    if isinstance(d, dict):
        yield path, d
        for k, v in d.items():
            yield from _mappings(v, path + (k,))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield from _mappings(v, path + (i,))


def _set(d, path, value):
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value


def _pick(rng, seq):
    return seq[int(rng.integers(len(seq)))]


def _numbers(d, skip=("reported", "notes", "description", "source", "name")):
    return [(p, v) for p, v in _leaves(d) if isinstance(v, (int, float)) and not isinstance(v, bool)
            and p[0] not in skip]


def wrong_type(rng, d, skip=("reported", "notes", "description", "source", "name")):
    """A number of `d` replaced by a word, a bool, a list or a mapping."""
    path, _ = _pick(rng, _numbers(d, skip))
    _set(d, path, _pick(rng, ["abc", "fast", True, False, {"value": 1}, "1.0.0", [[1]]]))
    return d


def non_finite(rng, d, skip=("reported", "notes", "description", "source", "name")):
    """A number of `d` replaced by inf, -inf or NaN (no number of any input may be non-finite)."""
    path, _ = _pick(rng, _numbers(d, skip))
    _set(d, path, _pick(rng, [float("inf"), float("-inf"), float("nan")]))
    return d


def misspell(rng, word: str) -> str:
    w = str(word)
    i = int(rng.integers(len(w))) if w else 0
    op = int(rng.integers(5))
    if op == 0 and len(w) > 1:
        out = w[:i] + w[i + 1:]
    elif op == 1:
        out = w[:i] + w[i:i + 1] * 2 + w[i + 1:]
    elif op == 2 and len(w) > 1:
        j = min(i + 1, len(w) - 1)
        out = w[:min(i, j)] + w[j] + w[min(i, j)] + w[j + 1:] if i != j else w + "s"
    elif op == 3:
        out = w[:i] + "xqz"[int(rng.integers(3))] + w[i + 1:]
    else:
        out = w.upper() if w != w.upper() else w + "_"
    return out if out != w else w + "_x"


def bad_key(rng, d):
    """A key of some fixed-key mapping in `d` misspelt (the value kept), or a new unknown key."""
    maps = [(p, m) for p, m in _mappings(d) if m and tuple(k for k in p if isinstance(k, str)) not in
            FREE_KEY_MAPPINGS and not (len(p) >= 1 and p[-1] in ("genes",))]
    path, m = _pick(rng, maps)
    key = _pick(rng, list(m))
    new = misspell(rng, key)
    while new in m:
        new += "_"
    if rng.random() < 0.75:
        m[new] = m.pop(key)
    else:
        m[new] = copy.deepcopy(m[key])
    return d


def duplicated_key_text(rng, d) -> str:
    """The YAML text of `d` with one `key: value` line written twice in its mapping."""
    lines = yaml.safe_dump(d, sort_keys=False, default_flow_style=False).splitlines()
    cand = [i for i, s in enumerate(lines) if re.match(r"^\s*[A-Za-z_][\w]*: \S", s)]
    i = _pick(rng, cand)
    return "\n".join(lines[:i + 1] + [lines[i]] + lines[i + 1:]) + "\n"


# ---------------------------------------------------------------------------- bad output paths
def bad_out_file(rng, ctx: Ctx) -> str:
    return _pick(rng, [f"/proc/x{int(rng.integers(1000))}.json", f"/proc/nowhere/{int(rng.integers(99))}/r.json",
                       f"{ctx.afile}/r{int(rng.integers(99))}.json", str(ctx.tmp / "a_dir"), "",
                       f"/dev/null/x{int(rng.integers(9))}.png", "/sys/x.html"])


def bad_out_dir(rng, ctx: Ctx) -> str:
    return _pick(rng, [f"/proc/x{int(rng.integers(1000))}", str(ctx.afile), f"{ctx.afile}/sub{int(rng.integers(9))}",
                       "", f"/dev/null/o{int(rng.integers(9))}", "/sys/out"])


def missing_input(rng, ctx: Ctx, suffix=".yaml") -> str:
    return _pick(rng, [str(ctx.tmp / f"missing{int(rng.integers(10**6))}{suffix}"), str(ctx.tmp / "a_dir"),
                       str(ctx.afile), f"{ctx.afile}/x{suffix}"])


def _junk(rng) -> str:
    """A random non-number: digits with a stray character."""
    return f"{int(rng.integers(100))}{_pick(rng, ['x', ',', '..', '/', ' 1', 'j', '%'])}{int(rng.integers(10))}"


def _int_word(rng) -> str:
    return _pick(rng, list(WORDS) + [f"{rng.uniform(0.1, 9):.2f}", "1e3", "two", _junk(rng), _junk(rng)])


# ----------------------------------------------------------------------------------- generators
def gen_plan(klass: str, rng, ctx: Ctx) -> list:
    sc = _pick(rng, SCENARIOS)
    energy = _pick(rng, ["ohsaka-fig2", "ohsaka-fig3", "ohsaka-fig4"])
    r = rng.random()
    if klass == "types":
        if r < 0.4:
            return ["plan", sc, _pick(rng, ["--seed", "--generations", "--stall"]), _int_word(rng)]
        if r < 0.55:
            return ["plan", energy, _pick(rng, ["--m", "--divisions", "--max-iter", "--c1", "--c2"]),
                    _pick(rng, ["abc", "fast", "1,5", "0x1g", "two"])]
        return ["plan", ctx.write(wrong_type(rng, ctx.scenario(sc))), "--method", "thesis"]
    if klass == "ranges":
        if r < 0.4:
            flag = _pick(rng, ["--seed", "--generations", "--stall"])
            lo = {"--seed": -10**6, "--generations": -10**6, "--stall": -10**6}[flag]
            hi = {"--seed": -1, "--generations": 0, "--stall": -1}[flag]
            return ["plan", sc, flag, str(int(rng.integers(lo, hi + 1)))]
        if r < 0.55:
            flag, val = _pick(rng, [("--m", str(-int(rng.integers(0, 99)))),
                                    ("--divisions", str(-int(rng.integers(0, 99)))),
                                    ("--max-iter", str(-int(rng.integers(0, 99)))),
                                    ("--c2", f"{-rng.uniform(0, 1e5):.1f}"), ("--c2", "0"), ("--c2", "inf"),
                                    ("--c1", "nan")])
            return ["plan", energy, flag, val]
        return ["plan", ctx.write(non_finite(rng, ctx.scenario(sc))), "--method", "thesis"]
    if klass == "sizes":
        if r < 0.3:
            return ["plan", sc, "--generations", str(int(10 ** rng.uniform(6.5, 18)))]
        if r < 0.5:
            return ["plan", energy, *_pick(rng, [["--m", str(int(10 ** rng.uniform(2.4, 6)))],
                                                 ["--divisions", str(int(10 ** rng.uniform(8, 15)))]])]
        d = ctx.scenario(sc)
        key, val = _pick(rng, [(("ga", "population"), 2 * int(10 ** rng.uniform(6, 9) / 2)),
                               (("ga", "max_generations"), int(10 ** rng.uniform(7, 12))),
                               (("sampling", "check_rate_hz"), float(10 ** rng.uniform(9.5, 14))),
                               (("sampling", "plan_rate_hz"), float(10 ** rng.uniform(9, 14)))])
        d.setdefault(key[0], {})[key[1]] = val
        return ["plan", ctx.write(d), "--method", "ga" if key[0] == "ga" else "thesis"]
    if klass == "paths":
        if r < 0.5:
            return ["plan", sc, _pick(rng, ["--json", "--trajectory-csv", "--checkpoint"]), bad_out_file(rng, ctx)]
        if r < 0.75:
            return ["plan", energy, _pick(rng, ["--json", "--execute", "--recording"]), bad_out_file(rng, ctx)]
        return ["plan", missing_input(rng, ctx), "--method", "thesis"]
    # keys
    d = ctx.scenario(sc)
    if r < 0.6:
        return ["plan", ctx.write(bad_key(rng, d)), "--method", "thesis"]
    return ["plan", ctx.write(None, text=duplicated_key_text(rng, d)), "--method", "thesis"]


def gen_simulate(klass: str, rng, ctx: Ctx) -> list:
    sc = _pick(rng, SCENARIOS)
    r = rng.random()
    base = ["simulate", sc, "--method", "thesis" if sc != "crane-tray" else "ruckig"]
    if klass == "types":
        if r < 0.5:
            flag = _pick(rng, ["--seed", "--time-scale", "--time-step-ms"])
            return base + [flag, _int_word(rng) if flag == "--seed" else _pick(rng, ["abc", "fast", "1,5", "0x1g", "two", "", "--"])]
        return ["simulate", ctx.write(wrong_type(rng, ctx.scenario(sc))), "--method", "thesis"]
    if klass == "ranges":
        if r < 0.5:
            return base + _pick(rng, [["--time-scale", _pick(rng, ["0", "inf", "nan", "-inf",
                                                                   f"{-rng.uniform(0, 100):.3f}"])],
                                      ["--time-step-ms", _pick(rng, ["0", "inf", "nan", f"{-rng.uniform(0, 9):.3f}"])],
                                      ["--seed", str(-int(rng.integers(1, 10**6)))]])
        return ["simulate", ctx.write(non_finite(rng, ctx.scenario(sc))), "--method", "thesis"]
    if klass == "sizes":
        if r < 0.6:
            return base + ["--time-scale", f"{10 ** rng.uniform(4.5, 12):.6g}"]
        return base + ["--time-step-ms", f"{10 ** rng.uniform(-12, -6):.3g}"]
    if klass == "paths":
        if r < 0.6:
            return base + [_pick(rng, ["--json", "--record"]), bad_out_file(rng, ctx)]
        if r < 0.8:
            return ["simulate", sc, "--plan", missing_input(rng, ctx, ".json")]
        return ["simulate", missing_input(rng, ctx)]
    d = ctx.scenario(sc)
    if r < 0.6:
        return ["simulate", ctx.write(bad_key(rng, d)), "--method", "thesis"]
    return ["simulate", ctx.write(None, text=duplicated_key_text(rng, d)), "--method", "thesis"]


def _task_wrong_type(rng, d):
    u = _pick(rng, d["units"])
    choice = int(rng.integers(8))
    word = _pick(rng, ["abc", "up", "forward", "big", True, 3.5, {"x": 1}])
    if choice == 0:
        d["units"][int(rng.integers(len(d["units"])))] = _pick(rng, [1, "P0", [0.5, 0, 0], True])
    elif choice == 1:
        d["obstacles"] = _pick(rng, [2, 0.5, "walls", True, {"a": 1}])
    elif choice == 2:
        d[_pick(rng, ["link_radius_m", "tool_radius_m", "a"])] = _pick(rng, ["big", "thin", True, [0.04], {"r": 1}])
    elif choice == 3:
        u[_pick(rng, ["work", "constrained", "free"])] = _pick(rng, ["up", "forward", "xy", 5, [1, 2], [{"x": 1}]])
    elif choice == 4:
        u[_pick(rng, ["position_m", "rpy_deg"])] = _pick(rng, ["down", 5, [1, "a", 2], [1, 2], [[1, 2, 3]], True])
    elif choice == 5:
        d["units"] = _pick(rng, ["P0", 5, {"name": "P"}, [], True])
    elif choice == 6:
        boxes = d.get("work_boxes") or [{"name": "b", "center_m": [3, 3, 3], "size_m": [0.1, 0.1, 0.1]}]
        b = _pick(rng, boxes)
        b[_pick(rng, ["center_m", "size_m"])] = _pick(rng, ["here", 1, [1, 2], ["a", 1, 2]])
        d["work_boxes"] = boxes
    else:
        u[_pick(rng, ["name", "a"])] = word if not isinstance(word, str) else {"n": word}
    return d


def gen_design(klass: str, rng, ctx: Ctx) -> list:
    t = _pick(rng, TASKS)
    r = rng.random()
    if klass == "types":
        if r < 0.35:
            return ["design", t, *_pick(rng, [["--seed", _int_word(rng)], ["--workers", _int_word(rng)],
                                              ["--generations", _pick(rng, ["a,b", "400", "1.5,2", "", "4,0,1", "x,1"])],
                                              ["--design", _pick(rng, ["BP", "BP:", "BP:zzzzzz", "BP:1,2", "1:0db000",
                                                                       "BP:a,b,c,d,e,f"])]])]
        return ["design", ctx.write(_task_wrong_type(rng, ctx.task(t)))]
    if klass == "ranges":
        if r < 0.35:
            return ["design", t, *_pick(rng, [["--seed", str(-int(rng.integers(1, 10**6)))],
                                              ["--workers", str(_pick(rng, [0, -1, 10**6, 257]))],
                                              ["--generations", f"{-int(rng.integers(0, 9))},{int(rng.integers(0, 9))}"],
                                              ["--generations", f"{int(rng.integers(1, 9))},{-int(rng.integers(1, 9))}"],
                                              ["--design", f"BP:0,{int(rng.integers(16, 99))},1,0,0,0"]])]
        d = ctx.task(t)
        u = _pick(rng, d["units"])
        choice = int(rng.integers(5))
        if choice == 0:
            d[_pick(rng, ["link_radius_m", "tool_radius_m"])] = _pick(rng, [-rng.uniform(1e-3, 1), rng.uniform(0.51, 9),
                                                                            float("nan"), float("inf")])
        elif choice == 1:
            u["a"] = _pick(rng, [-rng.uniform(0.01, 5), 1 + rng.uniform(0.01, 5), float("nan")])
        elif choice == 2:
            u["position_m"] = [float(x) for x in rng.uniform(-1, 1, 3) * rng.uniform(7, 1e6)]
        elif choice == 3:
            d["work_boxes"] = [{"name": "b", "center_m": [0, 0, 0], "size_m": [float(rng.uniform(-1, 0)), 1, 1]}]
        else:
            non_finite(rng, d, skip=("name", "description"))
        return ["design", ctx.write(d)]
    if klass == "sizes":
        if r < 0.9:
            return ["design", t, "--generations", f"{int(10 ** rng.uniform(6, 15))},{int(rng.integers(0, 200))}"]
        d = ctx.task(t)
        n = int(rng.integers(400, 600))  # the default GA: ~4.9 h at 400 unit tasks
        d["units"] = [dict(d["units"][i % len(d["units"])], name=f"P{i}") for i in range(n)]
        d["work_boxes"], d["obstacles"] = [], []
        return ["design", ctx.write(d)]
    if klass == "paths":
        if r < 0.6:
            return ["design", t, "--out", bad_out_dir(rng, ctx), *(["--design", "BP:0db000"] if rng.random() < 0.3 else [])]
        return ["design", missing_input(rng, ctx)]
    d = ctx.task(t)
    if r < 0.6:
        return ["design", ctx.write(bad_key(rng, d))]
    return ["design", ctx.write(None, text=duplicated_key_text(rng, d))]


def gen_sweep(klass: str, rng, ctx: Ctx) -> list:
    d = copy.deepcopy(SPEC)
    r = rng.random()
    if klass == "types":
        if r < 0.25:
            return ["sweep", ctx.write(d), _pick(rng, ["--workers", "--allowed-failures"]), _int_word(rng)]
        choice = int(rng.integers(6))
        if choice == 0:
            d[_pick(rng, ["scenario", "plans", "parameters", "sim", "monte_carlo"])] = _pick(rng, [5, True, [1], "x"])
            if d.get("scenario") in ("x",):
                d["scenario"] = 5
        elif choice == 1:
            d["parameters"][_pick(rng, ["friction", "time_scale"])] = _pick(rng, ["abc", [0.3, "x"], True, {"values": "a"}])
        elif choice == 2:
            d["parameters"]["coil_current_scale"][_pick(rng, ["low", "high"])] = _pick(rng, ["abc", True, [1], "1.0"])
        elif choice == 3:
            d["monte_carlo"][_pick(rng, ["cases", "seed"])] = _pick(rng, ["three", 2.5, True, [3], "3"])
        elif choice == 4:
            d["plans"] = [_pick(rng, [{"method": "ga", "options": {"max_generations": _pick(rng, ["10", 2.5, [1], True])}},
                                      {"method": 5}, "thesis", {"method": "ga", "options": [1, 2]},
                                      {"method": "ga", "options": "fast"}, {"file": 5}, {"method": "thesis", "seed": "0"}])]
        else:
            key = _pick(rng, ["time_step_s", "implicit_loop_damping", "feedforward"])
            d["sim"][key] = _pick(rng, {"time_step_s": ["abc", True, [1, 2], {"a": 1}, "0.001"],
                                        "implicit_loop_damping": ["abc", 1, 0, [True], "yes"],
                                        "feedforward": [3, True, [1], "fast"]}[key])
        return ["sweep", ctx.write(d)]
    if klass == "ranges":
        if r < 0.25:
            return ["sweep", ctx.write(d), *_pick(rng, [["--workers", str(-int(rng.integers(0, 99)))],
                                                        ["--allowed-failures", str(-int(rng.integers(1, 99)))]])]
        choice = int(rng.integers(5))
        if choice == 0:
            d["parameters"]["friction"] = [float(-rng.uniform(0, 1)), 0.3]
        elif choice == 1:
            d["parameters"]["time_scale"] = [_pick(rng, [0.0, float(-rng.uniform(0, 5)), float("nan"), float("inf")])]
        elif choice == 2:
            d["parameters"]["coil_current_scale"] = {"dist": "uniform", "low": 1.1, "high": float(rng.uniform(0, 1.09))}
        elif choice == 3:
            d["parameters"]["friction"] = {"dist": "normal", "mean": 0.3, "std": float(-rng.uniform(1e-3, 1))}
        else:
            d["monte_carlo"][_pick(rng, ["cases", "seed"])] = -int(rng.integers(1, 10**6))
        return ["sweep", ctx.write(d)]
    if klass == "sizes":
        choice = int(rng.integers(4))
        if choice == 0:
            d["monte_carlo"]["cases"] = int(10 ** rng.uniform(5, 12))
        elif choice == 1:
            d["parameters"]["time_scale"] = [1.0, float(10 ** rng.uniform(4.5, 9))]
        elif choice == 2:
            d["plans"] = [{"method": "ga", "options": {"max_generations": int(10 ** rng.uniform(7, 12))}}]
        else:
            d["parameters"]["time_step_s"] = [float(10 ** rng.uniform(-12, -7))]
        return ["sweep", ctx.write(d)]
    if klass == "paths":
        if r < 0.35:
            return ["sweep", ctx.write(d), "--out", bad_out_dir(rng, ctx)]
        if r < 0.6:
            return ["sweep", ctx.write(d), "--json", bad_out_file(rng, ctx)]
        if r < 0.75:
            d["plans"] = [{"file": missing_input(rng, ctx, ".json")}]
            return ["sweep", ctx.write(d)]
        if r < 0.9:
            return ["sweep", ctx.write(d), "--scheduler", _pick(rng, ["tcp://127.0.0.1:0", "nohost", "tcp://:80",
                                                                     "http://h:1", "tcp://h:99999", "udp://x:1",
                                                                     "tcp://no-such-host.invalid:8786"])]
        return ["sweep", missing_input(rng, ctx)]
    if r < 0.6:
        return ["sweep", ctx.write(bad_key(rng, d))]
    return ["sweep", ctx.write(None, text=duplicated_key_text(rng, d))]


def gen_benchmark(klass: str, rng, ctx: Ctx) -> list:
    cmd = _pick(rng, ["bench", "benchmark"])
    if klass == "types":
        flag = "--seeds" if cmd == "bench" else _pick(rng, ["--ga-seeds", "--jerk-limits"])
        return [cmd, flag, _pick(rng, ["abc", "ten", "0x1g", "two", "--", "2.5", _junk(rng)]) if flag != "--jerk-limits"
                else _pick(rng, ["abc", "fast", "0x1g", _junk(rng), _junk(rng)])]
    if klass == "ranges":
        if cmd == "bench":
            return [cmd, "--seeds", str(-int(rng.integers(0, 10**6)))]
        return [cmd, *_pick(rng, [["--ga-seeds", str(-int(rng.integers(1, 10**6)))],
                                  ["--jerk-limits", _pick(rng, ["0", "-1", "nan", "inf", f"{-rng.uniform(0, 9):.2f}"])]])]
    if klass == "sizes":
        if cmd == "bench":
            return [cmd, "--seeds", str(int(10 ** rng.uniform(3, 15)))]
        return [cmd, "--scenarios", "thesis-ch4", "--ga-seeds", *map(str, range(int(rng.integers(150, 400))))]
    if klass == "paths":
        return [cmd, "--out", bad_out_dir(rng, ctx)]
    d = ctx.scenario("thesis-ch4")
    text = yaml.safe_dump(bad_key(rng, d)) if rng.random() < 0.6 else duplicated_key_text(rng, d)
    return [cmd, "--scenario" if cmd == "bench" else "--scenarios", ctx.write(None, text=text)]


def _with_out(gen, flag="--out"):
    """Outputs into the scratch folder unless the input under test is the output itself."""
    def wrapped(klass, rng, ctx):
        argv = gen(klass, rng, ctx)
        return argv if flag in argv else argv + [flag, str(ctx.tmp / "out")]
    return wrapped


GENERATORS = {"plan": gen_plan, "simulate": gen_simulate, "design": _with_out(gen_design),
              "sweep": _with_out(gen_sweep), "benchmark": _with_out(gen_benchmark)}


# --------------------------------------------------------------------------------------- running
# Heavy entry points replaced while a bad input runs: reaching one means the input was accepted.
STUBS = ("qmt_drake.planners.registry:plan", "qmt_drake.hands:run_simulate", "qmt_drake.design.search:run_all_types",
         "qmt_drake.sweep.runner:dask_client", "qmt_drake.energy.nlp:solve_nlp",
         "qmt_drake.energy.steepest:steepest_descent", "qmt_drake.apps.bench:run_bench",
         "qmt_drake.apps.benchmark:run_benchmark")


def _accepted(*args, **kwargs):
    raise Accepted("a bad input reached the work")


def _energy_through(plan):
    """registry.plan stubbed except on energy-time scenarios, whose planner checks its inputs (E.problem)
    before any solve and whose solvers are stubbed (STUBS)."""
    def stub(scenario, method, **kwargs):
        registry = importlib.import_module("qmt_drake.planners.registry")
        if registry.kind_of_scenario(scenario) == registry.ENERGY:
            return plan(scenario, method, **kwargs)
        return _accepted()
    return stub


THROUGH = {"qmt_drake.planners.registry:plan": _energy_through}


# Lists of the built-in scenarios: each call parses every built-in YAML file (~70 ms); the list is
# fixed while the tests run, so it is computed once (speed only: the same names are returned).
CACHED = ("qmt_drake.config.scenario:builtin_scenarios", "qmt_drake.energy.scenario:builtin_scenarios",
          "qmt_drake.energy.scenario:builtin_energy_scenarios")


@contextlib.contextmanager
def stubbed():
    """Replace each entry point of STUBS (and CACHED) in every loaded qmt_drake module that holds
    it (modules import these names at their top, so the defining module is not enough). On the way
    out every qmt_drake module holding a stub gets the original back, also one first imported while
    stubbed (the CLI imports its command modules lazily): otherwise the stub would stay in it and a
    later test in the same process would run into it."""
    swapped = []
    for spec in STUBS + CACHED:
        mod, _, attr = spec.partition(":")
        original = getattr(importlib.import_module(mod), attr)
        new = functools.cache(original) if spec in CACHED else THROUGH.get(spec, lambda _f: _accepted)(original)
        swapped.append((attr, original, new))
        for name, m in list(sys.modules.items()):
            if (name == "qmt_drake" or name.startswith("qmt_drake.")) and getattr(m, attr, None) is original:
                setattr(m, attr, new)
    try:
        yield
    finally:
        for name, m in list(sys.modules.items()):
            if name == "qmt_drake" or name.startswith("qmt_drake."):
                for attr, original, new in swapped:
                    if getattr(m, attr, None) is new:
                        setattr(m, attr, original)


def run(argv: list) -> tuple[int | str, str]:
    """(exit code or 'accepted' or the exception's name, stderr) of main(argv) in this process."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exc:
            rc = exc.code
        except Accepted:
            rc = "accepted"
        except Exception as exc:  # noqa: BLE001 - a traceback is what the test looks for
            rc = f"{type(exc).__name__}: {exc}"
    return rc, err.getvalue()


def cases(command: str, klass: str, ctx: Ctx, n: int = N_PER_CLASS) -> list[list]:
    """The n bad inputs of (command, class), from default_rng(SEED + index of the pair)."""
    rng = np.random.default_rng(SEED + COMMANDS.index(command) * len(CLASSES) + CLASSES.index(klass))
    return [GENERATORS[command](klass, rng, ctx) for _ in range(n)]


def problems(command: str, klass: str, ctx: Ctx, n: int = N_PER_CLASS) -> tuple[list, list]:
    """(every (argv, rc, stderr) that is not exit 2 with one line and no traceback, all results)."""
    bad, results = [], []
    with stubbed():
        for argv in cases(command, klass, ctx, n):
            rc, err = run(argv)
            lines = err.strip().splitlines()
            results.append((argv, rc, err))
            if rc != 2 or len(lines) != 1 or "Traceback" in err or not lines[0].startswith("qmt-drake: "):
                bad.append((argv, rc, err))
    return bad, results


# ------------------------------------------------------------------------- the issue's own list
def issue_files(ctx: Ctx) -> dict:
    """The files the issue's inputs name (written into ctx.tmp)."""
    task = ctx.task("task1_welding_plate")
    f = {}
    t = copy.deepcopy(task)
    t["obstacels"] = t.pop("obstacles")
    f["misspelt_obstacles"] = ctx.write(t)
    t = copy.deepcopy(task)
    t["units"][0] = "P0"
    f["unit_not_mapping"] = ctx.write(t)
    f["obstacles_number"] = ctx.write(dict(task, obstacles=2))
    f["radius_word"] = ctx.write(dict(task, link_radius_m="thick"))
    t = copy.deepcopy(task)
    t["units"][0]["work"] = ["forward"]
    f["direction_word"] = ctx.write(t)
    f["negative_radius"] = ctx.write(dict(task, link_radius_m=-0.04))
    sc = ctx.scenario("thesis-ch4")
    f["check_rate"] = ctx.write(dict(sc, sampling={"plan_rate_hz": 1000.0, "check_rate_hz": 1e10}))
    f["population"] = ctx.write(dict(sc, ga=dict(sc["ga"], population=10_000_000)))
    text = yaml.safe_dump(sc, sort_keys=False).replace("  mass_kg: 0.03\n", "  mass_kg: 0.03\n  mass_kg: 0.3\n", 1)
    f["duplicated_key"] = ctx.write(None, text=text)
    spec = copy.deepcopy(SPEC)
    spec["monte_carlo"]["cases"] = 999_999
    spec["parameters"] = {"friction": {"dist": "normal", "mean": 0.3, "std": 0.03}}
    f["cases"] = ctx.write(spec)
    f["spec"] = ctx.write(SPEC)
    return f


# (class of the issue, argv with {name} for issue_files and {tmp}, {afile})
ISSUE_CASES = (
    ("unwritable output", ["plan", "ohsaka-fig3", "--json", "/proc/x.json"]),
    ("unwritable output", ["plan", "ohsaka-fig3", "--execute", "/proc/x.png"]),
    ("unwritable output", ["design", "peg_in_hole", "--out", "/proc/x"]),
    ("unwritable output", ["sweep", "{spec}", "--out", "/proc/x"]),
    ("unwritable output", ["sweep", "{spec}", "--out", "{afile}"]),
    ("unwritable output", ["sweep", "{spec}", "--out", "{tmp}/out", "--json", "/proc/x/run.json"]),
    ("size", ["plan", "ohsaka-fig3", "--m", "3000"]),
    ("size", ["plan", "ohsaka-fig3", "--divisions", "1000000000"]),
    ("size", ["simulate", "thesis-ch4", "--method", "thesis", "--time-scale", "1e6"]),
    ("size", ["simulate", "thesis-ch4", "--method", "thesis", "--time-scale", "1e4"]),
    ("size", ["plan", "{check_rate}", "--method", "thesis"]),
    ("size", ["plan", "{population}"]),
    ("size", ["sweep", "{cases}", "--out", "{tmp}/out"]),
    ("size", ["design", "task1_welding_plate", "--generations", "1000000000,100", "--out", "{tmp}/out"]),
    ("design task file", ["design", "{unit_not_mapping}", "--out", "{tmp}/out"]),
    ("design task file", ["design", "{obstacles_number}", "--out", "{tmp}/out"]),
    ("design task file", ["design", "{radius_word}", "--out", "{tmp}/out"]),
    ("design task file", ["design", "{direction_word}", "--out", "{tmp}/out"]),
    ("design task file", ["design", "{misspelt_obstacles}", "--out", "{tmp}/out"]),
    ("design task file", ["design", "{negative_radius}", "--out", "{tmp}/out"]),
    ("sweep scheduler", ["sweep", "{spec}", "--out", "{tmp}/out", "--scheduler", "tcp://10.255.255.1:8786"]),
    ("duplicated YAML key", ["plan", "{duplicated_key}", "--method", "thesis"]),
)


def issue_argv(argv, ctx: Ctx, files: dict) -> list:
    return [a.format(tmp=ctx.tmp, afile=ctx.afile, **files) for a in argv]


# ------------------------------------------------------------------------------ docs/bad_inputs.md
def _normal(text: str, ctx: Ctx) -> str:
    text = text.replace(str(ctx.tmp), "$TMP").replace(str(ROOT), "$REPO")
    text = re.sub(r"this machine has \([^)]*\)|this machine has [0-9.]+ [KMGT]iB", "this machine has <RAM>", text)
    text = re.sub(r"answered within ([0-9.]+) s \(.*\); start", r"answered within \1 s (<why>); start", text)
    return text.replace("|", "\\|")


def _show_argv(argv) -> str:
    argv = [a if a and " " not in a else repr(a) for a in map(str, argv)]
    if len(argv) > 12:
        argv = argv[:8] + [f"... ({len(argv) - 10} more) ..."] + argv[-2:]
    return " ".join(argv)


def doc_text(tmp: Path) -> str:
    """docs/bad_inputs.md: for each class and command, the first generated input and its line."""
    ctx = Ctx(tmp)
    rows = []
    for klass in CLASSES:
        for command in COMMANDS:
            with stubbed():
                argv = cases(command, klass, ctx, 1)[0]
                _, err = run(argv)
            line = err.strip().splitlines()[0] if err.strip() else "(nothing)"
            rows.append(f"| {klass} | `qmt-drake {_normal(_show_argv(argv), ctx)}` | {_normal(line, ctx)} |")
    files = issue_files(ctx)
    names = {v: "{" + k + "}" for k, v in files.items()}
    issue_rows = []
    for klass, argv in ISSUE_CASES:
        argv = issue_argv(argv, ctx, files)
        with stubbed():
            _, err = run(argv)
        line = err.strip().splitlines()[0] if err.strip() else "(nothing)"
        shown = " ".join(names.get(a, a) for a in argv)
        issue_rows.append(f"| {klass} | `qmt-drake {_normal(shown, ctx)}` | {_normal(line, ctx)} |")
    return ("# Bad inputs: what each command prints\n\n"
            "Generated by `python -m tests.inputs_fuzz --write docs/bad_inputs.md` from the randomized tests\n"
            "of tests/test_inputs_randomized.py (issue 21): for every command and every class of bad input,\n"
            f"{N_PER_CLASS} inputs from `numpy.random.default_rng({SEED} + 5 * command index + class index)`\n"
            "must exit with code 2 and print exactly one line, never a traceback, before any work. The\n"
            "table shows the first input of each generator (YAML files it writes are under $TMP, the\n"
            "YAML change is random: a number made a word, a key misspelt or written twice, ...).\n"
            "A test regenerates this table and compares, so it cannot drift.\n\n"
            "Classes: types (a word or a list where a number is wanted), ranges (negative, zero,\n"
            "non-finite, out of bounds), sizes (over the memory and time budget of qmt_drake/budgets.py;\n"
            "`--allow-large` runs them anyway, except beyond the machine's memory), paths (outputs that\n"
            "cannot be written, inputs that do not exist, scheduler addresses nobody answers), keys\n"
            "(unknown, misspelt or duplicated keys of scenario, task and sweep files).\n\n"
            "| class | command | the line it prints (stderr, exit 2) |\n|---|---|---|\n"
            + "\n".join(rows) + "\n\n"
            "## The inputs of issue 21's list\n\n"
            "Each also runs through the real entry point (`python -m qmt_drake.apps.cli`, a subprocess) in\n"
            "tests/test_inputs_randomized.py, which checks it is refused within 5 s and 1 GiB. `{name}` is a\n"
            "file the test writes (tests/inputs_fuzz.py `issue_files`: e.g. {misspelt_obstacles} is task1\n"
            "with `obstacels:`, {check_rate} thesis-ch4 with `check_rate_hz: 1e10`).\n\n"
            "| class | command | the line it prints (stderr, exit 2) |\n|---|---|---|\n"
            + "\n".join(issue_rows) + "\n")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", metavar="PATH", help="write the table (docs/bad_inputs.md)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="qmt-fuzz-") as d:
        text = doc_text(Path(d))
    if a.write:
        Path(a.write).write_text(text)
    else:
        sys.stdout.write(text)
