"""Randomized bad arguments for every public function of the library (issue 30 item 7).

For each function a generator draws at least N_CALLS calls from numpy.random.default_rng(SEED), each with
at least one bad argument of one class: wrong types, NaN/inf, huge, zero or negative sizes, bad paths (a
directory, a missing file, an HTML page, /dev/null, an empty or NUL-bearing name), unknown or misspelt
keywords. Every call must raise QmtInputError whose text is one line (no other exception, no SystemExit,
no success: each call carries a bad argument), within CALL_S, and the process's peak memory must not grow
by more than GROWTH_BYTES over a function's whole batch (resource.getrusage: its max RSS is monotonic, so
this bounds every call). The cheap scenarios (thesis-ch4, ohsaka-fig3, ur5-magnet-part at a 20 Hz check
rate) keep the file fast; the generators are the point: a refusal costs microseconds.
The new CLI options get a smaller randomized set through the CLI's main(): exit code 2 and one line.
"""

from __future__ import annotations

import copy
import math
import resource
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from qmt_drake.api import build_diagram, load_plan, load_scenario, plan_with, simulate
from qmt_drake.apps.cli import main as cli_main
from qmt_drake.config.scenario import SCENARIO_DIR
from qmt_drake.errors import QmtInputError

SEED = 20261126
N_CALLS = 200
N_CLI = 40
CALL_S = 5.0
GROWTH_BYTES = 1 << 30

NAN, INF = float("nan"), float("inf")
BAD_TYPES = [None, "2", "abc", b"1", [1, 2], {"a": 1}, (), object(), 1j, True, set()]
BAD_REALS = [NAN, INF, -INF, 0, -1, -5.5, 1e300, -1e300]
BAD_COUNTS = [NAN, INF, -INF, 0, -1, -5, 2.5, 10 ** 9, 10 ** 12, 2 ** 70, "3", True]  # None is a default


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    (d / "page.html").write_text("<!doctype html><html><body><p>not a scenario</p></body></html>\n")
    (d / "garbage.json").write_text("{not json")
    (d / "list.json").write_text("[1, 2, 3]\n")
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-magnet-part.yaml").read_text())
    raw["limits"]["check_rate_hz"] = 20.0  # a cheap re-check for the fixture's plan
    raw["actuators"].pop("motor")  # a scenario without motor constants: actuator dc_motor is refused
    (d / "magnet.yaml").write_text(yaml.safe_dump(raw))
    sc = load_scenario("thesis-ch4")
    sp = load_scenario(d / "magnet.yaml")
    ex = load_scenario("ohsaka-fig3")
    return {"dir": d, "sc": sc, "sp": sp, "ex": ex, "plan": plan_with("thesis", sc),
            "sp_plan": plan_with("ruckig", sp)}


def bad_paths(w) -> list:
    d = w["dir"]
    return [None, 123, 1.5, b"bytes", "", "a\0b", str(d), d, str(d / "missing.yaml"), d / "page.html",
            "/dev/null", ["x"], str(d / "garbage.json"), str(d / "list.json")]


def misspell(rng, name: str) -> str:
    """A random one-letter edit of `name` (drop, double or swap), never `name` itself."""
    i = int(rng.integers(0, len(name)))
    edits = [name[:i] + name[i + 1:], name[:i] + name[i] + name[i:], name + "s", name.upper(), name + "_"]
    out = edits[int(rng.integers(0, len(edits)))]
    return out if out != name else name + "x"


def pick(rng, seq):
    return seq[int(rng.integers(0, len(seq)))]


def run_batch(calls) -> dict:
    """Run every (label, thunk); each must refuse in one line within CALL_S; the batch's memory growth bounded."""
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    classes: dict[str, int] = {}
    for label, thunk in calls:
        t0 = time.perf_counter()
        try:
            thunk()
        except QmtInputError as exc:
            text = str(exc)
            assert text and "\n" not in text, (label, text)
        except BaseException as exc:  # noqa: BLE001 - anything else (SystemExit included) is the defect
            pytest.fail(f"{label}: {type(exc).__name__}: {exc}")
        else:
            pytest.fail(f"{label}: accepted a bad argument")
        dt = time.perf_counter() - t0
        assert dt < CALL_S, (label, dt)
        cls = label.split(":")[0]
        classes[cls] = classes.get(cls, 0) + 1
    growth = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - rss0
    assert growth < GROWTH_BYTES, growth
    assert len(calls) >= N_CALLS or len(calls) >= N_CLI
    return classes


