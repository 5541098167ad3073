"""Does the fastest carried verdict survive the plant step and the contact approximation? (issue 29)

    .venv/bin/python -m studies.verdict_margins --out out [--only CASE ...]

CASES: tray, ur5-suction, ur5-magnet (weld hands), ur5-suction-contact, ur5-magnet-contact (contact hands).
For the fastest carried crane-tray plan (TOPP-RA, time scale bisected by sweep/robust.plan_fastest_carried
as `qmt-drake plan crane-tray --method toppra --carried` does) and the fastest carried UR5 plans
(ur5-suction-bins: TOPP-RA; ur5-magnet-part: the family optimum over the line with cubic velocity,
docs/spatial.md; each through planners/spatial_carried.carried_search with the weld hand, ideal actuators,
the plan itself tried first), the plan is co-simulated at plant steps of 1, 0.5 and 0.25 ms with each of
Drake's discrete contact approximations (MultibodyPlantConfig.discrete_contact_approximation: tamsi, sap,
similar, lagged; the tray's through tray/cosim's keyword, the spatial ones through
margin_runs.spatial_plant_options). Each cell: the outcome, the deciding quantity of the verdict's margin
(qmt_drake/margin.py, margin_runs.spatial_margin) and its ratio to the threshold. The weld-that-breaks
hands of the UR5 need SAP's constraints (TAMSI has none): their TAMSI cells are 'n/a' with Drake's reason.

The contact cases (`hand.physics: contact`, sim/spatial_contact_hand.py: the part a free body held by
contact and a pull; its default cell 1 ms lagged) run the same plan: first at the weld's fastest carried
scale, then at the contact hand's own fastest carried scale, bisected at its default cell as
carried_search would (k >= 1, the plan itself first; from the weld's scale outward by x1.02, 1.1, 1.5, 2.5
when lost there, then geometric bisection to TOL); its bracket is the row's margin (the flip scale).

When a grid's verdicts differ, the fastest time scale carried at EVERY cell is searched by the library's
search (carried_cells.carried_at_every_cell, what `qmt-drake plan --carried --carried-cells all` runs:
raised from the choice by x1.02 steps, then geometric bisection to TOL, each try run at the cells lost so
far, the answer checked at all twelve): how far the verdict moves.

Each weld-hand or tray plan's verdict margin at the defaults (api.simulate(..., margin=True): the deciding
quantity against its threshold, the time scale at which the verdict flips, to 0.5 %, and the verdict at
half the step) goes to the row's 'margin'.

Resumable: every co-simulation, search and margin is stored under '_runs' in
OUT/verdict_margins/verdict_margins.json (written atomically after each), keyed by its case, time scale,
step and approximation; a rerun replays the searches from it and runs only what is missing (delete the
file to recompute). A contact case's keys and row also carry the contact hand's revision
(spatial_contact_hand.CONTACT_HAND_REVISION, e.g. 'ur5-suction-contact|r2|1.0|0.001|sap'): runs of an older
contact hand are not reused, the tray's and the weld hands' are. Prints the table and writes the JSON and
the .md atomically.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

from qmt_drake.api import load_scenario, plan_with, simulate
from qmt_drake.carried_cells import carried_at_every_cell
from qmt_drake.errors import QmtSimulationError
from qmt_drake.margin_runs import spatial_margin, spatial_plant_options
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic
from qmt_drake.planners.spatial_carried import carried_search
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_contact_hand import CONTACT_HAND_REVISION
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.sweep.robust import plan_fastest_carried
from qmt_drake.timescale import Grow, search_scale
from qmt_drake.tray.execute import simulate_tray_plan
from studies.verdict_margins_table import markdown

STEPS_S = (1e-3, 0.5e-3, 0.25e-3)
APPROXIMATIONS = ("tamsi", "sap", "similar", "lagged")
TRAY_S_MAX, TRAY_REL_TOL = 3.0, 0.002  # the CLI's --carried defaults
TOL = 0.002  # relative width of the all-cells and the contact hand's bracket
CONTACT_DEFAULT = (1e-3, "lagged")  # the contact hand's own cell (sim/spatial_contact_hand)
OUTWARD = (1.02, 1.1, 1.5, 2.5)  # the contact search's steps from the weld's scale (margin.OUTWARD_FACTORS)
# case: (scenario, method, options, hand physics; None: the scenario's own)
CASES = {"tray": ("crane-tray", "toppra", {}, None),
         "ur5-suction": ("ur5-suction-bins", "toppra", {}, None),
         "ur5-magnet": ("ur5-magnet-part", "family_optimum", {"family": "line_cubic_velocity"}, None),
         "ur5-suction-contact": ("ur5-suction-bins", "toppra", {}, "contact"),
         "ur5-magnet-contact": ("ur5-magnet-part", "family_optimum", {"family": "line_cubic_velocity"}, "contact")}


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


class Store:
    """The study's JSON: rows by case, and every run, search and margin under '_runs' by key, written
    atomically after each new entry (the module docstring's resumption)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.data = json.loads(path.read_text()) if path.exists() else {}
        self.data.setdefault("_runs", {})

    def memo(self, key: str, compute):
        runs = self.data["_runs"]
        if key not in runs:
            runs[key] = jsonable(compute())
            self.save()
        return runs[key]

    def save(self) -> None:
        write_text_atomic(self.path, json.dumps(jsonable(self.data), indent=1))


def _cell(r: dict) -> dict:
    m = r.get("margin", {})
    extra = ("lost_at_s", "max_gap_m", "max_slide_m", "final_slide_on_face_m", "max_tilt_while_held_rad",
             "max_grip_ratio_while_held", "final_goal_error_rad", "goal_error_at_end_rad", "arrival_wait_s",
             "arrival_steady", "relaxation_time_s")
    return {"outcome": r["outcome"], "held": bool(r["held"]), "max_slip_m": r.get("max_slip_m"),
            "quantity": m.get("quantity"), "value": m.get("value"), "threshold": m.get("threshold"),
            "ratio": m.get("ratio"), "wall_s": r.get("sim_wall_s"),
            "criteria": {c["quantity"]: c["ratio"] for c in m.get("criteria", [])},
            **({k: r.get(k) for k in extra} if r.get("hand_physics") == "contact" else {})}


def runner(case: str, sc, plan, store: Store):
    """run(time_scale, step, approximation) -> a cell of this case's plan, from the store when it holds it."""
    def raw(s, h, a):
        if case == "tray":
            return _cell(simulate_tray_plan(sc, plan, time_scale=s, time_step_s=h, contact_approximation=a))
        traj = plan.trajectory if s == 1.0 else TimeScaled(plan.trajectory, s)
        t0 = time.perf_counter()
        try:
            r = simulate_spatial(sc, traj, **spatial_plant_options(h, a))
        except QmtSimulationError as exc:  # the co-simulation could not finish: lost, with its reason
            return {"outcome": "failed", "held": False, "error": str(exc).strip().splitlines()[0][:200]}
        except RuntimeError as exc:  # TAMSI refuses the weld constraint of the cup / magnet hand
            return {"outcome": "n/a", "held": None, "error": str(exc).strip().splitlines()[0][:200]}
        r["margin"] = spatial_margin(sc, r)
        r["sim_wall_s"] = time.perf_counter() - t0
        return _cell(r)

    def run(s, h, a):
        return store.memo(f"{key(case)}|{s!r}|{h!r}|{a}", lambda: raw(s, h, a))
    return run


def key(case: str) -> str:
    """The store's key prefix of a case: a contact case's carries the contact hand's revision (module docstring)."""
    return f"{case}|r{CONTACT_HAND_REVISION}" if CASES[case][3] == "contact" else case


def reusable(case: str, row: dict) -> bool:
    """A finished row of this code's hands: a contact case's row of the present contact hand revision."""
    return CASES[case][3] != "contact" or row.get("contact_hand_revision") == CONTACT_HAND_REVISION


def fastest(case: str, sc, plan, store: Store) -> tuple[float, dict]:
    """The chosen time scale of the weld hand's (or the tray's) fastest carried search, and its summary."""
    def search():
        if case == "tray":
            p = plan_fastest_carried(sc, "toppra", base_plan=plan, s_max=TRAY_S_MAX, rel_tol=TRAY_REL_TOL,
                                     progress=log)
            s = p.extra["carried_search"]
            return {k: s.get(k) for k in ("chosen", "lost_below", "variable")}
        s = carried_search(sc, plan, progress=log)
        return {"chosen": s["chosen"], "lost_below": s["lost_below"]}
    found = store.memo(f"{case}|search", search)
    return float(found["chosen"]), found


def contact_fastest(run, s_weld: float) -> dict:
    """The contact hand's fastest carried scale at its default cell (module docstring): {'chosen' (None: not
    carried up to x2.5 of the weld's), 'lost_below', 'status', 'tries'}."""
    tries: list[dict] = []

    def held(s: float) -> bool:
        c = run(s, *CONTACT_DEFAULT)
        tries.append({"time_scale": s, "outcome": c["outcome"]})
        log(f"  contact search x{s:.5f}: {c['outcome']}")
        return bool(c["held"])

    if held(s_weld):
        if s_weld == 1.0:
            return {"chosen": 1.0, "lost_below": None, "status": "planned", "tries": tries}
        f = search_scale(held, 1.0, s_weld, ends=("lo",), midpoint="geometric", rel_tol=TOL)
    else:
        f = search_scale(held, midpoint="geometric", rel_tol=TOL,
                         grow=Grow(start=s_weld, start_holds=False, table=OUTWARD))
    lost = None if f.status == "end" else f.lo
    return {"chosen": f.holding, "lost_below": lost, "status": f.status, "tries": tries}


def grid(run, s: float) -> dict:
    cells = {}
    for h in STEPS_S:
        for a in APPROXIMATIONS:
            c = cells[f"{h * 1e3:g} ms {a}"] = dict(run(s, h, a), time_step_s=h, approximation=a)
            log(f"  x{s:.5f} {h * 1e3:g} ms {a}: {c['outcome']}"
                + (f", {c['quantity']} {c['value']:.4g} ({c['ratio']:.3f} of its threshold)"
                   if c.get("ratio") is not None else f" ({c.get('error', '')})"))
    return cells


def same_verdict(cells: dict) -> bool:
    return len({c["held"] for c in cells.values() if c["held"] is not None}) == 1


def scenario_of(case: str):
    name, method, opts, physics = CASES[case]
    sc = load_scenario(name)
    return (sc if physics is None else dataclasses.replace(sc, hand_physics=physics)), plan_with(method, sc, **opts)


def study(case: str, store: Store) -> dict:
    name, method, opts, physics = CASES[case]
    sc, plan = scenario_of(case)
    t0 = time.perf_counter()
    weld_case = case.removesuffix("-contact")
    s, search = fastest(weld_case, *scenario_of(weld_case), store)  # the weld's (tray's) own search
    bound = float(getattr(plan, "motion_time_s", getattr(plan, "duration_s", math.nan)))
    log(f"{name} {method} ({physics or 'scenario'} hand): planned {bound:.4f} s, fastest carried x{s:.5f}")
    run = runner(case, sc, plan, store)
    row = {"scenario": name, "method": method, "options": opts, "hand": physics or "scenario", "planned_s": bound}
    if physics == "contact":
        row["weld_time_scale"], row["weld_search"] = s, search
        row["cells_at_weld"] = grid(run, s)
        row["contact_hand_revision"] = CONTACT_HAND_REVISION
        search = store.memo(f"{key(case)}|contact_search", lambda: contact_fastest(run, s))
        if search["chosen"] is None:
            row.update(chosen_time_scale=None, search=search, cells={}, same_verdict=same_verdict(row["cells_at_weld"]))
            row["wall_s"] = time.perf_counter() - t0
            return row
        s = float(search["chosen"])
        lo = search["lost_below"]
        row["margin"] = {"flip": {"carried_at": s, "lost_at": lo, "flip_time_scale": None if lo is None
                                  else math.sqrt(s * lo), "relative_to_run": None if lo is None else math.sqrt(lo / s) - 1},
                         "cell": f"{CONTACT_DEFAULT[0] * 1e3:g} ms {CONTACT_DEFAULT[1]}"}
    row.update(chosen_time_scale=s, search=search)
    cells = row["cells"] = grid(run, s)
    row["same_verdict"] = same_verdict(cells)
    if not row["same_verdict"]:
        s_max = TRAY_S_MAX if case == "tray" else 2.5
        default = CONTACT_DEFAULT if physics == "contact" else (1e-3, "lagged" if case == "tray" else "sap")
        every = carried_at_every_cell(run, s, [(h, a) for h in STEPS_S for a in APPROXIMATIONS], k_max=s_max,
                                      rel_tol=TOL, default_cell=default, progress=log)
        row["carried_at_every_cell"] = {"time_scale": every["time_scale"], "lost_below": every["lost_below"],
                                        "tries": every["tries"], "relative_to_chosen": every["relative_to_chosen"],
                                        "cells": every["table"]}
    if physics != "contact":
        row["margin"] = store.memo(f"{case}|margin|{s!r}", lambda: with_flip(sc, plan, s))
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--only", choices=list(CASES), action="append")
    ap.add_argument("--table-only", action="store_true", help="print the table of the stored rows, run nothing")
    a = ap.parse_args(argv)
    check_output_dir(a.out, "--out")
    d = Path(a.out) / "verdict_margins"
    d.mkdir(parents=True, exist_ok=True)
    store = Store(d / "verdict_margins.json")
    for case in [] if a.table_only else (a.only or list(CASES)):
        if case in store.data and reusable(case, store.data[case]):  # (an unfinished one resumes from '_runs')
            log(f"{case}: reused from {store.path}")
            continue
        store.data[case] = study(case, store)
        store.save()
    md = markdown({k: v for k, v in store.data.items() if k in CASES}, STEPS_S, APPROXIMATIONS)
    write_text_atomic(d / "verdict_margins.md", md)
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
