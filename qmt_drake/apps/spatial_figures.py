"""Figures of the spatial benchmark (studies/spatial_benchmark.py), drawn from its saved JSON.

`plan_series(sc, traj, rate_hz)` is what the benchmark stores per plan: the hand's limit ratio (the
scenario's hand term: suction grip, magnet moment or tray contact, the largest of its rows) and the
largest ratio of every limit a time scaling changes (joint speed, acceleration, torque, hand), sampled
at the re-check rate with limits/spatial_columns.py (the re-check's own columns) and thinned to at most
MAX_POINTS per plan by keeping each bin's largest value (so a peak is never thinned away); with
obstacles and a clearance function, the smallest signed distance of the arm and its part from them.

`write_spatial_figures(res, folder)` writes, for one scenario's JSON:
  <scenario>-hand_ratio.png  the hand's ratio over time per method (1 = the limit),
  <scenario>-times.png       the methods' motion times side by side, the TOPP-RA bound marked, each bar
                             coloured by its co-simulation outcome,
  <scenario>-clearance.png   the clearance along each path (only when the JSON has it).

    python -m qmt_drake.apps.spatial_figures out/spatial/ur5-suction-bins.json [...]   # redraw
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from qmt_drake.limits.spatial_columns import TIMED_GROUPS_EXCLUDE, SpatialColumns
from qmt_drake.outputs import atomic_output
from qmt_drake.planners.spatial_trajectory import sample_times

MAX_POINTS = 500
MAIN_METHODS_MAX = 8  # the ratio figure shows the methods without a family suffix (plus the fast replay)


def thin_max(t_s, values, max_points: int = MAX_POINTS):
    """(t, v) with at most max_points: equal bins of samples, each its largest value at its time."""
    t_s, values = np.asarray(t_s, float), np.asarray(values, float)
    if values.size <= max_points:
        return t_s, values
    bins = np.array_split(np.arange(values.size), max_points)
    k = np.array([b[np.argmax(values[b])] for b in bins])
    return t_s[k], values[k]


def plan_series(sc, traj, rate_hz: float, clearance_fn=None, horizon_m: float | None = None) -> dict:
    """{'t_s', 'hand_ratio', 'max_timed_ratio'} (and 'clearance_t_s', 'clearance_m' with clearance_fn(q)
    -> signed distance m, whose distance query sees no farther than horizon_m) of traj sampled at
    rate_hz, each thinned to MAX_POINTS (module docstring)."""
    t = sample_times(traj.duration_s, rate_hz)
    cols = SpatialColumns(sc)
    q, qd, qdd = traj.sample(t)
    c = cols.columns(q, qd, qdd)
    hand = c[:, cols.slices[sc.hand_term().name]].max(axis=1)
    timed = np.concatenate([c[:, cols.slices[g]] for g, _ in cols.groups if g not in TIMED_GROUPS_EXCLUDE],
                           axis=1).max(axis=1)
    th, vh = thin_max(t, hand)
    tt, vt = thin_max(t, timed)
    out = {"t_s": th.tolist(), "hand_ratio": vh.tolist(), "timed_t_s": tt.tolist(), "max_timed_ratio": vt.tolist()}
    if clearance_fn is not None:
        k = np.unique(np.linspace(0, t.size - 1, min(t.size, MAX_POINTS)).round().astype(int))
        out["clearance_t_s"] = t[k].tolist()
        out["clearance_m"] = [float(clearance_fn(q[i])) for i in k]
        out["clearance_horizon_m"] = horizon_m
    return out


def _save(fig, path: Path) -> Path:
    with atomic_output(path, suffix=".tmp.png") as tmp:  # unpredictable temporary name
        fig.savefig(path if tmp is None else tmp, dpi=110)
    return path


def _outcome_colour(row: dict) -> str:
    c = row.get("cosim") or {}
    if not c.get("held"):
        return "#d62728"  # lost (or not carried)
    return "#2ca02c" if row.get("recheck_max_ratio", 0.0) <= 1.0 else "#ff7f0e"


def write_spatial_figures(res: dict, folder) -> list[Path]:
    """The scenario's figures (module docstring) into folder; the paths written."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder, name = Path(folder), res["scenario"]
    rows = res["rows"]
    files = []
    shown = [m for m, r in rows.items() if "series" in r and ("-" not in m or m == "toppra_x0.67")]
    shown = shown[:MAIN_METHODS_MAX]
    if shown:
        fig, ax = plt.subplots(figsize=(10, 4.4))
        for m in shown:
            s = rows[m]["series"]
            ax.plot(s["t_s"], s["hand_ratio"], label=f"{m} ({rows[m]['duration_s']:.3f} s)",
                    lw=1.4, ls="--" if m == "toppra_x0.67" else "-")
        ax.axhline(1.0, color="k", lw=1, ls=":", label="limit")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"hand ratio ({res['hand_kind']}) [-]")
        ax.set_title(f"{name}: the hand's limit ratio over each plan (1 = the part is about to go)")
        # A plan far over the limit (x0.67 on the tray: lift-off, ratio in the hundreds) would flatten the
        # others to a line at the bottom: the axis stops at 2 and the clipped peaks are named.
        peaks = {m: float(np.nanmax(np.array(rows[m]["series"]["hand_ratio"], dtype=float))) for m in shown}
        top = max(1.1, min(2.0, max(peaks.values()) * 1.05))
        ax.set_ylim(0.0, top)
        clipped = [f"{m} peaks at {v:.3g}" for m, v in peaks.items() if v > top]
        if clipped:
            ax.text(0.01, 0.98, "axis clipped at " + f"{top:g}: " + "; ".join(clipped), transform=ax.transAxes,
                    va="top", fontsize=8, bbox={"facecolor": "white", "alpha": 0.8, "lw": 0})
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the curves, not on them
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files.append(_save(fig, folder / f"{name}-hand_ratio.png"))
        plt.close(fig)
    timed = [(m, r) for m, r in rows.items() if np.isfinite(r.get("duration_s", np.nan))]
    if timed:
        timed.sort(key=lambda mr: mr[1]["duration_s"])
        fig, ax = plt.subplots(figsize=(10, 1.2 + 0.32 * len(timed)))
        y = np.arange(len(timed))
        ax.barh(y, [r["duration_s"] for _, r in timed], color=[_outcome_colour(r) for _, r in timed])
        for k, (_, r) in enumerate(timed):
            ax.text(r["duration_s"], k, f" {r['duration_s']:.3f}", va="center", fontsize=7)
        ax.axvline(res["bound_s"], color="k", ls="--", lw=1.2)
        ax.set_yticks(y, [m for m, _ in timed], fontsize=8)
        ax.invert_yaxis()
        ax.set_xlabel("motion time [s]")
        ax.set_title(f"{name}: motion time per method (dashed: TOPP-RA bound {res['bound_s']:.3f} s)", fontsize=10)
        handles = [plt.Rectangle((0, 0), 1, 1, color=c) for c in ("#2ca02c", "#ff7f0e", "#d62728")]
        ax.legend(handles, ["carried, re-check within limits", "carried, re-check over a limit", "part lost"],
                  fontsize=8, loc="lower left", bbox_to_anchor=(1.01, 0.0))
        ax.set_xlim(0, 1.15 * max(r["duration_s"] for _, r in timed))
        fig.tight_layout()
        files.append(_save(fig, folder / f"{name}-times.png"))
        plt.close(fig)
    cl = [m for m in shown if "clearance_m" in rows[m]["series"]]
    if cl:
        fig, ax = plt.subplots(figsize=(10, 4.4))
        for m in cl:
            s = rows[m]["series"]
            ax.plot(s["clearance_t_s"], 1e3 * np.asarray(s["clearance_m"]), label=m, lw=1.4)
        ax.axhline(0.0, color="k", lw=1, ls=":", label="contact")
        horizon = rows[cl[0]]["series"].get("clearance_horizon_m")
        if horizon:  # the distance query's reach: a flat top there means 'at least this far'
            ax.axhline(1e3 * horizon, color="0.5", lw=1, ls="--", label=f"query horizon ({1e3 * horizon:g} mm: at least)")
        ax.set_xlabel("time [s]")
        ax.set_ylabel("clearance of arm and part [mm]")
        ax.set_title(f"{name}: smallest distance to the obstacles along each plan (Drake signed distance)")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.grid(alpha=0.3)
        fig.tight_layout()
        files.append(_save(fig, folder / f"{name}-clearance.png"))
        plt.close(fig)
    return files


def main(argv=None) -> int:
    for p in (sys.argv[1:] if argv is None else argv):
        for f in write_spatial_figures(json.loads(Path(p).read_text()), Path(p).parent):
            print(f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