# --------------------------------------------------------------------------------------- generators
def gen_load_scenario(rng, w):
    out = []
    while len(out) < N_CALLS:
        k = int(rng.integers(0, 4))
        if k == 0:
            p = pick(rng, bad_paths(w))
            out.append((f"path: load_scenario({p!r})", lambda p=p: load_scenario(p)))
        elif k == 1:
            o = pick(rng, BAD_TYPES[1:] + [[1, 2], "limits", 3.0])
            if isinstance(o, dict):
                o = {"limits": o}
            out.append((f"type: overrides={o!r}", lambda o=o: load_scenario("thesis-ch4", overrides=o)))
        elif k == 2:
            v = pick(rng, [NAN, INF, -INF, 0, -1, -5.5, "0.5", [1], True])
            key = pick(rng, ["moment_limit_Nm", "motor_torque_limit_Nm"])
            out.append((f"value: overrides limits.{key}={v!r}",
                        lambda v=v, key=key: load_scenario("thesis-ch4", overrides={"limits": {key: v}})))
        else:
            kw = misspell(rng, pick(rng, ["overrides", "name_or_path"]))
            out.append((f"keyword: load_scenario({kw}=...)", lambda kw=kw: load_scenario("thesis-ch4", **{kw: {}})))
    return out


def gen_plan_with(rng, w):
    sc, sp, ex = w["sc"], w["sp"], w["ex"]
    transfer = {"max_generations": BAD_COUNTS, "stall_generations": [NAN, -1, "x", 2.5, None, INF],
                "checkpoint_every": [0, -1, NAN, "x"]}
    spatial = {"population": BAD_COUNTS + [1, 10 ** 6, None], "generations": BAD_COUNTS + [None], "stall": [-1, NAN, "x", 2.5],
               "family": [1, None, 2.5, ["via_cubic"]]}
    energy = {"m": BAD_COUNTS + [10 ** 4], "divisions": BAD_COUNTS + [1], "max_iter": [0, -1, NAN, "x", INF],
              "c1": [NAN, INF, -1, "x"], "c2": [NAN, -INF, -1.0, "1e5"]}
    out = []
    while len(out) < N_CALLS:
        k = int(rng.integers(0, 7))
        if k == 0:
            m = pick(rng, BAD_TYPES + ["", "gaa", "colocation", "toppra-drak"])
            out.append((f"type: plan_with(method={m!r})", lambda m=m: plan_with(m, sc)))
        elif k == 1:
            s = pick(rng, bad_paths(w) + [3, NAN, "no-such-scenario"])
            out.append((f"path: plan_with('toppra', {s!r})", lambda s=s: plan_with("toppra", s)))
        elif k == 2:
            key = pick(rng, list(transfer))
            v = pick(rng, transfer[key])
            if key == "stall_generations" and v is None:
                v = -3
            out.append((f"size: plan_with('ga', thesis-ch4, {key}={v!r})",
                        lambda key=key, v=v: plan_with("ga", sc, **{key: v})))
        elif k == 3:
            key = pick(rng, list(spatial))
            v = pick(rng, spatial[key])
            out.append((f"size: plan_with('ga', ur5-magnet, {key}={v!r})",
                        lambda key=key, v=v: plan_with("ga", sp, **{key: v})))
        elif k == 4:
            key, method = pick(rng, [("n_grid", "toppra"), ("restarts", "family_optimum"),
                                     ("control_points", "trajopt"), ("tilt_samples", "trajopt")])
            v = pick(rng, BAD_COUNTS)
            out.append((f"size: plan_with({method!r}, ur5-magnet, {key}={v!r})",
                        lambda key=key, v=v, method=method: plan_with(method, sp, **{key: v})))
        elif k == 5:
            key = pick(rng, list(energy))
            v = pick(rng, energy[key])
            out.append((f"size: plan_with('snopt', ohsaka-fig3, {key}={v!r})",
                        lambda key=key, v=v: plan_with("snopt", ex, **{key: v})))
        else:
            target, method, name = pick(rng, [(sc, "ga", "max_generations"), (sc, "ga", "stall_generations"),
                                              (sp, "ga", "population"), (sp, "toppra", "n_grid"),
                                              (ex, "snopt", "divisions"), (ex, "steepest", "max_iter"),
                                              (sc, "ruckig", "jerk_limit"), (sc, "ga", "seed")])
            kw = misspell(rng, name)
            out.append((f"keyword: plan_with({method!r}, {kw}=1)",
                        lambda target=target, method=method, kw=kw: plan_with(method, target, **{kw: 1})))
    return out


