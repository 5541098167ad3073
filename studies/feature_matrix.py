"""Issue 27 item 6: every feature on every kind of arm, run, not claimed. For each kind (one built-in
scenario each) and each feature, the cheapest real command that exercises it runs in a fresh process
(short GA runs, few sweep cases, a per-cell timeout) and the cell is classified:

    ok       exit 0, or exit 3 with the plan file written (limits that no plan meets)
    refused  exit 2 and its message (one line: the CLI's QmtInputError or argparse's error)
    error    a traceback, a timeout, another exit code, or exit 0/3 without the expected output

    python -m studies.feature_matrix                 # out/feature_matrix.json + docs/features.md
    python -m studies.feature_matrix --fresh         # run every cell again (with --only: those)
    python -m studies.feature_matrix --only plan-ga --kinds ur5-suction-bins   # a few cells

The JSON is rewritten (atomically) after every cell, and a rerun skips the cells already in it, so an
interrupted run resumes (a cell whose command has changed since runs again). Commands are run as written in the table, with `qmt-drake` standing for
`python -m qmt_drake.apps.cli` and `python` for this interpreter, in a temporary folder; a cell that
needs a plan file (simulate, sweeps, retime, export, build_diagram) uses the kind's base plan, made once
per run (BASE below). A refusal is judged against JUDGEMENTS (physics, or a missing feature, and why);
a refusal whose message no judgement matches is listed as "not judged" for a reader to decide.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from qmt_drake.outputs import write_text_atomic

ROOT = Path(__file__).resolve().parents[1]
SCENARIO_DIR = ROOT / "models" / "scenarios"
OUT_JSON = ROOT / "out" / "feature_matrix.json"
OUT_MD = ROOT / "docs" / "features.md"

# column -> (built-in scenario, family of the kind: transfer | energy | spatial)
KINDS = {
    "planar magnet": ("thesis-ch4", "transfer"),
    "tray": ("crane-tray", "transfer"),
    "energy-time": ("ohsaka-fig3", "energy"),
    "UR5 suction": ("ur5-suction-bins", "spatial"),
    "UR5 magnet": ("ur5-magnet-part", "spatial"),
    "Panda tray": ("panda-tray-cup", "spatial"),
}
METHODS = ("ga", "optimum", "thesis", "toppra", "toppra-drake", "ruckig", "trajopt", "family_optimum",
           "snopt", "ipopt", "steepest", "collocation")
# The cheapest plan of each family of kinds: what --carried, --success, the sweeps and the simulate
# rows start from (the thesis's reported genes; TOPP-RA; one start of the energy-time multi-start).
BASE_METHOD = {"transfer": "thesis", "spatial": "toppra", "energy": "snopt"}
# The energy-time planners' cheap problem: one Fourier term, one rotation-direction start.
ENERGY_SMALL = ["--m", "1", "--pattern=-+-", "--divisions", "20"]
# GA sizes that run in seconds (transfer GA: the scenario's population; spatial: --option population).
GA_SMALL = {"transfer": ["--stall", "2"], "spatial": ["--stall", "2", "--option", "population=6"],
            "energy": ["--stall", "2"]}
# The one value the override rows change: a dotted key of the scenario YAML and the factor applied.
OVERRIDE = {"thesis-ch4": ("payload.mass_kg", 1.1), "crane-tray": ("payload.mass_kg", 1.1),
            "ohsaka-fig3": ("objective.c2", 0.5), "ur5-suction-bins": ("payload.mass_kg", 1.1),
            "ur5-magnet-part": ("payload.mass_kg", 1.1), "panda-tray-cup": ("hand.cup.mass_kg", 1.1)}
NO_SECTION = {"time_scale_jitter": {"dist": "normal", "mean": 1.0, "std": 0.005}}
FEW_CASES = 4  # Monte Carlo cases of the uncertainty rows (the scenario's own section, cut to this)

# The API snippets run as `python -c`; a QmtInputError becomes the CLI's exit 2 and one line.
SNIPPET = """import sys
from qmt_drake.errors import QmtInputError
try:
{body}
except QmtInputError as exc:
    print(f"qmt-drake: error: {{exc}}", file=sys.stderr)
    sys.exit(2)
