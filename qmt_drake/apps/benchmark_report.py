"""The benchmark's report: the Markdown table (benchmark.md) of the rows apps/benchmark.py measured,
and its figures (tip acceleration against the limit per planner group, motion times per scenario).
Reads the rows and plans; computes nothing a row does not already say, except the tip acceleration
curves it draws."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from qmt_drake.apps.bang_bang import bang_bang_acceleration_m_s2, closed_form_bound_s
from qmt_drake.hands import hand_plugin
from qmt_drake.plan import Plan

CARRIED_LABEL = "fastest carried"  # the label of the fastest carried row (the figures single it out)


def _series(scenario, plan: Plan, rate_hz: float = 1000.0):
    T = plan.motion_time_s
    if T <= 0:
        return None
    t = np.linspace(0.0, T, int(np.ceil(T * rate_hz)) + 1)
    q, qd, qdd = plan.sample(t)
    a = np.linalg.norm(scenario.arm.tip_acceleration(q, qd, qdd), axis=1)
    return t, a


def _fmt(v, spec=".4f"):
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    return format(v, spec)


def _convergence_text(rows: list[dict]) -> str:
    """One clause per plant step tried by plan_fastest_carried_converged."""
    out = []
    for c in rows:
        t = (f"{c['time_step_s'] * 1e3:g} ms: {c['motion_time_s']:.4f} s, at {c['check_step_s'] * 1e3:g} ms "
             f"{'carried' if c['chosen_at_check_step']['held'] else 'lost'}")
        if c.get("lost_neighbour_at_check_step") is not None:
            t += (f", the faster lost neighbour ({c['lost_neighbour_motion_time_s']:.4f} s) "
                  f"{'carried' if c['lost_neighbour_at_check_step']['held'] else 'lost'}")
        out.append(t)
    return "; ".join(out)


def benchmark_markdown(result: dict) -> str:
    lines = ["# Benchmark: GA vs TOPP-RA, Ruckig and trajectory optimization", "",
             "Every number is from the plan's 10 kHz re-check with the shared limit code and from "
             "the co-simulation (held = never detached and slip < 1 mm), not from the planner. "
             "Ratios are peak/limit. 'raw' is the re-check of the planner's own output "
             "(moment / motor ratios) before the exact slow-down: 'over by x' is its worst ratio "
             "minus 1 (x below 1e-12 is rounding). Jerk: peak tip jerk by finite differences "
             "of the tip acceleration at 10 kHz; 'jump' marks an acceleration discontinuity.", ""]
    for name, e in result["scenarios"].items():
        lines += [f"## {name}", ""]
        A = e.get("A_m_s2")
        if A is not None:
            lines.append(f"A = moment limit / (m_o r_G) = {A:.5f} m/s^2.")
        if e.get("closed_form_bound_s"):
            lines.append(f"No path can beat 2*sqrt(L/A) = {e['closed_form_bound_s']:.5f} s "
                         "(tip as a double integrator with |a| <= A).")
        lines += ["", "| method | feasible | motion time [s] | / fastest | moment ratio | "
                  "motor ratio | raw moment / motor | peak jerk [m/s^3] | planning wall [s] | held | "
                  "max slip [mm] |", "|" + "---|" * 11]
        for r in e.get("rows", []):
            raw = "—"
            if r.get("raw_peak_moment_ratio") is not None:
                rm, rt = r["raw_peak_moment_ratio"], r["raw_peak_motor_torque_ratio"]
                over = max(rm, rt) - 1.0
                raw = f"**over by {over:.2g}** ({rm:.4f} / {rt:.4f})" if over > 0 else "within"
            jerk = _fmt(r.get("peak_tip_jerk_m_s3"), ".3g")
            if r.get("acceleration_jumps"):
                jerk = f"jump ({jerk})"
            slip = r.get("max_slip_m")
            wall = _fmt(r["planner_wall_s"], ".3f")
            solve = (r.get("extra") or {}).get("toppra_solve_wall_s")
            if solve:
                wall += f" (solve {solve * 1e3:.0f} ms)"
            lines.append(
                f"| {r['label']} | {_fmt(r['feasible'])} | "
                f"{_fmt(r['motion_time_s']) if r['motion_time_s'] > 0 else '—'} | "
                f"{_fmt(r.get('ratio_to_fastest'), '.3f')} | {_fmt(r['peak_moment_ratio'])} | "
                f"{_fmt(r['peak_motor_torque_ratio'])} | {raw} | {jerk} | "
                f"{wall} | {_fmt(r.get('held'))} | "
                f"{_fmt(None if slip is None else slip * 1e3, '.3f')} |")
        notes = [f"- {r['label']}: {r['infeasible']}" for r in e.get("rows", []) if r.get("infeasible")]
        notes += [f"- {r['label']}: co-simulation: {r['cosim_note']}" for r in e.get("rows", [])
                  if r.get("cosim_note") and r["cosim_note"] != "co-simulation not run"]
        notes += [f"- {r['label']}: co-simulation: the payload detached at {r['detached_at_s']:.3f} s"
                  for r in e.get("rows", []) if r.get("detached_at_s") is not None]
        notes += [f"- {x['label']}: raised {x['error']}" for x in e.get("errors", [])]
        if notes:
            lines += ["", *notes]
        fc = e.get("fastest_carried")
        if fc:
            vs = (f"{fc['excess_over_bang_bang'] * 100:+.2f}% over the bang-bang bound {fc['bang_bang_s']:.4f} s"
                  if fc.get("bang_bang_s") else "no closed-form bound (via points)")
            lines += ["", f"**Fastest carried**: {fc['motion_time_s']:.4f} s, {vs}; carried in the nominal "
                      f"co-simulation with feedforward '{fc['feedforward']}' at a {fc['cosim_time_step_s'] * 1e3:g} ms "
                      f"step ({fc['search_variable']} = {fc['search_chosen']:.4g}); the verdict is "
                      f"{'converged' if fc['step_converged'] else 'NOT converged'} in the step "
                      f"({_convergence_text(fc.get('step_convergence') or [])}). Search added "
                      f"{fc['carried_wall_s']:.1f} s of wall time."]
        if e.get("ratios"):
            lines += [""] + [f"- {k}: {v:.4g}" for k, v in e["ratios"].items()]
        lines.append("")
    return "\n".join(lines)


def _planner_groups(shown: list) -> list[tuple[str, list]]:
    """The benchmark's rows in planner groups, in the table's order: (group title, [(label, plan)])."""
    def group_of(label: str) -> str:
        if label.startswith(("TOPP-RA", "Drake Toppra")):
            return "TOPP-RA variants"
        if label.startswith("Ruckig"):
            return "Ruckig variants"
        if label.startswith(("trajopt", CARRIED_LABEL)):
            return "trajopt and the fastest carried plan"
        return "thesis family (reported, GA, optimum)"
    groups: dict[str, list] = {}
    for label, plan in shown:
        groups.setdefault(group_of(label), []).append((label, plan))
    return list(groups.items())


def write_figures(plans_by_scenario: dict, out: Path, carried_by_scenario: dict | None = None) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    for name, plans in plans_by_scenario.items():
        if not plans:
            continue
        sc = plans[0][1].scenario
        A = bang_bang_acceleration_m_s2(sc)
        hand = hand_plugin(sc)  # how its payload limit reads: the caption, the titles' ratio, a moment axis
        peak_of, limit_text = hand.figure_peak_ratio, hand.limit_caption(sc, A)
        X = sc.moment_per_accel_kgm
        shown = [(lb, p) for lb, p in plans if p.motion_time_s > 0]
        # the time axis of the feasible plans (an infeasible one may rest at the family's slowest)
        T_all = max([p.motion_time_s for _, p in shown if p.feasible] or [p.motion_time_s for _, p in shown])
        # one readable figure per planner group (at most 6 panels, 2 columns) instead of one mosaic
        for group, members in _planner_groups(shown):
            cols = 2 if len(members) > 1 else 1
            rows = int(np.ceil(len(members) / cols))
            fig, axes = plt.subplots(rows, cols, figsize=(6.2 * cols, 2.9 * rows + 1.1), sharex=True,
                                     sharey=True, squeeze=False)
            for ax, (label, plan) in zip(axes.ravel(), members):
                t, a = _series(sc, plan)
                color = "tab:blue" if plan.feasible else "tab:red"
                ax.plot(t, a, color=color, lw=1.2, label="|a_tip| of the plan")
                ax.axhline(A, color="k", lw=1.0, ls="--", label="limit A")
                ax.set_title(f"{label}: {plan.motion_time_s:.3f} s, peak ratio {peak_of(plan):.4f}", fontsize=10)
                ax.set_xlim(0, T_all * 1.02)
                ax.set_ylim(0, 1.2 * A)
                ax.grid(alpha=0.3)
                ax.tick_params(labelsize=9)
                if hand.moment_axis:
                    sec = ax.secondary_yaxis("right", functions=(lambda v: v * X * 1e3,
                                                                 lambda m: m / (X * 1e3)))
                    sec.tick_params(labelsize=9)
                    sec.set_ylabel("payload moment [mN·m]", fontsize=9)
                ax.set_ylabel("|a_tip| [m/s²]", fontsize=9)
                ax.set_xlabel("time [s]", fontsize=9)
            axes.ravel()[0].legend(fontsize=8, loc="upper right")
            for ax in axes.ravel()[len(members):]:
                ax.set_visible(False)
            fig.suptitle(f"{name}, {group}: tip acceleration over time; dashed: {limit_text}; red: breaks a "
                         "limit on the re-check", fontsize=10, wrap=True)
            fig.tight_layout()
            path = out / f"benchmark_{name}_moment_{group.split()[0].lower().replace('-', '')}.png"
            fig.savefig(path, dpi=110)
            plt.close(fig)
            files.append(str(path))

    fig, axes = plt.subplots(len(plans_by_scenario), 1,
                             figsize=(11, 3.6 * len(plans_by_scenario)), squeeze=False)
    for ax, (name, plans) in zip(axes[:, 0], plans_by_scenario.items()):
        labels = [lb for lb, _ in plans]
        times = [p.motion_time_s for _, p in plans]
        colors = ["tab:green" if p.feasible else "tab:red" for _, p in plans]
        y = np.arange(len(plans))
        carried = (carried_by_scenario or {}).get(name) or [None] * len(plans)
        bars = ax.barh(y, times, color=colors)
        for bar, c in zip(bars, carried):
            if c is False:  # hatched: the payload was not carried (lost, or slip >= 1 mm)
                bar.set_hatch("///")
                bar.set_edgecolor("black")
        for yi, (tt, (_, p), c) in enumerate(zip(times, plans, carried)):
            notes = ([] if p.feasible else ["breaks a limit"]) + (["not carried in co-simulation"] if c is False else [])
            ax.text(tt, yi, f" {tt:.3f}" + (f" ({'; '.join(notes)})" if notes else ""), va="center", fontsize=7)
        bound = closed_form_bound_s(plans[0][1].scenario) if plans else None
        if bound:
            ax.axvline(bound, color="k", ls="--", lw=1.0)
            ax.text(bound, -0.6, f" bang-bang bound {bound:.3f} s", fontsize=7, va="bottom")
        for yi, lb in enumerate(labels):
            if lb.startswith(CARRIED_LABEL):
                bars[yi].set_color("tab:blue")
        ax.set_yticks(y, labels, fontsize=7)
        ax.set_xlabel("motion time [s]")
        ax.set_ylabel("planner (a row of the benchmark table)")
        ax.set_title(f"{name}: motion time. Green: keeps every limit on the 10 kHz re-check; blue: fastest "
                     "carried;\nhatched: payload not carried in the co-simulation (thesis PID; the blue row: "
                     "its own search, full feedforward)", fontsize=9)
        ax.set_xlim(0, max(times) * 1.45 if times else 1)
        ax.set_ylim(len(plans) - 0.5, -1.2)  # room above the first bar for the bound's label
        ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    path = out / "benchmark_times.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    files.append(str(path))
    return files