def _run_calls(rng, w, fn, name: str):
    sc, p = w["sc"], w["plan"]
    sp, spp = w["sp"], w["sp_plan"]
    out = []
    while len(out) < N_CALLS:
        k = int(rng.integers(0, 6))
        spatial = bool(rng.integers(0, 2)) and fn is simulate
        s, plan = (sp, spp) if spatial else (sc, p)
        if k == 0:
            v = pick(rng, BAD_TYPES + BAD_REALS + [1e6, 1e12])
            out.append((f"size: {name}(time_scale={v!r})", lambda s=s, plan=plan, v=v: fn(s, plan, time_scale=v)))
        elif k == 1:
            v = pick(rng, BAD_TYPES[1:] + [0, -1e-3, NAN, INF, 1.0, 1e9])
            out.append((f"size: {name}(time_step_s={v!r})", lambda s=s, plan=plan, v=v: fn(s, plan, time_step_s=v)))
        elif k == 2:
            v = pick(rng, BAD_TYPES + [sc, w["ex"], "plan.json", 3.0])
            out.append((f"type: {name}(plan={v!r:.30})", lambda s=s, v=v: fn(s, v)))
        elif k == 3:
            kw = misspell(rng, pick(rng, ["time_scale", "time_step_s", "meshcat", "plan"]
                                    + (["feedforward", "record_path", "actuator"] if fn is simulate else [])))
            if fn is build_diagram:  # build_diagram takes the hand diagram's own keywords: a misspelt one of those
                kw = misspell(rng, pick(rng, ["coil_current_A", "log_period_s", "inverse_dynamics_feedforward"]))
            out.append((f"keyword: {name}({kw}=2)", lambda s=s, plan=plan, kw=kw: fn(s, plan, **{kw: 2})))
        elif k == 4:
            v = pick(rng, [None, "yes", 1, 0, "True", [], 1.0])
            out.append((f"type: {name}(allow_large={v!r})", lambda s=s, plan=plan, v=v: fn(s, plan, allow_large=v)))
        else:
            if fn is simulate:
                # (planar: thesis-ch4's own actuator, dc_motor, is taken as the CLI takes it; another is refused)
                v = pick(rng, [1, 2.5, [], {"a": 1}, b"x"] + (["dc_motor", "ideal_"] if spatial else ["ideal"]))
                out.append((f"type: simulate(actuator={v!r})", lambda s=s, plan=plan, v=v: simulate(s, plan, actuator=v)))
            else:
                v = pick(rng, BAD_TYPES[1:] + ["meshcat"])
                out.append((f"type: build_diagram(meshcat={v!r})", lambda v=v: build_diagram(sc, p, meshcat=v)))
    return out


def gen_simulate(rng, w):
    return _run_calls(rng, w, simulate, "simulate")


def gen_build_diagram(rng, w):
    out = _run_calls(rng, w, build_diagram, "build_diagram")
    return out + [("keyword: build_diagram(spatial, coil_current_A)",  # a magnet-hand keyword on a spatial arm
                   lambda: build_diagram(w["sp"], w["sp_plan"], coil_current_A=1.0))]