"""


@dataclass
class Cell:
    feature: str
    kind: str
    steps: list  # each a list of words; "qmt-drake" and "python" are expanded at run time
    expect: list = field(default_factory=list)  # files an exit 0/3 must have written (relative to the cell dir)
    needs_base: bool = False
    prep: dict = field(default_factory=dict)  # file name -> ("yaml", changes) | ("csv", None)
    # (file, key, subkey): a JSON output that must hold `key` (a mapping holding `subkey`) somewhere,
    # else an exit 0 ignored the option (a silent wrong answer, an error)
    evidence: tuple | None = None

    @property
    def key(self) -> str:
        return f"{self.feature}|{self.kind}"

    def shown(self) -> str:
        """The command as a reader would type it (files by their name, snippets abbreviated)."""
        out = []
        for step in self.steps:
            argv = step["argv"] if isinstance(step, dict) else step
            if isinstance(step, dict) and step.get("mode") == "interrupt":
                out.append(" ".join(shlex.quote(w) for w in argv) + " (Ctrl-C at its first progress line)")
            elif argv[:2] == ["python", "-c"]:
                out.append(f"python -c '{_snippet_title(argv[2])}'")
            else:
                out.append(" ".join(shlex.quote(w) for w in argv).replace("{GEN}", "G+2"))
        return " && ".join(out)


def _snippet_title(code: str) -> str:
    first = [x.strip() for x in code.splitlines() if x.strip().startswith("#")]
    return first[0].lstrip("# ") if first else "..."


def _py(body: str) -> list:
    indented = "\n".join("    " + line for line in body.strip("\n").splitlines())
    return ["python", "-c", SNIPPET.format(body=indented)]


# ----------------------------------------------------------------------------------- the cells
FEATURES = [f"plan --method {m}" for m in METHODS] + [
    "GA --checkpoint + resume", "plan --carried", "plan --success P", "scenario YAML copy (CLI)",
    "overrides (API)", "uncertainty sweep (Monte Carlo)", "Dask sweep (grid)", "build_diagram in user code",
    "simulate --plan", "simulate --time-step-ms", "simulate --explicit", "simulate --feedforward back-emf",
    "simulate --actuator dc_motor", "simulate --record (HTML)", "simulate --margin", "retime", "export"]


def _plan_words(name: str, fam: str, method: str, generations: int = 2) -> list:
    w = ["qmt-drake", "plan", name, "--method", method, "--quiet"]
    if fam == "energy":
        w += ENERGY_SMALL + (["--max-iter", "200"] if method == "steepest" else [])
    if method == "ga":
        w += ["--generations", str(generations), *GA_SMALL[fam]]
    if method == "optimum" and fam == "transfer":  # 24 starts, 6 polished: over 4 min on the tray under load
        w += ["--option", "starts=4", "--option", "polished=1"]
    return w


def cell(feature: str, kind: str) -> Cell:
    """The command(s) of one cell (no file is written here; the yaml/csv preps are made at run time)."""
    name, fam = KINDS[kind]
    base = BASE_METHOD[fam]
    if feature.startswith("plan --method "):
        m = feature.removeprefix("plan --method ")
        return Cell(feature, kind, [_plan_words(name, fam, m) + ["--json", "plan.json"]], expect=["plan.json"])
    if feature == "GA --checkpoint + resume":
        # a long run stopped by Ctrl-C at its first progress line (the GA writes its checkpoint then),
        # and the same command again, a few generations past the checkpoint's: it must say it resumes
        words = ["qmt-drake", "plan", name, "--method", "ga", *(ENERGY_SMALL if fam == "energy" else []),
                 "--generations", "100000", "--stall", "0", *GA_SMALL[fam][2:]]
        first = words + ["--checkpoint", "ga.ckpt", "--json", "p1.json"]
        again = [w if w != "100000" else "{GEN}" for w in words] + ["--checkpoint", "ga.ckpt", "--json", "p2.json"]
        return Cell(feature, kind, [{"argv": first, "mode": "interrupt"}, {"argv": again, "mode": "resume"}],
                    expect=["p2.json"])
    if feature == "plan --carried":
        return Cell(feature, kind, [_plan_words(name, fam, base) + ["--carried", "--carried-max-scale", "1.5",
                                                                     "--json", "plan.json"]], expect=["plan.json"],
                    evidence=("plan.json", "carried_search", None))
    if feature == "plan --success P":
        return Cell(feature, kind, [_plan_words("few.yaml", fam, base) + [
            "--success", "0.3", "--success-out", "succ", "--success-check-cases", str(FEW_CASES),
            "--success-max-scale", "1.5", "--json", "plan.json"]], expect=["plan.json"],
            prep={"few.yaml": ("yaml", "few")}, evidence=("plan.json", "success", "fresh_check"))
    if feature == "scenario YAML copy (CLI)":
        return Cell(feature, kind, [_plan_words("copy.yaml", fam, base) + ["--json", "plan.json"]],
                    expect=["plan.json"], prep={"copy.yaml": ("yaml", "override")})
    if feature == "overrides (API)":
        key, factor = OVERRIDE[name]
        value = _get(_raw(name), key) * factor
        over = _nested(key, value)
        opts = "m=1, pattern=(-1, 1, -1), divisions=20" if fam == "energy" else ""
        body = (f"# load_scenario('{name}', overrides={over}); plan_with('{base}', sc)\n"
                "from qmt_drake.api import load_scenario, plan_with\n"
                f"sc = load_scenario({name!r}, overrides={over!r})\n"
                f"p = plan_with({base!r}, sc{', ' + opts if opts else ''})\n"
                "print(p.summary() if callable(getattr(p, 'summary', None)) else p)")
        return Cell(feature, kind, [_py(body)])
    if feature in ("uncertainty sweep (Monte Carlo)", "Dask sweep (grid)"):
        spec = "mc.yaml" if feature.startswith("uncertainty") else "grid.yaml"
        return Cell(feature, kind, [["qmt-drake", "sweep", spec, "--out", "sw", "--workers", "1", "--no-figures",
                                     "--quiet", "--json", "sweep.json"]], expect=["sweep.json"], needs_base=True,
                    prep={spec: ("sweep", spec)})
    if feature == "build_diagram in user code":
        body = (f"# build_diagram(load_scenario('{name}'), base plan) in the user's DiagramBuilder, run 0.05 s\n"
                "from pydrake.systems.analysis import Simulator\n"
                "from pydrake.systems.framework import DiagramBuilder\n"
                "from qmt_drake.api import build_diagram, load_plan, load_scenario\n"
                f"sc = load_scenario({name!r})\n"
                "td = build_diagram(sc, load_plan('base.json', sc))\n"
                "b = DiagramBuilder()\n"
                "b.AddSystem(td.diagram)\n"
                "sim = Simulator(b.Build())\n"
                "sim.AdvanceTo(0.05)\n"
                "print('advanced to', sim.get_context().get_time())")
        return Cell(feature, kind, [_py(body)], needs_base=True)
    sim = ["qmt-drake", "simulate", name, "--plan", "base.json", "--quiet"]
    extra = {"simulate --plan": [], "simulate --time-step-ms": ["--time-step-ms", "1"],
             "simulate --explicit": ["--explicit"],  # its step defaults to 1 ms (the CLI's help)
             "simulate --feedforward back-emf": ["--feedforward", "back-emf"],
             "simulate --actuator dc_motor": ["--actuator", "dc_motor"],
             "simulate --record (HTML)": ["--record", "rec.html"], "simulate --margin": ["--margin"]}
    if feature in extra:
        out = ["rec.html"] if feature.endswith("(HTML)") else []
        return Cell(feature, kind, [sim + extra[feature] + ["--json", "sim.json"]], expect=["sim.json", *out],
                    needs_base=True, evidence=("sim.json", "flip", None) if feature.endswith("--margin") else None)
    if feature == "retime":
        return Cell(feature, kind, [["qmt-drake", "retime", name, "--path", "path.csv", "--method", "toppra",
                                     "--quiet", "--json", "plan.json"]], expect=["plan.json"], needs_base=True,
                    prep={"path.csv": ("csv", None)})
    if feature == "export":
        return Cell(feature, kind, [["qmt-drake", "export", "base.json", "--scenario", name, "--format", "csv",
                                     "--rate", "500", "--out", "stream.csv", "--json", "export.json"]],
                    expect=["stream.csv"], needs_base=True)
    raise ValueError(f"no command for feature {feature!r}")


def all_cells() -> list[Cell]:
    return [cell(f, k) for f in FEATURES for k in KINDS]


# ----------------------------------------------------------------------------------- scenario files
def _raw(name: str) -> dict:
    return yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text())


def _get(raw: dict, key: str):
    for k in key.split("."):
        raw = raw[k]
    return raw


def _nested(key: str, value) -> dict:
    out: dict = value
    for k in reversed(key.split(".")):
        out = {k: out}
    return out


def _absolute_paths(x, folder: Path):
    """The YAML with every relative path that exists beside the original made absolute (a copy lives elsewhere)."""
    if isinstance(x, dict):
        return {k: _absolute_paths(v, folder) for k, v in x.items()}
    if isinstance(x, list):
        return [_absolute_paths(v, folder) for v in x]
    if isinstance(x, str) and ("/" in x or x.endswith((".urdf", ".yaml"))) and not os.path.isabs(x):
        p = folder / x
        if p.exists():
            return str(p.resolve())
    return x


def scenario_copy(name: str, how: str) -> dict:
    """A copy of the built-in scenario's mapping: "override" changes the OVERRIDE value, "few" cuts its
    uncertainty section's Monte Carlo to FEW_CASES cases."""
    raw = _absolute_paths(copy.deepcopy(_raw(name)), SCENARIO_DIR)
    if how == "override":
        key, factor = OVERRIDE[name]
        *path, last = key.split(".")
        d = raw
        for k in path:
            d = d[k]
        d[last] = d[last] * factor
    elif how == "few" and isinstance(raw.get("uncertainty"), dict):
        raw["uncertainty"].setdefault("monte_carlo", {})["cases"] = FEW_CASES
    return raw


