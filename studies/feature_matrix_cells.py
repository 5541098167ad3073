"""The cells of studies/feature_matrix.py: the kinds (one built-in scenario each), the features, the command(s)
of each cell, and the scenario copies, sweep specs and joint-path CSV some cells run on."""

from __future__ import annotations

import copy
import os
import shlex
from dataclasses import dataclass, field
from pathlib import Path

import yaml

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
ENERGY_SOLVERS = ("snopt", "ipopt", "steepest", "collocation")  # the Fourier planners ENERGY_SMALL is for
# GA sizes that run in seconds (transfer GA: the scenario's population; spatial: --option population).
GA_SMALL = {"transfer": ["--stall", "2"], "spatial": ["--stall", "2", "--option", "population=6"],
            "energy": ["--stall", "2", "--option", "population=6"]}  # the energy arm's GA is the spatial one
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
    # (file, key, subkey[, value]): a JSON output that must hold `key` (a mapping holding `subkey`; equal
    # to `value`) somewhere, else an exit 0 ignored the option (a silent wrong answer, an error)
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
    if fam == "energy" and method in ENERGY_SOLVERS:  # the transfer planners on the arm take no Fourier options
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
        words = ["qmt-drake", "plan", name, "--method", "ga", "--generations", "100000", "--stall", "0",
                 *GA_SMALL[fam][2:]]
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
        words, evidence = extra[feature], SIM_EVIDENCE.get(feature)
        if feature == "simulate --explicit" and fam == "spatial":  # the spatial --explicit is the DC drive's law
            words, evidence = ["--actuator", "dc_motor", "--explicit"], ("sim.json", "explicit", None, True)
        return Cell(feature, kind, [sim + words + ["--json", "sim.json"]], expect=["sim.json", *out],
                    needs_base=True, evidence=evidence)
    if feature == "retime":
        return Cell(feature, kind, [["qmt-drake", "retime", name, "--path", "path.csv", "--method", "toppra",
                                     "--quiet", "--json", "plan.json"]], expect=["plan.json"], needs_base=True,
                    prep={"path.csv": ("csv", None)})
    if feature == "export":
        return Cell(feature, kind, [["qmt-drake", "export", "base.json", "--scenario", name, "--format", "csv",
                                     "--rate", "500", "--out", "stream.csv", "--json", "export.json"]],
                    expect=["stream.csv"], needs_base=True)
    raise ValueError(f"no command for feature {feature!r}")


# what a simulate row's JSON shows when its option was used (the planar co-simulation's keys)
SIM_EVIDENCE = {"simulate --margin": ("sim.json", "flip", None),
                "simulate --time-step-ms": ("sim.json", "time_step_s", None, 0.001),
                "simulate --explicit": ("sim.json", "implicit_loop_damping", None, False),
                "simulate --feedforward back-emf": ("sim.json", "feedforward", None, "back-emf"),
                "simulate --actuator dc_motor": ("sim.json", "actuator", None, "dc_motor")}


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