def gen_load_plan(rng, w):
    good = w["dir"] / "good_plan.json"
    if not good.exists():
        w["plan"].write_json(good)
    out = []
    while len(out) < N_CALLS:
        if rng.integers(0, 3):
            p = pick(rng, bad_paths(w) + [SCENARIO_DIR / "thesis-ch4.yaml"])
            out.append((f"path: load_plan({p!r})", lambda p=p: load_plan(p)))
        else:
            s = pick(rng, BAD_TYPES[1:] + [w["sp"], w["ex"], "no-such-scenario"])
            out.append((f"type: load_plan(good, scenario={s!r:.30})", lambda s=s: load_plan(good, s)))
    return out


def gen_sample(rng, w):
    out = []
    bad = [None, "2", "abc", b"1", {"a": 1}, (), object(), 1j, True, set(), NAN, INF, -INF, [NAN], [0.1, NAN],
           [[0.1, "a"]], [], np.array(["x"]), [1, None], np.array([0.0, INF]), "0.5", [[0.1], [0.2, 0.3]]]
    while len(out) < N_CALLS:
        plan = w["sp_plan"] if rng.integers(0, 2) else w["plan"]
        t = pick(rng, bad)
        cls = "nan" if "nan" in repr(t) or "inf" in repr(t) else "type"
        out.append((f"{cls}: {type(plan).__name__}.sample({t!r:.30})", lambda plan=plan, t=t: plan.sample(t)))
    return out


def gen_writers(rng, w):
    out = []
    while len(out) < N_CALLS:
        plan = w["sp_plan"] if rng.integers(0, 2) else w["plan"]
        if rng.integers(0, 2):
            p = pick(rng, [None, 123, 1.5, b"x.json", "", "a\0b", ["x.json"], object()])
            out.append((f"type: write_json({p!r:.30})", lambda plan=plan, p=p: plan.write_json(p)))
        else:
            r = pick(rng, BAD_TYPES + BAD_REALS + [1e12, 1e9])
            out.append((f"size: write_csv(rate_hz={r!r:.30})",
                        lambda plan=plan, r=r: plan.write_csv(w["dir"] / "x.csv", rate_hz=r)))
    return out


GENERATORS = {"load_scenario": gen_load_scenario, "plan_with": gen_plan_with, "simulate": gen_simulate,
              "build_diagram": gen_build_diagram, "load_plan": gen_load_plan, "Plan.sample": gen_sample,
              "writers": gen_writers}


@pytest.mark.parametrize("name", list(GENERATORS))
def test_every_bad_argument_is_refused_in_one_line(world, name):
    rng = np.random.default_rng([SEED, list(GENERATORS).index(name)])
    calls = GENERATORS[name](rng, world)
    assert len(calls) >= N_CALLS
    classes = run_batch(calls)
    assert len(classes) >= 2, classes  # every batch mixes classes (type, size, path, keyword, value)


# ------------------------------------------------------------------------------------------- the CLI
def _scenario_file(d: Path, base: str, path: str, value) -> Path:
    raw = yaml.safe_load((SCENARIO_DIR / f"{base}.yaml").read_text())
    for key, v in (value.items() if isinstance(value, dict) else [(path, value)]):
        x = raw
        keys = key.split(".")
        for k in keys[:-1]:
            x = x[k]
        x[keys[-1]] = v
    out = d / f"{base}-{abs(hash((path, repr(value)))) % 10 ** 8}.yaml"
    out.write_text(yaml.safe_dump(raw))
    return out


CLI_FILE_CASES = [  # (base scenario, key, bad values) for the plausibility checks at load
    ("ur5-suction-bins", "arm.face_axis", [[0, 0, 0], [0.0, 0.0, 1e-12]]),
    ("panda-tray-cup", "arm.lock_joints", [None, "panda_finger_joint1", [1, 2]]),
    ("ur5-suction-bins", "hand.rim_points", [10 ** 9, 10 ** 6, 2, 64]),
    ("ur5-suction-bins", "hand.pyramid_edges", [10 ** 7, 1, 33]),
    ("ur5-suction-bins", "limits.check_rate_hz", [1e9, 0, -1, 1e5]),
    ("ur5-suction-bins", "task.transfer_points", [10 ** 6, -1, 1001]),
    ("ur5-suction-bins", "payload.inertia_kgm2", [[0.001, 0.001, 0.05], [0.0, 1.0, 1.0], [1, 1, 3]]),
    ("ur5-suction-bins", "payload.mass_kg", [1e9, 1e4]),
    ("ur5-suction-bins", "task.seed_rad", [[-34, -75, 92, -109, -90, 0]]),
    ("crane-tray", "actuator.control_period_s", [1e-7, 0.0, 1.0]),
    ("crane-tray", "", [{"actuator.p": [0, 0, 0], "actuator.i": [0, 0, 0], "actuator.d": [0, 0, 0]},
                        {"actuator.p": [0, 800, 800], "actuator.i": [0, 0, 0]}]),
]