def sweep_spec(name: str, which: str) -> dict:
    """mc.yaml: the scenario's uncertainty section, FEW_CASES cases, on the base plan; grid.yaml: the base
    plan replayed at two time scales."""
    spec = {"name": f"fm-{which.split('.')[0]}", "scenario": name, "plans": [{"file": "base.json"}]}
    if which == "mc.yaml":  # a scenario without the section: the executed timing's jitter (every kind's)
        u = _raw(name).get("uncertainty") or {}
        spec["parameters"] = dict(u.get("parameters") or NO_SECTION)
        spec["monte_carlo"] = {"cases": FEW_CASES, "seed": int((u.get("monte_carlo") or {}).get("seed", 1))}
    else:
        spec["parameters"] = {"time_scale": [1.0, 1.2]}
    return spec


CSV_SNIPPET = """# the base plan's joint path at 8 waypoints, as a CSV with a header of joint names
import csv, numpy as np
from qmt_drake.api import load_plan, load_scenario
sc = load_scenario({name!r})
p = load_plan('base.json', sc)
names = getattr(sc, 'joint_names', None) or getattr(getattr(sc, 'arm', None), 'joint_names', None)
rows = [np.atleast_1d(np.asarray(p.sample(t)[0], float)).ravel() for t in np.linspace(0, p.motion_time_s, 8)]
names = list(names) if names else [f'joint{{i + 1}}' for i in range(len(rows[0]))]
with open('path.csv', 'w', newline='') as f:
    w = csv.writer(f)
    w.writerow(names)
    w.writerows([[repr(float(v)) for v in r] for r in rows])
"""


