"""The table of issue 30 items 1 and 4: each bad input of the issue, the call or command, the one line it
now prints, and how long it took and how much the process's peak memory grew before the refusal.

    python -m studies.bad_inputs_table            # a Markdown table on stdout (about 20 s)

The CLI rows run the CLI's main() in this process (a fresh `qmt-drake` adds its start-up, ~2 s of CPU).
Every row must be a refusal (QmtInputError, or the CLI's exit 2 with one line); a row that is accepted or
raises anything else is printed as such and makes the script exit 1. Scenario files for the file rows are
written to a temporary folder from the shipped ones, one key changed.
"""

from __future__ import annotations

import contextlib
import copy
import io
import resource
import sys
import tempfile
import time
from pathlib import Path

import yaml

from qmt_drake.api import load_plan, load_scenario, plan_with, simulate
from qmt_drake.apps.cli import main as cli_main
from qmt_drake.config.scenario import SCENARIO_DIR
from qmt_drake.errors import QmtInputError

NAN, INF = float("nan"), float("inf")


def _file(d: Path, base: str, changes: dict, tag: str) -> Path:
    raw = copy.deepcopy(yaml.safe_load((SCENARIO_DIR / f"{base}.yaml").read_text()))
    for key, v in changes.items():
        x, keys = raw, key.split(".")
        for k in keys[:-1]:
            x = x[k]
        if v is _DROP:
            x.pop(keys[-1], None)
        else:
            x[keys[-1]] = v
    p = d / f"{tag}.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


_DROP = object()


def _api_row(cls: str, call: str, thunk) -> tuple[str, str, str, float, float, bool]:
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t0 = time.perf_counter()
    try:
        thunk()
        line, ok = "ACCEPTED", False
    except QmtInputError as exc:
        line, ok = str(exc), "\n" not in str(exc)
    except BaseException as exc:  # noqa: BLE001 - the table shows any defect as it is
        line, ok = f"{type(exc).__name__}: {exc}", False
    dt = time.perf_counter() - t0
    return cls, call, line, dt, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - rss0, ok


def _cli_row(cls: str, argv: list[str]) -> tuple[str, str, str, float, float, bool]:
    """The CLI's main() in this process (its import, 2 s of CPU, is not part of the refusal): exit code 2
    and exactly one error line."""
    err = io.StringIO()
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t0 = time.perf_counter()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = cli_main(argv)
        except SystemExit as exc:
            code = exc.code
    dt = time.perf_counter() - t0
    errs = [x for x in err.getvalue().splitlines() if "error" in x]
    line = errs[-1].removeprefix("qmt-drake: error: ") if errs else (err.getvalue().strip().splitlines() or ["-"])[-1]
    shown = " ".join(a if "/" not in a else Path(a).name for a in argv)
    return (cls, f"qmt-drake {shown}", line, dt, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - rss0,
            code == 2 and len(errs) == 1)


