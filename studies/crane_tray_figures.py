"""Seed 002 study (studies/crane_tray.py): its figures, from the results the study wrote (so
`--sections replot` redraws them from the JSON): the pair's joint responses and bottle, the friction
each phase needs, the friction and fill sweeps, the fastest carried transfers and their sweep."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.colors  # noqa: E402,F401
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402,F401
import numpy as np  # noqa: E402

from qmt_drake.tray.cosim import SEATING_S  # noqa: E402
from studies.crane_tray_runs import CASES, event_windows  # noqa: E402


def plot_req(req: dict, path: Path) -> None:
    combos = list(req)
    periods = sorted({float(k[len("period_"):-2]) * 1e-3 for k in req["P-only, linear"]} - {1e-3})
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    phases = list(event_windows({"move": (0, 1), "return": (2, 3)}))
    w = 0.2
    for k, name in enumerate(combos):
        axes[0].bar(np.arange(len(phases)) + (k - 1.5) * w, [req[name]["period_1ms"][p] for p in phases], w,
                    label=name)
    axes[0].set_xticks(range(len(phases)), phases, fontsize=7)
    axes[0].set_ylabel("required friction max |f_t|/f_n")
    axes[0].set_title("gains x spacing, servo period 1 ms", fontsize=9)
    axes[0].legend(fontsize=8)
    pl = [1e-3, *periods]
    for name, style, color in (("P-only, linear", "o", "C0"), ("PID, eased", "s", "C3")):
        for ev, ls in (("arrival", "-"), ("return start", "--")):
            axes[1].plot([p * 1e3 for p in pl], [req[name][f"period_{p * 1e3:g}ms"][ev] for p in pl], ls + style,
                         color=color, label=f"{name}: {ev}")
    axes[1].set_xlabel("servo control period [ms] (assumed 1 ms)")
    axes[1].set_ylabel("required friction")
    axes[1].set_title("the servo rate", fontsize=9)
    axes[1].legend(fontsize=8)
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.suptitle("Friction the bottle needs to stay put (sticking run, mu = 1)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_pair(results: dict, path_joints: Path, path_bottle: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), sharey=True)
    colors = ["tab:red", "tab:cyan", "tab:blue"]  # the seed's colours: joint 1 red, 2 light blue, 3 blue
    for ax, (case, r) in zip(axes, results.items()):
        t, q, goal = r.series["t"], r.series["arm_state"][:3], r.series["goal"]
        for k in range(3):
            ax.plot(t, q[k], color=colors[k], label=f"joint {k + 1}")
            ax.plot(t, goal[k], color=colors[k], ls=":", lw=1)
        for ph, (a, b) in r.phases.items():
            ax.axvspan(a, b, alpha=0.06 if ph in ("move", "return") else 0.0, color="k")
        ax.set_title(f"{case}: {CASES[case][2]}", fontsize=8)
        ax.set_xlabel("time [s] (dotted: goal stream)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("joint angle [rad]")
    axes[0].legend(fontsize=8)
    fig.suptitle("Joint responses (cf. seed 002 Fig. 9 / Fig. 10); shaded: move and return")
    fig.tight_layout()
    fig.savefig(path_joints, dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(5, 1, figsize=(10, 11), sharex=True)
    for case, r in results.items():
        t, s = r.series["t"], r.series
        m = t >= SEATING_S
        slide = np.hypot(s["slide"][0], s["slide"][1])
        f = s["contact_force"]
        axes[0].plot(t[m], np.degrees(np.sum(s["arm_state"][:3], axis=0))[m], label=case)
        axes[1].plot(t[m], 1e3 * slide[m], label=case)
        axes[2].plot(t[m], np.degrees(s["tilt"][0][m]), label=case)
        axes[3].plot(t[m], f[2][m], label=case)
        axes[4].plot(t[m], np.hypot(f[0], f[1])[m] / np.maximum(f[2][m], 1e-9), label=case)
    axes[0].set_ylabel("tray angle [deg]\n(theta1+theta2+theta3)")
    axes[1].axhline(1.0, color="k", ls="--", lw=0.8, label="slip threshold 1 mm")
    axes[1].set_ylabel("slide on tray [mm]")
    axes[2].set_ylabel("bottle tilt\non tray [deg]")
    axes[3].set_ylabel("normal force [N]")
    axes[4].axhline(results["before"].friction, color="k", ls="--", lw=0.8, label="mu")
    axes[4].set_ylabel("|f_t| / f_n")
    axes[4].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"Bottle on the tray, mu = {results['before'].friction}")
    fig.tight_layout()
    fig.savefig(path_bottle, dpi=110)
    plt.close(fig)


def plot_friction_sweep(mus, sweep: dict, path: Path) -> None:
    """Slip (and creep) path on the tray over friction, both seed runs; crosses where the bottle was lost."""
    fig, ax = plt.subplots(figsize=(9, 5))
    for c in CASES:
        ax.semilogy(mus, [1e3 * max(d["slip_m"], 1e-4) for d in sweep[c]], "-o", label=f"{c}: {CASES[c][2]}")
        ax.semilogy(mus, [1e3 * max(d["creep_m"], 1e-4) for d in sweep[c]], ":", color=ax.lines[-1].get_color(),
                    label=f"{c}: creep (slower than 3 mm/s)")
        lost = [(m, d) for m, d in zip(mus, sweep[c]) if d["outcome"] != "on_tray"]
        if lost:
            ax.semilogy([m for m, _ in lost], [1e3 * max(d["slip_m"], 1e-4) for _, d in lost], "x", ms=12, mew=2,
                        color=ax.lines[-2].get_color(), label=f"{c}: lost (" + ", ".join(
                            f"{m:g}: {d['outcome']} at {d['lost_at_s']:.1f} s" for m, d in lost) + ")")
    ax.axhline(1.0, color="k", ls="--", lw=0.8, label="slip threshold 1 mm")
    ax.set_xlabel("friction coefficient mu (bottle on tray)")
    ax.set_ylabel("slip path on the tray until lost [mm]")
    ax.set_title("seed motion: move 1-6 s, hold 6-11 s, return 11-16 s", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_fill_sweep(coms, fill: dict, path: Path) -> None:
    """Max bottle tilt over its centre-of-mass height (fill), both seed runs, at mu = 1."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for c in CASES:
        ax.plot(coms, [np.degrees(d["max_tilt_rad"]) for d in fill[c]], "-o", label=c)
        for h, d in zip(coms, fill[c]):
            if d["outcome"] != "on_tray":
                ax.annotate(d["outcome"], (h, np.degrees(d["max_tilt_rad"])), fontsize=7)
    ax.set_yscale("log")
    ax.set_xlabel("bottle centre-of-mass height [m] (ring radius 0.029 m), mu = 1")
    ax.set_ylabel("max tilt [deg]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_qmt(q: dict, path: Path) -> None:
    names = {"toppra": "TOPP-RA (1000-waypoint line)", "ga": "GA (line family)", "ruckig": "Ruckig (jerk 5 m/s^3)",
             "seed_eased_5s": "seed: 5 s eased line"}
    fig, ax = plt.subplots(figsize=(8, 4))
    y = np.arange(len(names))
    for i, k in enumerate(names):
        m = q["methods"].get(k)
        if m is None:
            continue
        planned = m.get("plan", {}).get("duration_s", m.get("plan", {}).get("planned_duration_s"))
        done = m["executed"].get("duration_s")
        if planned is not None:
            ax.barh(i + 0.2, planned, 0.38, color="C0", label="planned (tray limits x0.8, re-checked)" if i == 0 else None)
            ax.text(planned, i + 0.2, f" {planned:.2f} s", va="center", fontsize=8)
        if done is not None:
            ax.barh(i - 0.2, done, 0.38, color="C2", label="fastest carried through the servos" if i == 0 else None)
            ax.text(done, i - 0.2, f" {done:.2f} s", va="center", fontsize=8)
    ax.set_yticks(y, list(names.values()), fontsize=8)
    ax.set_xlabel("start-to-goal time [s]")
    ax.set_xlim(0, 7.0)
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=8, loc="center right")
    ax.set_title(f"Fastest carried tray transfer, 0.36 m line, mu {q['friction']}, bottle COM "
                 f"{1e3 * q['com_height_m']:.0f} mm", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_sweep(sw: dict, path: Path) -> None:
    mus, waters = sw["mu"], sw["water_kg"]
    cells = {(c["water_kg"], c["mu"]): c for c in sw["cells"]}
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.4))
    ax = axes[0]
    img = np.array([[1.0 if cells[(w, m)]["nominal_plan"]["carried"] else 0.0 for m in mus] for w in waters])
    ax.imshow(img, cmap=matplotlib.colors.ListedColormap(["#f2a8a8", "#b5e3b0"]), vmin=0, vmax=1, aspect="auto",
              origin="lower")
    for i, w in enumerate(waters):
        for j, m in enumerate(mus):
            c = cells[(w, m)]["nominal_plan"]
            word = c["outcome"] if c["outcome"] != "on_tray" else ("carried" if c["carried"] else "slipped")
            ax.text(j, i, f"{word}\nslip {1e3 * c['slip_m']:.1f} mm", ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(mus)), [f"{m:g}" for m in mus])
    ax.set_yticks(range(len(waters)), [f"{1e3 * w:.0f} g water\nCOM {1e3 * cells[(w, mus[0])]['com_height_m']:.0f} mm"
                                       for w in waters], fontsize=8)
    ax.set_xlabel("friction coefficient mu")
    ax.set_title(f"nominal fastest carried transfer ({sw['nominal']['duration_s']:.2f} s, planned for mu 0.3, 30 g)\n"
                 "executed unchanged on each bottle", fontsize=9)
    ax = axes[1]
    for w in waters:
        d = [cells[(w, m)]["fastest"]["duration_s"] or np.nan for m in mus]
        p = [cells[(w, m)]["toppra_plan_s"] or np.nan for m in mus]
        tip = [m for m in mus if cells[(w, m)]["binding"] == "tip"]
        line, = ax.plot(mus, d, "-o", label=f"{1e3 * w:.0f} g water (COM {1e3 * cells[(w, mus[0])]['com_height_m']:.0f} mm)"
                        + (f", tip binds at mu {', '.join(f'{m:g}' for m in tip)}" if tip else ""))
        ax.plot(mus, p, ":", color=line.get_color())
    ax.plot([], [], "k-o", label="fastest carried through the servos (time scale searched)")
    ax.plot([], [], "k:", label="TOPP-RA plan (tray limits x0.8)")
    ax.axhline(5.0, color="k", ls="--", lw=0.8, label="seed: 5 s eased line")
    ax.set_xlabel("friction coefficient mu")
    ax.set_ylabel("start-to-goal time [s]")
    ax.set_yscale("log")
    ax.set_ylim(0.5, 12)
    ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.set_yticks([0.5, 1, 2, 3, 5, 10])
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="upper right")
    ax.set_title("fastest carried TOPP-RA transfer planned for each bottle", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
