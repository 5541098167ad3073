"""Does the fastest carried verdict survive the plant step and the contact approximation? (issue 29)

    .venv/bin/python -m studies.verdict_margins --out out [--only tray|ur5-suction|ur5-magnet]

For the fastest carried crane-tray plan (TOPP-RA, time scale bisected by sweep/robust.plan_fastest_carried
as `qmt-drake plan crane-tray --method toppra --carried` does) and the fastest carried UR5 plans
(ur5-suction-bins: TOPP-RA; ur5-magnet-part: the family optimum over the line with cubic velocity,
docs/spatial.md; each through planners/spatial_carried.carried_search, the plan itself tried first),
the plan is co-simulated at plant steps of 1, 0.5 and 0.25 ms with each of Drake's discrete contact
approximations (MultibodyPlantConfig.discrete_contact_approximation: tamsi, sap, similar, lagged;
the tray's through tray/cosim's keyword, the spatial ones through margin_runs.spatial_plant_options).
Each cell: the outcome, the deciding quantity of the verdict's margin (qmt_drake/margin.py) and its
ratio to the threshold. The weld-that-breaks hands of the UR5 need SAP's constraints (TAMSI has none):
their TAMSI cells are 'n/a' with Drake's reason.

When a cell's verdict differs from the chosen plan's, the fastest time scale carried at EVERY cell is
searched (geometric bisection in [chosen, s_max] to TOL, each try run at the cells that were lost,
then the answer checked at all twelve): how far the verdict moves.

Each chosen plan's verdict margin at the defaults (api.simulate(..., margin=True): the deciding quantity
against its threshold, the time scale at which the verdict flips, to 0.5 %, and the verdict at half the
step) goes to the row's 'margin'.

Prints the table and writes OUT/verdict_margins/verdict_margins.json and .md atomically; a rerun reuses
the plans' rows already in the JSON (delete it to recompute).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from qmt_drake.api import load_scenario, plan_with, simulate
from qmt_drake.margin_runs import spatial_margin, spatial_plant_options
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic
from qmt_drake.planners.spatial_carried import carried_search
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.sweep.robust import plan_fastest_carried
from qmt_drake.tray.execute import simulate_tray_plan

STEPS_S = (1e-3, 0.5e-3, 0.25e-3)
APPROXIMATIONS = ("tamsi", "sap", "similar", "lagged")
TRAY_S_MAX, TRAY_REL_TOL = 3.0, 0.002  # the CLI's --carried defaults
TOL = 0.002  # relative width of the all-cells search's bracket
CASES = {"tray": ("crane-tray", "toppra", {}),
         "ur5-suction": ("ur5-suction-bins", "toppra", {}),
         "ur5-magnet": ("ur5-magnet-part", "family_optimum", {"family": "line_cubic_velocity"})}


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def _cell(r: dict) -> dict:
    m = r.get("margin", {})
    return {"outcome": r["outcome"], "held": bool(r["held"]), "max_slip_m": r.get("max_slip_m"),
            "quantity": m.get("quantity"), "value": m.get("value"), "threshold": m.get("threshold"),
            "ratio": m.get("ratio"), "wall_s": r.get("sim_wall_s")}


def runner(case: str, sc, plan):
    """run(time_scale, step, approximation) -> a cell of this case's plan."""
    if case == "tray":
        def run(s, h, a):
            return _cell(simulate_tray_plan(sc, plan, time_scale=s, time_step_s=h, contact_approximation=a))
        return run

    def run(s, h, a):
        traj = plan.trajectory if s == 1.0 else TimeScaled(plan.trajectory, s)
        t0 = time.perf_counter()
        try:
            r = simulate_spatial(sc, traj, **spatial_plant_options(h, a))
        except RuntimeError as exc:  # TAMSI refuses the weld constraint of the cup / magnet hand
            return {"outcome": "n/a", "held": None, "error": str(exc).strip().splitlines()[0][:200]}
        r["margin"] = spatial_margin(sc, r)
        r["sim_wall_s"] = time.perf_counter() - t0
        return _cell(r)
    return run


def fastest(case: str, sc, plan) -> tuple[float, dict]:
    """The chosen time scale of the fastest carried search, and the search's summary."""
    if case == "tray":
        p = plan_fastest_carried(sc, "toppra", base_plan=plan, s_max=TRAY_S_MAX, rel_tol=TRAY_REL_TOL, progress=log)
        s = p.extra["carried_search"]
        return float(s["chosen"]), {k: s.get(k) for k in ("chosen", "lost_below", "variable")}
    s = carried_search(sc, plan, progress=log)
    return float(s["chosen"]), {"chosen": s["chosen"], "lost_below": s["lost_below"]}


def grid(run, s: float) -> dict:
    cells = {}
    for h in STEPS_S:
        for a in APPROXIMATIONS:
            c = cells[f"{h * 1e3:g} ms {a}"] = dict(run(s, h, a), time_step_s=h, approximation=a)
            log(f"  x{s:.5f} {h * 1e3:g} ms {a}: {c['outcome']}"
                + (f", {c['quantity']} {c['value']:.4g} ({c['ratio']:.3f} of its threshold)"
                   if c.get("ratio") is not None else f" ({c.get('error', '')})"))
    return cells