def test_cli_new_options_refuse_in_one_line(tmp_path, capsys):
    rng = np.random.default_rng([SEED, 99])
    argvs = []
    while len(argvs) < N_CLI:
        k = int(rng.integers(0, 4))
        if k == 0:  # every value refused: below the minimum, over the range or the budget, not an integer
            key, method = pick(rng, [("population", "ga"), ("generations", "ga"), ("n_grid", "toppra")])
            v = pick(rng, ["0", "-5", "1000000000", "nan", "inf", "x", "2.5"] + (["1"] if key != "generations" else []))
            argvs.append(["plan", "ur5-suction-bins", "--method", method, "--option", f"{key}={v}"])
        elif k == 1:
            v = pick(rng, ["1e6", "1e9", "nan", "inf", "0", "-2", "1"])
            base = pick(rng, [["plan", "thesis-ch4", "--method", "thesis"]])
            argvs.append(base + ["--carried", "--carried-max-scale", v])
        elif k == 2:
            argvs.append(["plan", "thesis-ch4", "--method", pick(rng, ["toppra", "ruckig", "ga"]), "--option",
                          f"{misspell(rng, pick(rng, ['grid_points', 'jerk_limit', 'max_generations']))}=3"])
        else:
            base, key, values = pick(rng, CLI_FILE_CASES)
            path = _scenario_file(tmp_path, base, key, pick(rng, values))
            argvs.append(["plan", str(path), "--method", "toppra" if base != "crane-tray" else "thesis"])
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    for argv in argvs:
        capsys.readouterr()
        t0 = time.perf_counter()
        try:
            code = cli_main(argv)
        except SystemExit as exc:  # argparse's own refusals exit 2 with a usage line
            code = exc.code
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2, (argv, code, err)
        assert err and sum("error:" in line for line in err) == 1 and "error:" in err[-1], (argv, err)
        assert "Traceback" not in "\n".join(err), (argv, err)
        assert time.perf_counter() - t0 < CALL_S, argv
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - rss0 < GROWTH_BYTES
    assert math.isfinite(len(argvs))


def test_yaml_alias_bomb_is_refused_before_it_expands(tmp_path):
    text = (SCENARIO_DIR / "ur5-suction-bins.yaml").read_text()
    names = "abcdefgh"  # 9 values, then 8 levels of 9 aliases: 9**9 = 387 million values written out
    levels = "[&a [1,1,1,1,1,1,1,1,1], " + ", ".join(
        f"&{n} [{','.join([f'*{p}'] * 9)}]" for p, n in zip(names, names[1:])) + f", [{','.join(['*h'] * 9)}]]"
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(text.replace("  seed_rad: [-0.6, -1.3, 1.6, -1.9, -1.57, 0.0]", f"  seed_rad: {levels}"))
    t0 = time.perf_counter()
    with pytest.raises(QmtInputError, match="expands through aliases"):
        load_scenario(bomb)
    assert time.perf_counter() - t0 < 1.0


def test_a_deep_copy_of_a_shipped_scenario_still_loads(tmp_path):
    # the checks refuse what is wrong, not what is shipped: every built-in spatial scenario loads unchanged
    for name in ("ur5-suction-bins", "ur5-magnet-part", "panda-tray-cup"):
        raw = copy.deepcopy(yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text()))
        p = tmp_path / f"{name}.yaml"
        p.write_text(yaml.safe_dump(raw))
        assert load_scenario(p).name == name
