"""Figures of a sweep: success probability per group with its Wilson interval, and each uncertain
parameter against the largest slip of every case (carried green, lost red, the 1 mm 'held' line)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from qmt_drake.outputs import atomic_output

HELD_SLIP_LIMIT_M = 1e-3  # sim.HELD_SLIP_LIMIT_M (not imported: figures need no Drake)


def write_figures(spec, root: Path, results: list[dict], rows: list[dict]) -> dict:
    # lazy: plots only; start-up time, headless runs never load it (Agg chosen before pyplot loads)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    paths = {}
    grid = list(spec.grid)

    fig, ax = plt.subplots(figsize=(max(5.0, 1.3 * len(rows) + 2), 3.8))
    names = [textwrap.fill(r["label"], 16) + "".join(f"\n{g}={r[g]:g}" for g in grid) for r in rows]
    x = np.arange(len(rows))
    p = np.array([r["p"] for r in rows])
    err = np.array([[r["p"] - r["ci_low"] for r in rows], [r["ci_high"] - r["p"] for r in rows]])
    ax.bar(x, p, color="#4c72b0", alpha=0.8)
    ax.errorbar(x, p, yerr=err, fmt="none", ecolor="k", capsize=4)
    for xi, r in zip(x, rows):
        ax.text(xi, min(r["ci_high"] + 0.03, 1.05), f"{r['carried']}/{r['n']}", ha="center", fontsize=8)
    ax.set_xticks(x, names, fontsize=8)
    ax.set_ylim(0, 1.12)
    ax.set_ylabel("P(carried)")
    ax.set_title(f"{spec.name}: success probability, {int(round(rows[0]['confidence'] * 100))}% Wilson "
                 "interval", fontsize=9)
    fig.tight_layout()
    paths["success_png"] = _save(fig, root / "success_probability.png")
    plt.close(fig)

    params = list(spec.distributions) + [g for g in grid if g not in spec.distributions]
    labels = sorted({r["label"] for r in results})
    if params:
        ncol = min(len(params), 4)
        fig, axes = plt.subplots(len(labels), ncol, figsize=(3.3 * ncol, 2.6 * len(labels)), squeeze=False)
        for i, lab in enumerate(labels):
            rs = [r for r in results if r["label"] == lab]
            for j, pname in enumerate(params[:ncol]):
                ax = axes[i, j]
                v = np.array([r["parameters"].get(pname, np.nan) for r in rs], float)
                slip = np.array([np.nan if r.get("max_slip_m") is None else r["max_slip_m"] for r in rs], float)
                slip = np.where(np.isfinite(slip), np.maximum(slip, 1e-6), 1.0)  # failed runs drawn at 1 m
                held = np.array([bool(r.get("held")) for r in rs])
                ax.scatter(v[held], slip[held] * 1e3, s=10, c="tab:green", label="carried")
                ax.scatter(v[~held], slip[~held] * 1e3, s=10, c="tab:red", marker="x", label="lost")
                ax.axhline(HELD_SLIP_LIMIT_M * 1e3, color="k", lw=0.8, ls="--")
                ax.set_yscale("log")
                ax.set_xlabel(pname, fontsize=8)
                if j == 0:
                    ax.set_ylabel(f"{lab}\nmax slip [mm]", fontsize=8)
                ax.tick_params(labelsize=7)
        axes[0, 0].legend(fontsize=7)
        fig.suptitle(f"{spec.name}: largest slip per case against each parameter (dashed: 1 mm)", fontsize=9)
        fig.tight_layout()
        paths["parameters_png"] = _save(fig, root / "slip_vs_parameters.png")
        plt.close(fig)
    return paths


def _save(fig, path: Path) -> str:
    """savefig to a temporary name, then rename (atomic, like write_text_atomic)."""
    with atomic_output(path, suffix=".tmp.png") as tmp:  # unpredictable temporary name
        fig.savefig(path if tmp is None else tmp, dpi=110)  # None: a device node, written through
    return str(path)