def carried_everywhere(run, s_chosen: float, cells: dict, s_max: float) -> dict:
    """The fastest scale carried at every cell (module docstring), or None if s_max is not."""
    lost = [(c["time_step_s"], c["approximation"]) for c in cells.values() if c["held"] is False]
    tries = []

    def ok(s):
        res = [run(s, h, a) for h, a in lost]
        tries.append({"time_scale": s, "outcomes": [r["outcome"] for r in res]})
        log(f"  all-cells search x{s:.5f}: {[r['outcome'] for r in res]}")
        return all(r["held"] for r in res)

    lo, hi = s_chosen, s_max
    if not ok(hi):
        return {"time_scale": None, "tries": tries, "s_max": s_max}
    while hi / lo - 1 > TOL:
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return {"time_scale": hi, "lost_below": lo, "tries": tries, "relative_to_chosen": hi / s_chosen - 1,
            "cells": grid(run, hi)}


def study(case: str) -> dict:
    name, method, opts = CASES[case]
    sc = load_scenario(name)
    t0 = time.perf_counter()
    plan = plan_with(method, sc, **opts)
    s, search = fastest(case, sc, plan)
    bound = float(getattr(plan, "motion_time_s", getattr(plan, "duration_s", math.nan)))
    log(f"{name} {method}: planned {bound:.4f} s, fastest carried x{s:.5f}")
    run = runner(case, sc, plan)
    cells = grid(run, s)
    row = {"scenario": name, "method": method, "options": opts, "planned_s": bound, "chosen_time_scale": s,
           "search": search, "cells": cells,
           "same_verdict": len({c["held"] for c in cells.values() if c["held"] is not None}) == 1}
    if not row["same_verdict"]:
        s_max = TRAY_S_MAX if case == "tray" else 2.5
        row["carried_at_every_cell"] = carried_everywhere(run, s, cells, min(s_max, s * 1.2))
    row["margin"] = with_flip(sc, plan, s)
    row["wall_s"] = time.perf_counter() - t0
    return row


def with_flip(sc, plan, s: float) -> dict:
    """The chosen plan's margin at the co-simulation's defaults (module docstring)."""
    r = simulate(sc, plan, time_scale=s, margin=True)
    m = r["margin"]
    f, h = m["flip"], m["half_step"]
    log(f"  margin at x{s:.5f}: {m['quantity']} {m['value']:.4g} ({m['ratio']:.4f}); flips at x"
        f"{f['flip_time_scale'] if f['flip_time_scale'] is None else round(f['flip_time_scale'], 5)}; "
        f"half step: {h['outcome_at_half_step']}")
    return m


def markdown(res: dict) -> str:
    flips: list[str] = []
    lines = ["Cells: outcome, then the deciding quantity (slip against 1 mm, or the hand's ratio against 1).", "",
             "| plan | time scale | step | " + " | ".join(APPROXIMATIONS) + " |",
             "|---|---|---|" + "---|" * len(APPROXIMATIONS)]

    def fmt(c):
        if c["held"] is None:
            return "n/a (TAMSI: no weld constraint)"
        if c["quantity"] in ("max_slip_m", "final_slide_m"):
            return f"{c['outcome']}, slip {c['value'] * 1e3:.3f} mm"
        return f"{c['outcome']}, {c['quantity']} {c['value']:.5f}"

    for row in res.values():
        f = row.get("margin", {}).get("flip") or {}
        if f.get("flip_time_scale"):
            flips.append(f"- {row['scenario']} {row['method']} at x{row['chosen_time_scale']:.5f}: deciding "
                         f"{row['margin']['quantity']} {row['margin']['ratio']:.4f} of its threshold; the verdict flips "
                         f"at x{f['flip_time_scale']:.5f} ({f['relative_to_run']:+.2%}; carried at x{f['carried_at']:.5f}, "
                         f"lost at x{f['lost_at']:.5f}, {f['runs']} runs); at half the step "
                         f"{row['margin']['half_step']['outcome_at_half_step']}")
        for key, s, cells in [("chosen", row["chosen_time_scale"], row["cells"])] + (
                [("all", row["carried_at_every_cell"]["time_scale"], row["carried_at_every_cell"]["cells"])]
                if row.get("carried_at_every_cell", {}).get("cells") else []):
            label = f"{row['scenario']} {row['method']}" + (" (carried at every cell)" if key == "all" else "")
            for h in STEPS_S:
                cs = [cells[f"{h * 1e3:g} ms {a}"] for a in APPROXIMATIONS]
                lines.append(f"| {label} | x{s:.4f} ({row['planned_s'] * s:.4f} s) | {h * 1e3:g} ms | "
                             + " | ".join(fmt(c) for c in cs) + " |")
    return "\n".join(lines + [""] + flips) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--only", choices=sorted(CASES), action="append")
    a = ap.parse_args(argv)
    check_output_dir(a.out, "--out")
    d = Path(a.out) / "verdict_margins"
    d.mkdir(parents=True, exist_ok=True)
    path = d / "verdict_margins.json"
    res = json.loads(path.read_text()) if path.exists() else {}
    for case in a.only or list(CASES):
        if case in res and "margin" not in res[case]:  # a row of a run before the margin: add it
            name, method, opts = CASES[case]
            sc = load_scenario(name)
            res[case]["margin"] = with_flip(sc, plan_with(method, sc, **opts), res[case]["chosen_time_scale"])
        elif case in res:
            log(f"{case}: reused from {path}")
            continue
        else:
            res[case] = study(case)
        write_text_atomic(path, json.dumps(jsonable(res), indent=1))
    md = markdown(res)
    write_text_atomic(d / "verdict_margins.md", md)
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