# ----------------------------------------------------------------------------------- running
@dataclass
class Result:
    status: str  # ok | refused | error
    rc: int | None
    message: str
    seconds: float
    one_line: bool = True


def expand(argv: list) -> list:
    """'qmt-drake' -> this interpreter running the CLI module; 'python' -> this interpreter."""
    if argv and argv[0] == "qmt-drake":
        return [sys.executable, "-m", "qmt_drake.apps.cli", *argv[1:]]
    if argv and argv[0] == "python":
        return [sys.executable, *argv[1:]]
    return list(argv)


def run_step(argv: list, cwd: Path, timeout: float, env: dict | None = None) -> tuple[int | None, str, str, float]:
    """(exit code or None on timeout, stdout, stderr, seconds); the step's whole process group is killed
    on timeout (a sweep's Dask workers included)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(expand(argv), cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out, err = proc.communicate()
        rc = None
    return rc, out, err, time.perf_counter() - t0


def _error_line(stderr: str) -> str:
    lines = [x.strip() for x in stderr.splitlines() if x.strip()]
    errs = [x for x in lines if re.match(r"^(qmt-drake|usage)?[\w -]*: error: ", x) or x.startswith("qmt-drake: error")]
    line = errs[-1] if errs else (lines[-1] if lines else "")
    return re.sub(r"^[\w -]*: error: ", "", line)


def traceback_summary(stderr: str) -> str:
    """The exception line of the last traceback and the innermost project frame ('file:line')."""
    i = stderr.rfind("Traceback (most recent call last)")
    tail = stderr[i:].splitlines()
    frames = [re.search(r'File "([^"]+)", line (\d+)', x) for x in tail]
    ours = [m for m in frames if m and ("qmt_drake" in m.group(1) or "studies" in m.group(1))]
    exc = next((x.strip() for x in reversed(tail) if x.strip() and not x.startswith(" ")), "?")
    where = f" (at {Path(ours[-1].group(1)).name}:{ours[-1].group(2)})" if ours else ""
    return exc + where


def classify(rc: int | None, stdout: str, stderr: str, missing: list, seconds: float, timeout: float) -> Result:
    """ok / refused / error of one finished step (module docstring)."""
    if rc is None:
        return Result("error", None, f"timeout after {timeout:g} s", seconds)
    if "Traceback (most recent call last)" in stderr:
        return Result("error", rc, traceback_summary(stderr), seconds, one_line=False)
    if rc in (0, 3):
        if missing:
            return Result("error", rc, f"exit {rc} but {', '.join(missing)} not written", seconds)
        return Result("ok", rc, "" if rc == 0 else "exit 3: limits no plan meets, least-violating plan written",
                      seconds)
    if rc == 2:
        lines = [x for x in stderr.splitlines() if x.strip()]
        usage = [x for x in lines if x.startswith(("usage:", " "))]  # argparse prints its usage first
        return Result("refused", rc, _error_line(stderr), seconds, one_line=len(lines) - len(usage) == 1)
    last = _error_line(stderr) or (stdout.strip().splitlines() or [""])[-1]
    return Result("error", rc, f"exit {rc}: {last}", seconds)


def _prepare(c: Cell, d: Path, timeout: float) -> Result | None:
    """Write the cell's yaml/spec/csv files; a failure is the cell's result."""
    name = KINDS[c.kind][0]
    for fname, (what, arg) in c.prep.items():
        if what == "yaml":
            (d / fname).write_text(yaml.safe_dump(scenario_copy(name, arg), sort_keys=False))
        elif what == "sweep":
            (d / fname).write_text(yaml.safe_dump(sweep_spec(name, arg), sort_keys=False))
        elif what == "csv":
            rc, out, err, dt = run_step(_py(CSV_SNIPPET.format(name=name)), d, timeout)
            r = classify(rc, out, err, [] if (d / fname).exists() else [fname], dt, timeout)
            if r.status != "ok":
                r.message = f"preparing {fname} from the base plan: {r.message}"
                return r
    return None


class Bases:
    """The kind's base plan (BASE_METHOD), made once per run and copied into each cell's folder."""

    def __init__(self, root: Path, timeout: float):
        self.root, self.timeout, self.done = root, timeout, {}

    def get(self, kind: str) -> tuple[Path | None, Result]:
        if kind not in self.done:
            name, fam = KINDS[kind]
            d = self.root / f"base-{name}"
            d.mkdir(parents=True, exist_ok=True)
            argv = _plan_words(name, fam, BASE_METHOD[fam]) + ["--json", "base.json"]
            rc, out, err, dt = run_step(argv, d, self.timeout)
            r = classify(rc, out, err, [] if (d / "base.json").exists() else ["base.json"], dt, self.timeout)
            r.message = f"base plan `{' '.join(argv)}`: {r.status} {r.message}".strip()
            self.done[kind] = (d / "base.json" if r.status == "ok" else None, r)
        return self.done[kind]


def run_interrupted(argv: list, cwd: Path, timeout: float, pattern: str = r"generation \d+"):
    """Run `argv` and press Ctrl-C (SIGINT to the process) at its first stderr line matching `pattern`
    (at the latest after `timeout`); (exit code or None, stdout, stderr, seconds, interrupted)."""
    t0 = time.perf_counter()
    with open(cwd / "interrupted.stdout", "w+") as out_f:
        proc = subprocess.Popen(expand(argv), cwd=cwd, stdout=out_f, stderr=subprocess.PIPE, text=True,
                                start_new_session=True)
        lines, seen = [], threading.Event()

        def read():
            for line in proc.stderr:
                lines.append(line)
                if re.search(pattern, line):
                    seen.set()
        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        while not seen.is_set() and proc.poll() is None and time.perf_counter() - t0 < timeout:
            seen.wait(0.2)
        interrupted = proc.poll() is None
        if interrupted:
            proc.send_signal(signal.SIGINT)
        try:
            rc = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            rc = None
        reader.join(10)
        out_f.seek(0)
        out = out_f.read()
    return rc, out, "".join(lines), time.perf_counter() - t0, interrupted


def _holds(x, key: str, subkey: str | None) -> bool:
    """Some mapping inside `x` has `key` (whose value is a mapping holding `subkey`, when given)."""
    if isinstance(x, dict):
        if key in x and (subkey is None or (isinstance(x[key], dict) and subkey in x[key])):
            return True
        return any(_holds(v, key, subkey) for v in x.values())
    if isinstance(x, list):
        return any(_holds(v, key, subkey) for v in x)
    return False


def check_evidence(c: Cell, d: Path, res: Result) -> Result:
    if c.evidence is None or res.status != "ok":
        return res
    fname, key, subkey = c.evidence
    try:
        found = _holds(json.loads((d / fname).read_text()), key, subkey)
    except (OSError, ValueError):
        found = False
    if found:
        return res
    what = f"'{key}'" + (f" with '{subkey}'" if subkey else "")
    return Result("error", res.rc, f"exit {res.rc} but {fname} holds no {what}: the option was ignored", res.seconds)


def _checkpoint_generation(path: Path) -> int | None:
    try:
        return int(json.loads(path.read_text())["generation"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def run_steps(c: Cell, d: Path, timeout: float) -> tuple[Result, list]:
    res, steps = None, []
    for i, step in enumerate(c.steps):
        mode = step.get("mode", "run") if isinstance(step, dict) else "run"
        argv = list(step["argv"] if isinstance(step, dict) else step)
        last = i == len(c.steps) - 1
        missing = [f for f in c.expect if not (d / f).exists()] if last else []
        if mode == "interrupt":
            rc, out, err, dt, hit = run_interrupted(argv, d, timeout)
            res = classify(rc, out, err, [], dt, timeout) if rc is not None else Result(
                "error", None, "did not stop within 60 s of Ctrl-C", dt)
            if res.status != "refused" and "Traceback (most recent call last)" not in err and rc is not None:
                ckpt = d / argv[argv.index("--checkpoint") + 1]
                if ckpt.is_file():
                    res = Result("ok", rc, f"Ctrl-C {'sent' if hit else 'after the run ended'}, checkpoint kept", dt)
                else:
                    res = Result("error", rc, f"no checkpoint after Ctrl-C{'' if hit else ' (no progress line seen)'}"
                                 f" (exit {rc}): {_error_line(err)}", dt)
        else:
            if mode == "resume":
                ckpt = d / argv[argv.index("--checkpoint") + 1]
                gen = _checkpoint_generation(ckpt)
                argv = [str((gen or 3) + 2) if w == "{GEN}" else w for w in argv]
            rc, out, err, dt = run_step(argv, d, timeout)
            missing = [f for f in c.expect if not (d / f).exists()] if last else []
            res = classify(rc, out, err, missing, dt, timeout)
            if last:
                res = check_evidence(c, d, res)
            if mode == "resume" and res.status == "ok" and not re.search(r"resum", err, re.I):
                res = Result("error", rc, "finished but did not say it resumed from the checkpoint", dt)
        steps.append({"argv": argv, "rc": rc, "seconds": round(dt, 2), "stderr_tail": err.strip().splitlines()[-3:]})
        if res.status != "ok":
            if len(c.steps) > 1:
                res.message = f"step {i + 1}: {res.message}"
            break
    return res, steps


def run_cell(c: Cell, root: Path, bases: Bases, timeout: float) -> dict:
    d = root / re.sub(r"[^\w.-]+", "_", c.key)
    d.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    res, steps = None, []
    if c.needs_base:
        path, base = bases.get(c.kind)
        if path is None:
            res = Result("error", base.rc, f"no base plan: {base.message}", 0.0, base.one_line)
        else:
            (d / "base.json").write_bytes(path.read_bytes())
    if res is None:
        res = _prepare(c, d, timeout)
    if res is None:
        res, steps = run_steps(c, d, timeout)
    return {"feature": c.feature, "kind": c.kind, "scenario": KINDS[c.kind][0], "command": c.shown(),
            "status": res.status, "rc": res.rc, "message": res.message, "one_line": res.one_line,
            "seconds": round(time.perf_counter() - t0, 2), "steps": steps}


# ----------------------------------------------------------------------------------- judging refusals
# (feature regex, kind regex, message regex) -> (verdict, why). Verdicts: "physics" (the combination is
# meaningless for this arm) or "missing feature" (it could exist; the code does not offer it).
MISSING, PHYSICS, NO_DATA = "missing feature", "physics", "no data"
JUDGEMENTS: list = [
    (r"--method (snopt|ipopt|steepest|collocation)", r"^(?!energy)", r"plans energy-time|does not plan spatial",
     MISSING, "the energy-time cost (c1 tau'tau + c2) dt needs only joint torques, which every arm has; the solvers "
     "are written for seed 001's Fourier problem only"),
    (r"--method (ga|optimum|toppra|toppra-drake|ruckig|trajopt)$", "energy", r"plans transfer scenarios",
     MISSING, "a minimum-time plan of the vertical arm under its joint-torque limits is meaningful; the transfer "
     "planners take transfer scenarios only"),
    (r"--method family_optimum", "planar|tray", r"plans spatial scenarios",
     MISSING, "a name only: the transfer planners call the same thing `optimum` (the spatial ones take both)"),
    (r"--method family_optimum", "energy", r"plans transfer scenarios",
     MISSING, "as for the other minimum-time planners on the vertical arm"),
    (r"--method toppra-drake", "UR5|Panda", r"does not plan spatial",
     MISSING, "Drake's TOPP-RA on a spatial path is meaningful; only the planar variant is wired to it"),
    (r"--method thesis", ".", r"plans transfer scenarios|does not plan spatial",
     NO_DATA, "`thesis` replays a published plan's genes; this scenario has no published transfer plan (neither "
     "physics nor a missing feature)"),
    (r"--method trajopt", "tray", r"not available for the tray",
     MISSING, "the tray's level and friction-cone terms are missing from the trajopt constraints (TOPP-RA, Ruckig "
     "and the GA have them); a tray constraint set for trajopt is code, not physics"),
    (r"GA --checkpoint", "energy", r"plans transfer scenarios",
     MISSING, "no GA plans the vertical arm (see plan --method ga); nothing to checkpoint"),
    (r"GA --checkpoint", "UR5|Panda", r"keeps no checkpoint",
     MISSING, "the spatial GA runs the same planners/ga.run_ga, which writes checkpoints; only the plumbing is missing"),
    (r"--margin", "energy", r"takes no time scale",
     MISSING, "the execution's own verdict (goal reached within tolerance) could flip with a time scale or a plant "
     "step as the carried verdict does; the energy-time execution takes neither"),
    (r"--carried|--success|sweep", "energy", r"energy-time|no uncertainty|carried|payload",
     PHYSICS, "seed 001's vertical arm carries no payload: there is nothing to hold, slip or lose, so 'carried' and "
     "its probability have no meaning (the arm's own tracking could be swept: that would be a new verdict). Issue 27 "
     "asks the refusal to say so; a message naming option families or kinds does not"),
    (r"--success", ".", r"not reached even",
     PHYSICS, "an answer, not a refusal of the feature: under the scenario's uncertainty the plan is not carried often "
     "enough even this much slower (the cell's cheap bound, --success-max-scale 1.5 and 4 cases)"),
    (r"overrides \(API\)", ".", r"overrides apply to transfer",
     MISSING, "the same change in a copy of the YAML file is accepted (row 'scenario YAML copy'): only the dict form "
     "of load_scenario is missing"),
    (r"build_diagram", ".", r"composes transfer scenarios",
     MISSING, "simulate builds a Drake diagram for this kind too; it is not handed to the user to compose"),
    (r"--time-step-ms", "UR5|Panda", r"steps at 1 ms",
     MISSING, "the plant step of a spatial co-simulation is a number like the planar one's; fixed at 1 ms by the code"),
    (r"--time-step-ms|--explicit|--feedforward|--actuator", "energy", r"energy-time execution runs the plan",
     MISSING, "the vertical arm is run under ideal inverse dynamics; a step, a motor drive and its feedforward are "
     "meaningful for it, the code has none"),
    (r"--explicit|--feedforward", "tray", r"servos' own firmware loop",
     PHYSICS, "the Dynamixel servos close their position loop in firmware: there is no motor-voltage loop to step "
     "explicitly and no voltage feedforward to add (the message says so)"),
    (r"--explicit", "UR5|Panda", r"steps at 1 ms|implicitly",
     MISSING, "the spatial dc_motor drive has a motor loop like the planar one's; an explicit step of it is not offered"),
    (r"--feedforward back-emf", "UR5|Panda", r"applies to actuator dc_motor",
     PHYSICS, "the default ideal actuator is a torque source: it has no back-EMF to feed forward (with --actuator "
     "dc_motor the option applies; the message says so)"),
    (r"--actuator dc_motor", "planar|tray", r"actuator is its YAML actuator section",
     MISSING, "an interface gap, not physics: the planar arm's YAML actuator already is a DC motor with a gear (the "
     "tray's, Dynamixel servos), and the flag cannot name it"),
    (r"^(retime|export)$", "planar|tray|energy", r"takes a spatial scenario|spatial",
     MISSING, "a planar joint path has a fastest timing and a controller stream as a spatial one does; the commands "
     "take spatial scenarios only"),
]


def judge(row: dict) -> tuple[str, str]:
    for fpat, kpat, mpat, verdict, why in JUDGEMENTS:
        if re.search(fpat, row["feature"]) and re.search(kpat, row["kind"]) and re.search(mpat, row["message"]):
            return verdict, why
    return "not judged", "no judgement matches this message (new or changed): read it"


# ----------------------------------------------------------------------------------- outputs
def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "?"


def load_results(path: Path) -> dict:
    if not path.is_file():
        return {}
    try:
        return json.loads(path.read_text()).get("cells", {})
    except (OSError, ValueError):
        return {}


def save(path: Path, cells: dict, meta: dict) -> None:
    write_text_atomic(path, json.dumps({**meta, "cells": cells}, indent=1) + "\n")


def short(command: str) -> str:
    """The command without the words every cell shares (--quiet, the JSON output, the small energy-time
    problem, the spatial GA's population): what the row's feature adds."""
    for words in ("--quiet", " ".join(ENERGY_SMALL), "--option population=6"):
        command = command.replace(" " + words, "")
    return re.sub(r" --json \S+", "", command)


def _cmd_cell(row: dict | None) -> str:
    if row is None:
        return "(not run)"
    cmd = short(row["command"]).replace("|", "\\|")
    return f"**{row['status']}** `{cmd}`"


def markdown(cells: dict, meta: dict) -> str:
    kinds = list(KINDS)
    counts = {s: sum(1 for r in cells.values() if r["status"] == s) for s in ("ok", "refused", "error")}
    total_s = sum(r["seconds"] for r in cells.values())
    commits = sorted({r.get("commit", meta.get("commit", "?")) for r in cells.values()})
    timeouts = sorted({r.get("timeout_s", meta.get("timeout_s", "?")) for r in cells.values()}, key=str)
    lines = [
        "# Features x kinds", "",
        "Written by `python -m studies.feature_matrix` (issue 27 item 6) from out/feature_matrix.json; do not edit by "
        "hand. Each cell is the command that was run (in a temporary folder; `qmt-drake` is `python -m "
        "qmt_drake.apps.cli`, `base.json` the kind's base plan: " + ", ".join(
            f"{k}: `{BASE_METHOD[f]}`" for k, f in {"transfer": "transfer", "spatial": "spatial",
                                                     "energy": "energy"}.items()) + ") and its status: "
        "**ok** (exit 0, or exit 3 with the plan written), **refused** (exit 2, one line), **error** (traceback, "
        "timeout, other exit).", "",
        f"Commit{'s' if len(commits) > 1 else ''} {', '.join(commits)} (last run {meta.get('date', '?')}): "
        f"{len(cells)} cells, {counts['ok']} ok, {counts['refused']} refused, {counts['error']} error; "
        f"{total_s / 60:.1f} min of wall time in the cells, base plans not counted (per-step timeout "
        f"{', '.join(f'{t:g}' if isinstance(t, float) else str(t) for t in timeouts)} s).", "",
        "Kinds: " + ", ".join(f"{k} = `{v[0]}`" for k, v in KINDS.items()) + ".", "",
        "Run again: `python -m studies.feature_matrix --fresh` (every cell; the first full run took 47 min of wall "
        "time, 15.5 min of CPU, on 2 cores shared with 7 other jobs); without --fresh a cell already in the JSON with "
        "the same command is skipped; `--only TEXT --kinds NAME` selects cells. An exit 0 whose output lacks the "
        "feature's trace (--carried: carried_search, --success: its fresh check, --margin: the flip, the GA resume: "
        "'resuming' on stderr) counts as an error: the option was ignored.", "",
        "| feature | " + " | ".join(kinds) + " |", "|---|" + "---|" * len(kinds)]
    for f in FEATURES:
        lines.append(f"| {f} | " + " | ".join(_cmd_cell(cells.get(f"{f}|{k}")) for k in kinds) + " |")
    refused = [(r, *judge(r)) for r in cells.values() if r["status"] == "refused"]
    verdicts = {v: sum(1 for _, w, _ in refused if w == v) for v in (PHYSICS, MISSING, NO_DATA, "not judged")}
    lines += ["", "## Refusals", "",
              f"{len(refused)} refusals: " + ", ".join(f"{n} {v}" for v, n in verdicts.items()) + ". Verdicts (judged "
              "in studies/feature_matrix.py JUDGEMENTS, by the message): **physics**, the combination is meaningless "
              "for this arm; **missing feature**, it would mean something and the code does not offer it; **no "
              "data**, the scenario lacks what the feature replays. A refusal whose message changed is 'not judged'.",
              "", "| feature | kind | message | verdict | why |", "|---|---|---|---|---|"]
    for r, verdict, why in refused:
        msg = r["message"].replace("|", "\\|")
        lines.append(f"| {r['feature']} | {r['kind']} | {msg} | {verdict} | {why} |")
    errors = [r for r in cells.values() if r["status"] == "error"]
    lines += ["", "## Errors (defects)", "", "| feature | kind | command | first line |", "|---|---|---|---|"]
    for r in errors:
        lines.append(f"| {r['feature']} | {r['kind']} | `{r['command'].replace('|', '/')}` | "
                     f"{r['message'].replace('|', '/')} |")
    return "\n".join(lines) + "\n"


def main(argv: list | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fresh", action="store_true", help="run the selected cells again even if in the JSON")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per step of a cell (default 300)")
    ap.add_argument("--only", nargs="*", help="features to run (substrings)")
    ap.add_argument("--kinds", nargs="*", help="kinds to run (column name or scenario)")
    ap.add_argument("--json", type=Path, default=OUT_JSON)
    ap.add_argument("--md", type=Path, default=OUT_MD)
    ap.add_argument("--keep", type=Path, help="run in this folder (kept) instead of a temporary one")
    args = ap.parse_args(argv)
    cells = load_results(args.json)
    todo = [c for c in all_cells()
            if (not args.only or any(s in c.feature for s in args.only))
            and (not args.kinds or c.kind in args.kinds or KINDS[c.kind][0] in args.kinds)]
    if args.fresh:
        cells = {k: v for k, v in cells.items() if k not in {c.key for c in todo}}
    meta = {"commit": _commit(), "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
            "timeout_s": args.timeout}
    n = len(todo)
    with tempfile.TemporaryDirectory(prefix="feature-matrix-") as tmp:
        root = args.keep or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        bases = Bases(root, args.timeout)
        for k, c in enumerate(todo, 1):
            if c.key in cells and cells[c.key].get("command") == c.shown():  # a changed command runs again
                print(f"[{k}/{n}] {c.kind:14s} {c.feature}: {cells[c.key]['status']} (in the JSON, skipped)",
                      file=sys.stderr, flush=True)
                continue
            row = run_cell(c, root, bases, args.timeout)
            cells[c.key] = {**row, "commit": meta["commit"], "timeout_s": args.timeout}
            save(args.json, cells, meta)
            print(f"[{k}/{n}] {c.kind:14s} {c.feature}: {row['status']} {row['seconds']:.1f} s "
                  f"{row['message'][:100]}", file=sys.stderr, flush=True)
    write_text_atomic(args.md, markdown(cells, meta))
    print(f"{args.json}, {args.md}: {len(cells)} cells", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
