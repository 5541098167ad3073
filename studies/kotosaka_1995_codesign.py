"""Seed 003 study (studies/kotosaka_1995.py --codesign), item 7: the co-design of the ch.4 two-link
arm. Its lengths (grid, then 10 mm around the best) and then lengths + base position (compass search)
minimising the family-optimum QMT time under thesis-ch4's limits; the thesis arm and both winners
re-planned from their written scenarios and carried in the co-simulation; codesign.json and .png."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
import yaml

from qmt_drake.design.codesign import LAYOUT_LOWER_M, LAYOUT_UPPER_M, ROOT, grid_search, pattern_search
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.planners import plan_with
from qmt_drake.sim import simulate_transfer
from qmt_drake.transfer_scenario import load_scenario


def codesign(out_dir: Path, log, max_layout_evaluations: int = 60) -> None:
    """Item 7: lengths (grid) and then lengths + base position (compass search from the grid's
    best) of the ch.4 two-link arm minimising the family-optimum QMT time under thesis-ch4's moment
    and motor limits; the thesis arm and both winners re-planned and carried in the co-simulation."""
    t_start = time.perf_counter()
    folder = out_dir / "codesign"
    l1s = np.round(np.arange(0.12, 0.201, 0.02), 3)
    l2s = np.round(np.arange(0.08, 0.161, 0.02), 3)
    rows = grid_search(l1s, l2s, folder, progress=log)
    best = min(rows, key=lambda r: r["motion_time_s"])
    # refine around the best at 10 mm
    fine = grid_search(np.round(best["l1_m"] + np.array([-0.01, 0.0, 0.01]), 3),
                       np.round(best["l2_m"] + np.array([-0.01, 0.0, 0.01]), 3), folder / "fine", progress=log)
    allr = rows + [r for r in fine if not (r["l1_m"] == best["l1_m"] and r["l2_m"] == best["l2_m"])]
    best = min(allr, key=lambda r: r["motion_time_s"])
    t_lengths = time.perf_counter() - t_start
    thesis = next(r for r in rows if abs(r["l1_m"] - 0.16) < 1e-9 and abs(r["l2_m"] - 0.12) < 1e-9)
    # joint layout: the base position joins the lengths; start from the lengths-only optimum
    t0 = time.perf_counter()
    lay = pattern_search([best["l1_m"], best["l2_m"], 0.0, 0.0], folder / "layout", step_m=0.02,
                         min_step_m=0.005, max_evaluations=max_layout_evaluations, progress=log)
    t_layout = time.perf_counter() - t0
    layout = lay["best"]
    log(f"codesign layout: l1 {layout['l1_m']:.3f} l2 {layout['l2_m']:.3f} base {layout['base_m']} m: "
        f"T0 {layout['motion_time_s']:.4f} s after {lay['evaluations']} plans ({t_layout:.0f} s)")
    sims = {}
    for tag, r in (("thesis_arm", thesis), ("codesigned_lengths", best), ("codesigned_layout", layout)):
        sc = load_scenario(r["scenario"])
        plan = plan_with("optimum", sc)     # re-planned from the written scenario: the re-check
        res = simulate_transfer(sc, plan, keep_series=False)
        sims[tag] = {"l1_m": r["l1_m"], "l2_m": r["l2_m"], "base_m": r.get("base_m", [0.0, 0.0]),
                     "motion_time_s": float(plan.motion_time_s),
                     "search_motion_time_s": float(r["motion_time_s"]),
                     "held": bool(res.held), "max_slip_m": float(res.max_slip_m),
                     "peak_motor_torque_ratio": float(res.peak_motor_torque_ratio),
                     "peak_moment_ratio_planned": float(res.peak_moment_ratio_planned)}
        log(f"codesign {tag}: T0 {plan.motion_time_s:.4f} s, co-simulation held={res.held}, "
            f"slip {res.max_slip_m * 1e3:.3f} mm, torque ratio {res.peak_motor_torque_ratio:.3f}, "
            f"planned moment ratio {res.peak_moment_ratio_planned:.4f}")
    out = {"grid": allr, "best": best, "thesis": thesis, "cosim": sims,
           "time_saved_s": thesis["motion_time_s"] - best["motion_time_s"],
           "layout": {"best": layout, "evaluations": lay["evaluations"], "steps": lay["steps"],
                      "rows": lay["rows"], "bounds_m": [LAYOUT_LOWER_M.tolist(), LAYOUT_UPPER_M.tolist()],
                      "wall_s": t_layout},
           "layout_time_saved_s": thesis["motion_time_s"] - layout["motion_time_s"],
           "wall_s": {"lengths_grid": t_lengths, "layout_search": t_layout,
                      "total": time.perf_counter() - t_start}}
    write_text_atomic(out_dir / "codesign.json", json.dumps(jsonable(out), indent=1) + "\n")
    import matplotlib.pyplot as plt
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    Z = np.array([[next(r["motion_time_s"] for r in rows if r["l1_m"] == l1 and r["l2_m"] == l2)
                   for l1 in l1s] for l2 in l2s])
    im = ax.pcolormesh(l1s, l2s, np.where(np.isfinite(Z), Z, np.nan), shading="nearest", cmap="viridis")
    fig.colorbar(im, ax=ax, label="family-optimum motion time T0 [s]")
    ax.plot(0.16, 0.12, "rs", label="thesis arm (Table 4.1)")
    ax.plot(best["l1_m"], best["l2_m"], "w*", ms=12, label="co-designed lengths")
    ax.set_xlabel("l1 [m]")
    ax.set_ylabel("l2 [m]")
    ax.legend(fontsize=8)
    ax.set_title("lengths, base at the thesis's (white: unreachable)", fontsize=9)
    # layout: the task points in the world, each arm's base and reach
    pts = np.array(yaml.safe_load((ROOT / "models" / "scenarios" / "thesis-ch4.yaml").read_text())
                   ["task"]["points_m"])
    ax2.plot(pts[:, 0], pts[:, 1], "ko", label="task points (start, vias, goal)")
    th = np.linspace(0, 2 * np.pi, 200)
    for tag, col, mk, ms in (("thesis_arm", "r", "s", 13), ("codesigned_lengths", "b", "o", 7),
                             ("codesigned_layout", "g", "D", 7)):
        sm = sims[tag]
        b = np.array(sm["base_m"])
        R = sm["l1_m"] + sm["l2_m"]
        ax2.plot(b[0] + R * np.cos(th), b[1] + R * np.sin(th), col + ":", lw=0.8)
        ax2.plot(*b, col + mk, ms=ms, mfc="none" if tag == "thesis_arm" else col,
                 label=f"{tag}: base ({b[0]:+.3f}, {b[1]:+.3f}), l1 {sm['l1_m']:.3f}, "
                       f"l2 {sm['l2_m']:.3f} m, T0 {sm['motion_time_s']:.3f} s")
    ax2.set_aspect("equal")
    ax2.set_xlim(-0.35, 0.35)
    ax2.set_ylim(-0.2, 0.35)
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    ax2.legend(fontsize=7, loc="lower center")
    ax2.set_title("joint layout: base (marker) and reach l1 + l2 (dotted)", fontsize=9)
    fig.tight_layout()
    fig.savefig(out_dir / "codesign.png", dpi=110)
    plt.close(fig)
    log(f"codesign done in {time.perf_counter() - t_start:.0f} s")
