"""Seed 002 re-measured through the servos as the firmware runs them (issue 20): the fastest carried
TOPP-RA tray transfer per bottle-tray friction and bottle fill, with the goals shaped for the
firmware's own PID (`actuator.reference: shaped`, the crane-tray default), and for the seed's 30 g
bottle also with the plan streamed as it is (`plain`).

    .venv/bin/python -m studies.tray_carried --out out [--quick]

For every friction mu and fill (water in the PET bottle; mass and centre-of-mass height from
systems/tray_object.BottleSpec.pet_500ml) the crane-tray scenario is loaded with that bottle, TOPP-RA
plans the line within the scenario's plan margin of mu and of the base ring (its time is the
time-optimal bound of the line for that bottle), and sweep/robust.plan_fastest_carried bisects the
time scale s in [1, s_max] until the nominal co-simulation carries the bottle (to 0.5 % in s). The
ratio carried / planned is how much of the physical bound the servos give away. Prints a table and
writes OUT/tray_carried/tray_carried.json, .md and tray_carried.png (atomically); a rerun reuses
the cells already in the JSON.

Each cell also replays its plan at x1.0 and at the fastest carried scale with the arm logged every
plant step (tray/executed.execute_and_measure): the joint tracking error against the plan (RMS and
max over the move and the tail) and the executed limit ratio, the tray terms of the planner's own
LimitSet (friction and ring radius x plan_margin 0.8, so 1.25 is the friction cone itself)
evaluated on the executed joint motion, accelerations the 10 ms central difference of the logged
velocities, next to the plan's peak at the same scale. Cells in the JSON without it get it on a
rerun without a new search.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from qmt_drake.errors import QmtInputError  # noqa: E402
from qmt_drake.outputs import atomic_output, check_output_dir, jsonable, write_text_atomic  # noqa: E402
from qmt_drake.planners import plan_with  # noqa: E402
from qmt_drake.sweep.robust import plan_fastest_carried  # noqa: E402
from qmt_drake.systems.tray_object import BottleSpec  # noqa: E402
from qmt_drake.transfer_scenario import load_scenario  # noqa: E402
from qmt_drake.tray.executed import execute_and_measure  # noqa: E402

FRICTIONS = (0.2, 0.3, 0.4, 0.6)
WATER_KG = (0.030, 0.150, 0.300, 0.480)  # the seed's 30 g, then fuller bottles (500 mL holds 0.5 kg)
SHELL_KG = 0.020
REFERENCES = ("shaped", "plain")
S_MAX = 3.0
REL_TOL = 0.005


def bottle_overrides(mu: float, water_kg: float, reference: str) -> dict:
    b = BottleSpec.pet_500ml(mass_kg=SHELL_KG + water_kg, shell_mass_kg=SHELL_KG)
    return {"hand": {"friction": mu}, "payload": {"mass_kg": b.mass_kg, "com_offset_m": b.com_height_m},
            "actuator": {"reference": reference}}


def cell(mu: float, water_kg: float, reference: str) -> dict:
    sc = load_scenario("crane-tray", overrides=bottle_overrides(mu, water_kg, reference))
    base = plan_with("toppra", sc)
    row = {"friction": mu, "water_kg": water_kg, "reference": reference, "com_height_m": sc.payload.com_offset_m,
           "planned_s": float(base.motion_time_s), "plan_feasible": bool(base.feasible)}
    t0 = time.perf_counter()
    try:
        plan = plan_fastest_carried(sc, "toppra", base_plan=base, s_max=S_MAX, rel_tol=REL_TOL)
    except QmtInputError as exc:  # lost even S_MAX slower
        row.update(carried_s=None, time_scale=None, note=str(exc))
    else:
        s = plan.extra["carried_search"]
        last = [p for p in s["points"] if p["time_scale"] == s["chosen"]][-1]
        row.update(carried_s=float(plan.motion_time_s), time_scale=float(s["chosen"]),
                   lost_below=s.get("lost_below"), max_slip_m=last.get("max_slip_m"),
                   max_tilt_rad=last.get("max_tilt_rad"), tries=len(s["points"]))
    row["search_wall_s"] = time.perf_counter() - t0
    return row


def executed(row: dict) -> dict:
    """The row with `executed`: {"x1": ..., "carried": ...} (execute_and_measure at x1.0 and at the
    fastest carried scale; the latter absent when none carried)."""
    sc = load_scenario("crane-tray", overrides=bottle_overrides(row["friction"], row["water_kg"], row["reference"]))
    base = plan_with("toppra", sc)
    out = {"x1": execute_and_measure(sc, base, 1.0)}
    if row.get("time_scale") is not None:
        out["carried"] = execute_and_measure(sc, base, row["time_scale"])
    return {**row, "executed": out}


def _ratio(v) -> str:
    # unbounded (JSON null): the motion would need the tray to pull the bottle down (lift ratio > 1)
    return "∞" if v is None or not math.isfinite(v) else f"{v:.2f}"


def _ratios(e: dict | None) -> str:
    if e is None:
        return "—"
    p, x = e["planned_peak_ratio"], e["executed_peak_ratio"]
    return " / ".join(f"{_ratio(p[k])} → {_ratio(x[k])}" for k in ("tray_slide", "tray_tip"))


def _errors(e: dict | None) -> str:
    return "—" if e is None else f"{e['tracking_error_rms_rad'] * 1e3:.1f} / {e['tracking_error_max_rad'] * 1e3:.1f}"


def markdown(rows: list[dict]) -> str:
    lines = ["| friction | water [g] | reference | planned (bound) [s] | fastest carried [s] | carried / bound | "
             "x1.0: slide / tip ratio, planned → executed | x1.0: error RMS / max [mrad] | "
             "fastest carried: slide / tip ratio, planned → executed | fastest carried: error RMS / max [mrad] |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        c = f"lost at x{S_MAX:g}" if r["carried_s"] is None else f"{r['carried_s']:.3f}"
        k = "—" if r["carried_s"] is None else f"{r['carried_s'] / r['planned_s']:.3f}"
        e = r.get("executed", {})
        lines.append(f"| {r['friction']:g} | {r['water_kg'] * 1e3:.0f} | {r['reference']} | {r['planned_s']:.3f} | "
                     f"{c} | {k} | {_ratios(e.get('x1'))} | {_errors(e.get('x1'))} | {_ratios(e.get('carried'))} | "
                     f"{_errors(e.get('carried'))} |")
    note = ("\nRatios: the planner's tray limit terms (friction and ring radius x the plan margin 0.8: 1.25 is the "
            "friction cone, 1.0 the planned limit) on the plan replayed at that scale (planned) and on the "
            "co-simulated joint motion, accelerations over 10 ms (executed); error: logged joint positions minus "
            "the plan's over the move and the tail (tray/executed.py); ∞: the executed motion would need the tray to pull "
            "the bottle down (lift ratio > 1; a rocking bottle's feet jolting the arm).\n")
    return "\n".join(lines) + "\n" + note


def figure(rows: list[dict], path: Path) -> None:
    fig, axes = plt.subplots(1, len(WATER_KG), figsize=(3.2 * len(WATER_KG), 3.4), sharey=True)
    for ax, w in zip(axes, WATER_KG):
        for ref, style in zip(REFERENCES, ("C0-o", "C3-s")):
            rs = sorted((r for r in rows if r["water_kg"] == w and r["reference"] == ref), key=lambda r: r["friction"])
            ax.plot([r["friction"] for r in rs], [r["carried_s"] or float("nan") for r in rs], style,
                    label=f"fastest carried, {ref} goals")
        rs = sorted((r for r in rows if r["water_kg"] == w and r["reference"] == "shaped"), key=lambda r: r["friction"])
        ax.plot([r["friction"] for r in rs], [r["planned_s"] for r in rs], "k--", label="TOPP-RA bound (planned)")
        ax.set_title(f"{w * 1e3:.0f} g water", fontsize=9)
        ax.set_xlabel("bottle-tray friction coefficient [-]")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("transfer time [s]")
    axes[0].legend(fontsize=7)
    fig.suptitle("CRANE-X7 tray: fastest carried TOPP-RA transfer through the Dynamixel servos", fontsize=10)
    fig.tight_layout()
    with atomic_output(path, suffix=".tmp.png") as tmp:  # unpredictable temporary name
        fig.savefig(path if tmp is None else tmp, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--quick", action="store_true", help="friction 0.3 and 30 g only")
    args = ap.parse_args(argv)
    check_output_dir(args.out, "--out")
    out = Path(args.out) / "tray_carried"
    out.mkdir(parents=True, exist_ok=True)
    jpath = out / "tray_carried.json"
    done = {}
    if jpath.is_file():
        for r in json.loads(jpath.read_text()).get("rows", []):
            done[(r["friction"], r["water_kg"], r["reference"])] = r
    mus, waters = ((0.3,), (0.030,)) if args.quick else (FRICTIONS, WATER_KG)
    # plain goals (the comparison) for the seed's 30 g bottle only: each of its tries is 2x longer
    keys = [(m, w, ref) for w in waters for m in mus for ref in REFERENCES if ref == "shaped" or w == waters[0]]
    rows = []
    for i, k in enumerate(keys):
        r = done.get(k) or cell(*k)
        if "executed" not in r:
            r = executed(r)
        rows.append(r)
        print(f"[{i + 1}/{len(keys)}] mu {k[0]:g}, {k[1] * 1e3:.0f} g, {k[2]}: planned {r['planned_s']:.3f} s, "
              f"carried {'-' if r['carried_s'] is None else format(r['carried_s'], '.3f')} s", flush=True)
        all_rows = list({(x["friction"], x["water_kg"], x["reference"]): x for x in [*done.values(), *rows]}.values())
        write_text_atomic(jpath, json.dumps(jsonable({"s_max": S_MAX, "rel_tol": REL_TOL, "rows": all_rows}),
                                            indent=1) + "\n")
    write_text_atomic(out / "tray_carried.md", markdown(rows))
    print(markdown(rows))
    if not args.quick:
        figure(rows, out / "tray_carried.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