def rows(d: Path) -> list:
    sc = load_scenario("thesis-ch4")
    p = plan_with("thesis", sc)
    magnet = _file(d, "ur5-magnet-part", {"limits.check_rate_hz": 20.0, "actuators.motor": _DROP}, "ur5-magnet-part")
    sm = load_scenario(magnet)
    smp = plan_with("ruckig", sm)
    (d / "page.html").write_text("<!doctype html><html><body>a page</body></html>\n")
    api = [
        ("type", "load_scenario(None)", lambda: load_scenario(None)),
        ("type", "load_scenario(123)", lambda: load_scenario(123)),
        ("type", "load_scenario('thesis-ch4', overrides=[1, 2])", lambda: load_scenario("thesis-ch4", overrides=[1, 2])),
        ("type", "plan_with('toppra', 'no-such-scenario')  # a name is loaded", lambda: plan_with("toppra", "no-such-scenario")),
        ("NaN/inf", "plan_with('ga', ur5, generations=nan)", lambda: plan_with("ga", sm, generations=NAN)),
        ("size", "plan_with('ga', ur5, population=0)", lambda: plan_with("ga", sm, population=0)),
        ("size", "plan_with('ga', ur5, population=10**8)", lambda: plan_with("ga", sm, population=10 ** 8)),
        ("size", "plan_with('ga', ur5, population=10**6)  # budget", lambda: plan_with("ga", sm, population=10 ** 6)),
        ("size", "plan_with('toppra', ur5, n_grid=10**9)", lambda: plan_with("toppra", sm, n_grid=10 ** 9)),
        ("size", "plan_with('ga', ur5, generations=10**9)", lambda: plan_with("ga", sm, generations=10 ** 9)),
        ("NaN/inf", "plan_with('ga', thesis-ch4, max_generations=inf)", lambda: plan_with("ga", sc, max_generations=INF)),
        ("key", "plan_with('ga', thesis-ch4, max_generation=3)", lambda: plan_with("ga", sc, max_generation=3)),
        ("key", "plan_with('snopt', ohsaka-fig3, divison=40)",
         lambda: plan_with("snopt", load_scenario("ohsaka-fig3"), divison=40)),
        ("type", "simulate(sc, p, time_scale='2')", lambda: simulate(sc, p, time_scale="2")),
        ("type", "simulate(sc, p, time_scale=None)", lambda: simulate(sc, p, time_scale=None)),
        ("size", "simulate(sc, p, time_scale=1e6)", lambda: simulate(sc, p, time_scale=1e6)),
        ("key", "simulate(sc, p, timescale=2)", lambda: simulate(sc, p, timescale=2)),
        ("value", "simulate(ur5-magnet-part, p, actuator='dc_motor')  # no motors",
         lambda: simulate(sm, smp, actuator="dc_motor")),
        ("type", "simulate(sc, None)", lambda: simulate(sc, None)),
        ("NaN/inf", "plan.sample(nan)  # spatial plan", lambda: smp.sample(NAN)),
        ("type", "plan.sample('a')", lambda: p.sample("a")),
        ("type", "load_plan(None)", lambda: load_plan(None)),
        ("path", "load_plan(<a directory>)", lambda: load_plan(d)),
        ("path", "load_plan(page.html)", lambda: load_plan(d / "page.html")),
        ("type", "plan.write_json(None)", lambda: p.write_json(None)),
        ("size", "plan.write_csv(path, rate_hz=1e12)", lambda: p.write_csv(d / "x.csv", rate_hz=1e12)),
    ]
    out = [_api_row(*r) for r in api]
    files = [
        ("value", "arm.lock_joints: null", "panda-tray-cup", {"arm.lock_joints": None}),
        ("value", "arm.lock_joints: panda_finger_joint1", "panda-tray-cup", {"arm.lock_joints": "panda_finger_joint1"}),
        ("value", "arm.face_axis: [0, 0, 0]", "ur5-suction-bins", {"arm.face_axis": [0, 0, 0]}),
        ("size", "hand.rim_points: 1000000000", "ur5-suction-bins", {"hand.rim_points": 10 ** 9}),
        ("size", "hand.rim_points: 1000000", "ur5-suction-bins", {"hand.rim_points": 10 ** 6}),
        ("size", "hand.pyramid_edges: 10000000", "ur5-suction-bins", {"hand.pyramid_edges": 10 ** 7}),
        ("size", "limits.check_rate_hz: 1e9", "ur5-suction-bins", {"limits.check_rate_hz": 1e9}),
        ("size", "task.transfer_points: 1000000", "ur5-suction-bins", {"task.transfer_points": 10 ** 6}),
        ("size", "task.poses_m: 10,000 poses", "ur5-suction-bins",
         {"task.poses_m": [[0.45, -0.3, 0.1 + 1e-5 * k] for k in range(10000)]}),
        ("size", "task.poses_m: 150 poses", "ur5-suction-bins",
         {"task.poses_m": [[0.45, -0.3, 0.1 + 1e-3 * k] for k in range(150)]}),
        ("value", "payload.inertia_kgm2: [0.001, 0.001, 0.05]", "ur5-suction-bins",
         {"payload.inertia_kgm2": [0.001, 0.001, 0.05]}),
        ("value", "payload.mass_kg: 1e9", "ur5-suction-bins", {"payload.mass_kg": 1e9}),
        ("value", "task.hand_rpy_rad in degrees", "ur5-suction-bins",
         {"task.face_normal": _DROP, "task.hand_rpy_rad": [[180.0, 0.0, 0.0] for _ in range(4)]}),
        ("path", "arm.urdf: a directory", "ur5-suction-bins", {"arm.package": _DROP, "arm.urdf": str(d)}),
        ("path", "arm.urdf: an HTML page", "ur5-suction-bins",
         {"arm.package": _DROP, "arm.urdf": str(d / "page.html")}),
        ("key", "kind: spatial_trasfer", "ur5-suction-bins", {"kind": "spatial_trasfer"}),
        ("key", "kind: missing", "ur5-suction-bins", {"kind": _DROP}),
        ("value", "actuator p = i = d = 0 (tray servos)", "crane-tray",
         {"actuator.p": [0, 0, 0], "actuator.i": [0, 0, 0], "actuator.d": [0, 0, 0]}),
        ("size", "actuator.control_period_s: 1e-7", "crane-tray", {"actuator.control_period_s": 1e-7}),
    ]
    for k, (cls, what, base, changes) in enumerate(files):
        path = _file(d, base, changes, f"case{k}")
        out.append(_api_row(cls, f"load_scenario(<{base}, {what}>)", lambda path=path: load_scenario(path)))
    text = (SCENARIO_DIR / "ur5-suction-bins.yaml").read_text()
    bomb = d / "bomb.yaml"
    bomb.write_text(text.replace("  seed_rad: [-0.6, -1.3, 1.6, -1.9, -1.57, 0.0]",
                                 "  seed_rad: [&a [1,1,1,1,1,1,1,1,1], &b [*a,*a,*a,*a,*a,*a,*a,*a,*a], "
                                 "&c [*b,*b,*b,*b,*b,*b,*b,*b,*b], [*c,*c,*c,*c,*c,*c,*c,*c,*c]]"))
    out.append(_api_row("size", "load_scenario(<a YAML alias bomb in task.seed_rad>)", lambda: load_scenario(bomb)))
    cli = [
        ("size", ["plan", "ur5-suction-bins", "--method", "ruckig", "--carried", "--carried-max-scale", "1e6"]),
        ("size", ["plan", "thesis-ch4", "--method", "thesis", "--carried", "--carried-max-scale", "1e6"]),
        ("size", ["plan", "ur5-suction-bins", "--method", "ga", "--option", "population=0"]),
        ("size", ["plan", "ur5-suction-bins", "--method", "toppra", "--option", "n_grid=1000000000"]),
        ("size", ["plan", "ur5-suction-bins", "--method", "toppra", "--option", "n_grid=1"]),
        ("size", ["plan", "ur5-suction-bins", "--method", "toppra", "--option", "n_grid=-5"]),
        ("value", ["plan", str(_file(d, "crane-tray", {"actuator.p": [0, 0, 0], "actuator.i": [0, 0, 0],
                                                       "actuator.d": [0, 0, 0]}, "servo-pid0")), "--method", "thesis"]),
        ("size", ["plan", str(_file(d, "ur5-suction-bins", {"limits.check_rate_hz": 1e9}, "rate1e9")),
                  "--method", "toppra"]),
    ]
    out += [_cli_row(cls, argv) for cls, argv in cli]
    return out


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        table = rows(Path(tmp))
    print("| class | call or command | the line it prints | s | peak RSS growth |")
    print("|---|---|---|---|---|")
    for cls, call, line, dt, grew, ok in table:
        mem = f"{grew / 2 ** 20:.0f} MiB"
        flag = "" if ok else " **NOT REFUSED IN ONE LINE**"
        print(f"| {cls} | `{call}` | {line.replace('|', '/')}{flag} | {dt:.2f} | {mem} |")
    bad = [r for r in table if not r[5] or r[3] > 5.0]
    print(f"\n{len(table)} rows, {len(table) - len(bad)} refused in one line under 5 s")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
