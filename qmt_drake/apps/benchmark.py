"""Benchmark: the GA against TOPP-RA, Ruckig and Drake trajectory optimization under the same limits.

`run_benchmark` plans every scenario with every method and writes, into `out_dir`:
  benchmark.json  every row (the plan's re-check summary, planner facts, jerk, co-simulation);
  benchmark.md    one table per scenario and the GA / TOPP-RA ratios;
  benchmark_<scenario>_moment.png  tip acceleration |a_tip| and payload moment against the limit
                  over time, every method;
  benchmark_times.png  motion times per scenario and method (bar chart);
  fastest_carried_<scenario>.json  the fastest carried plan (studies/success_probability.py reuses it).

Rows per scenario: the thesis's reported genes, the GA (one row per seed), the family optimum,
TOPP-RA on the family path, the GA's path, the straight joint path and the straight Cartesian path,
TOPP-RA's spline output on the family path unslowed (to show its overshoot), Drake's Toppra,
Ruckig along the Cartesian line at each jerk limit and in joint space at the middle one, and the
free-path trajectory optimization, and the fastest plan CARRIED in the nominal co-simulation
(`fastest_carried`: Ruckig's jerk-limited line for a task without vias, otherwise the fastest
limit-keeping plan of the table time-scaled; the controller's full feedforward; the jerk limit
or time scale chosen by bisection on the co-simulation at the coarsest plant step whose verdict
is converged, see sweep.robust.plan_fastest_carried_converged), against the bang-bang bound.
Every number comes from the plan's 10 kHz re-check (`Plan.check`) and from the co-simulation,
never from the planner's own claim.

Peak jerk: the tip jerk |d a_tip / dt| by finite differences of the tip acceleration sampled at
10 kHz (m/s^3). Where the 50 kHz value exceeds the 10 kHz value three times over, the acceleration
jumps (TOPP-RA's constant-acceleration pieces, the thesis's trapezoids, a start or stop with
nonzero acceleration): the row says "jump" and keeps the 10 kHz number, which is then only the
jump divided by 0.1 ms.

Reference: for a task without via points, no path can be faster than 2*sqrt(L/A) (the tip is a
double integrator with |a| <= A, L the start-goal distance); the table states it.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from qmt_drake.apps.bang_bang import bang_bang_acceleration_m_s2, closed_form_bound_s
from qmt_drake.apps.benchmark_report import CARRIED_LABEL, benchmark_markdown, write_figures
from qmt_drake.carried_cells import carried_transfer_plan_every_cell
from qmt_drake.hands import hand_plugin, run_simulate
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.plan import Plan
from qmt_drake.plan_files import load_plan
from qmt_drake.planners import plan_with, registry
from qmt_drake.sweep.robust import plan_fastest_carried_converged
from qmt_drake.transfer_scenario import load_scenario

DEFAULT_JERK_LIMITS = (1.0, 10.0, 100.0)  # m/s^3


def tip_jerk_peak(scenario, plan: Plan) -> dict:
    """Peak tip jerk, m/s^3, by finite differences of the tip acceleration at 10 kHz; the
    acceleration "jumps" where the 50 kHz value exceeds it three times over."""
    out = {}
    T = plan.motion_time_s
    if T <= 0:
        return {"peak_tip_jerk_m_s3": None, "acceleration_jumps": None}
    for rate in (10000.0, 50000.0):
        t = np.linspace(0.0, T, max(int(np.ceil(T * rate)) + 1, 3))
        q, qd, qdd = plan.sample(t)
        a = scenario.arm.tip_acceleration(q, qd, qdd)
        out[rate] = float(np.max(np.linalg.norm(np.diff(a, axis=0), axis=1) / np.diff(t)))
    return {"peak_tip_jerk_m_s3": out[10000.0],
            "peak_tip_jerk_50kHz_m_s3": out[50000.0],
            "acceleration_jumps": bool(out[50000.0] > 3.0 * out[10000.0])}



def cosim_outcome(scenario, plan: Plan) -> dict:
    """Guarded co-simulation: held / max slip, or nulls and a note."""
    if plan.motion_time_s <= 0:
        return {"held": None, "max_slip_m": None, "cosim_note": "not simulated: no motion"}
    try:
        r = run_simulate(scenario, plan)  # a tray scenario: the bottle through the servos
    except Exception as exc:  # noqa: BLE001
        return {"held": None, "max_slip_m": None,
                "cosim_note": f"co-simulation failed: {type(exc).__name__}: {exc}"}
    return {"held": r.get("held"), "max_slip_m": r.get("max_slip_m"),
            "detached_at_s": r.get(hand_plugin(scenario).lost_at_key),  # the tray's: lost_at_s
            "max_tracking_error_rad": r.get("max_tracking_error_rad"),
            "cosim_sim_wall_s": r.get("sim_wall_s"), "cosim_note": None}


ROW_EXTRA_LEFT_OUT = ("raw_check", "ga_settings")  # and the GA's per-generation history_*: not a row's


def _row(scenario, label: str, plan: Plan, cosim: bool) -> dict:
    s = plan.summary()
    ex = plan.extra or {}
    raw = ex.get("raw_check") or {}
    row = {"label": label, "method": plan.method, "feasible": s["feasible"],
           "motion_time_s": s["motion_time_s"], "peak_moment_ratio": s["peak_moment_ratio"],
           "peak_motor_torque_ratio": s["peak_motor_torque_ratio"],
           "joint_range_ok": s["joint_range_ok"], "planner_wall_s": s["planner_wall_s"],
           "raw_peak_moment_ratio": raw.get("peak_moment_ratio"),
           "raw_peak_motor_torque_ratio": raw.get("peak_motor_torque_ratio"),
           "raw_motion_time_s": raw.get("motion_time_s"),
           "slowdown_factor": ex.get("slowdown_factor"), "genes": s["genes"],
           "infeasible": ex.get("infeasible"),
           "extra": {k: v for k, v in ex.items() if k not in ROW_EXTRA_LEFT_OUT and not k.startswith("history_")}}
    row.update(tip_jerk_peak(scenario, plan))
    row.update(cosim_outcome(scenario, plan) if cosim else
               {"held": None, "max_slip_m": None, "cosim_note": "co-simulation not run"})
    return row


CARRIED_STEPS_S = (2e-3, 1e-3, 0.5e-3)  # plant steps tried, coarsest first (converged verdict)


def fastest_carried(scenario, *, quick: bool = False, steps_s=CARRIED_STEPS_S, progress=None,
                    candidates=None, cells=None) -> tuple:
    """(Plan, row) of the fastest plan carried in the nominal co-simulation with the controller's
    full feedforward. Task without vias: Ruckig's jerk-limited Cartesian line, J by bisection on
    log J in [1, 300] m/s^3; with vias (Ruckig stops at every via): the time scale, by bisection,
    of the fastest limit-keeping plan among `candidates` ((label, Plan) pairs, e.g. the
    benchmark's rows), or of the TOPP-RA family path without them. The row's held / slip are the
    co-simulation at the step the search settled on (the plan's own verdict), with its
    feedforward; 'carried_wall_s' is what the search added to the benchmark. cells (None: not asked):
    'all' or (time_step_s, approximation) pairs at which the chosen plan must be carried too, the plan then
    raised until it is (carried_cells.carried_transfer_plan_every_cell, at the step the search settled
    on; the row's held / slip are then the default cell's at the raised plan, 'every_cell' its tables)."""
    t0 = time.perf_counter()
    bound = closed_form_bound_s(scenario)
    rel_tol = 0.01 if quick else 0.002
    if bound is not None:
        method, opts, what = "ruckig", {"jerk_range_m_s3": (1.0, 300.0)}, "Ruckig line"
    else:
        feas = [(lb, p) for lb, p in (candidates or []) if p.feasible and p.motion_time_s > 0]
        if feas:
            lb, base = min(feas, key=lambda lp: lp[1].motion_time_s)
            method, opts, what = base.method, {"base_plan": base}, f"{lb} time-scaled"
        else:
            method, opts, what = "toppra", {"path": "family"}, "TOPP-RA family time-scaled"
    plan = plan_fastest_carried_converged(scenario, method, steps_s=steps_s, rel_tol=rel_tol,
                                          progress=progress, **opts)
    s = plan.extra["carried_search"]
    if cells is not None:
        base = opts.get("base_plan")
        if base is None and s["variable"] == "time_scale":  # the family path plan_fastest_carried planned
            base = plan_with(method, scenario, seed=0, **opts)
        plan = carried_transfer_plan_every_cell(scenario, base, plan, cells, rel_tol=rel_tol,
                                                time_step_s=s["time_step_s"], progress=progress)
        s = plan.extra["carried_search"]
    at = _chosen_points(s) if cells is None else _default_cell_point(s["every_cell"])
    h = s["time_step_s"]
    label = f"{CARRIED_LABEL} ({what}, ff full, {h * 1e3:g} ms)"
    row = _row(scenario, label, plan, cosim=False)
    row.update({"held": bool(at[0]["held"]) if at else None,
                "max_slip_m": at[0]["max_slip_m"] if at else None,
                "detached_at_s": at[0]["detached_at_s"] if at else None, "cosim_note": None,
                "carried_search_method": method, "feedforward": s["feedforward"], "cosim_time_step_s": h,
                "search_variable": s["variable"], "search_chosen": s["chosen"],
                "search_points": len(s["points"]), "step_converged": s.get("converged"),
                "step_convergence": s.get("convergence"),
                **_half_step(s),
                "bang_bang_s": bound, "excess_over_bang_bang": (plan.motion_time_s / bound - 1.0) if bound else None,
                "carried_wall_s": time.perf_counter() - t0})
    return plan, row


def _half_step(search: dict) -> dict:
    """The chosen plan's verdict at half the step it was chosen at: the converged search's own
    re-run (plan_fastest_carried_converged's check step), no extra run; a flip is reported."""
    conv = (search.get("convergence") or [None])[-1]
    if conv is None:
        return {"verdict_at_half_step": None, "slip_at_half_step": None, "flips_at_half_step": None}
    r = conv["chosen_at_check_step"]
    return {"verdict_at_half_step": r.get("outcome", "carried" if r["held"] else "lost"),
            "slip_at_half_step": r.get("max_slip_m"),
            "flips_at_half_step": not r["held"], "half_step_s": conv["check_step_s"]}


def _default_cell_point(every: dict) -> list[dict]:
    """The every-cell answer's default-cell run as a carried point (none if that cell was not asked)."""
    c = every["table"].get(every["default_cell"])
    return [] if c is None else [{"held": c["held"], "max_slip_m": c["slip_m"], "detached_at_s": None}]


def _chosen_points(search: dict) -> list[dict]:
    """The co-simulated points of a carried search at its chosen value that were carried."""
    return [p for p in search["points"] if p[search["variable"]] == search["chosen"] and p["held"]]


def reusable_fastest_carried(path, scenario):
    """(Plan, row-like dict) of a fastest-carried plan the benchmark wrote (`fastest_carried_<name>.json`)
    if it was searched as `fastest_carried` searches now (steps, feedforward), else None."""
    if not Path(path).is_file():
        return None
    plan = load_plan(path, scenario)
    s = (plan.extra or {}).get("carried_search") or {}
    steps = [c["time_step_s"] for c in s.get("convergence", [])]
    if s.get("feedforward") != "full" or not steps or steps != list(CARRIED_STEPS_S[:len(steps)]):
        return None
    at = _chosen_points(s)
    return plan, {"held": bool(at[0]["held"]) if at else None, "max_slip_m": at[0]["max_slip_m"] if at else None}


def run_benchmark(scenarios=("thesis-ch2", "thesis-ch3", "thesis-ch4"), out_dir="out",
                  jerk_limits=DEFAULT_JERK_LIMITS, progress: Callable[[str], None] | None = print,
                  ga_seeds=(0,), quick: bool = False, cosim: bool = True,
                  ga_max_generations: int | None = None, ga_stall_generations: int | None = None,
                  figures: bool = True, carried: bool = True) -> dict:
    """Plan every scenario with every method, write benchmark.json/.md and figures; return the
    JSON dict. quick=True: a 30-generation GA, a smaller trajopt (10 control points, 40 samples),
    one jerk limit, a 1% bracket for the fastest carried plan. cosim=False skips the
    co-simulation (rows then say so) and the fastest-carried search; carried=False skips only the
    search."""

    say = progress or (lambda _m: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    gmax = ga_max_generations or (30 if quick else 1000)
    gstall = ga_stall_generations or (30 if quick else 200)
    jerks = tuple(jerk_limits[-1:]) if quick else tuple(jerk_limits)
    trajopt_kw = {"num_control_points": 10, "constraint_samples": 40} if quick else {}
    result = {"settings": {"ga_seeds": list(ga_seeds), "ga_max_generations": gmax,
                           "ga_stall_generations": gstall, "jerk_limits_m_s3": list(jerks),
                           "quick": quick, "cosim": cosim, "fastest_carried": bool(cosim and carried),
                           "check": "every row re-checked at the scenario's check rate (10 kHz)",
                           "peak_jerk": "tip jerk, finite differences of the tip acceleration "
                                        "at 10 kHz (m/s^3); 'jump' where it is discontinuous"},
              "scenarios": {}}
    plans_by_scenario = {}
    carried_by_scenario = {}  # per plan: True/False from the co-simulation, None if not simulated
    for name in scenarios:
        sc = load_scenario(name)
        plans: list[tuple[str, Plan]] = []

        def add(label, fn):
            t0 = time.perf_counter()
            try:
                plan = fn()
            except Exception as exc:  # noqa: BLE001 - one method's failure is a row, not a crash
                say(f"{name}: {label} raised {type(exc).__name__}: {exc}")
                result["scenarios"].setdefault(name, {}).setdefault("errors", []).append(
                    {"label": label, "error": f"{type(exc).__name__}: {exc}"})
                return None
            say(f"{name}: {label}: {plan.motion_time_s:.4f} s, feasible {plan.feasible} "
                f"({time.perf_counter() - t0:.2f} s)")
            plans.append((label, plan))
            return plan

        # every row through the one planner registry (planners/registry.py)
        add("thesis reported", lambda: registry.plan(sc, "thesis"))
        ga_plans = []
        for seed in ga_seeds:
            p = add(f"GA (seed {seed})", lambda seed=seed: registry.plan(sc, "ga", seed=seed, max_generations=gmax,
                                                                 stall_generations=gstall))
            if p is not None:
                ga_plans.append(p)
        add("family optimum", lambda: registry.plan(sc, "optimum"))
        best_ga = min(ga_plans, key=lambda p: p.motion_time_s) if ga_plans else None
        for path in ("family", "ga_path", "joint_line", "cartesian_line"):
            if path == "ga_path" and best_ga is None:
                continue
            add(f"TOPP-RA {path}", lambda path=path: registry.plan(sc, "toppra", path=path, reference_plan=best_ga))
        add("TOPP-RA family, spline output (raw)",
            lambda: registry.plan(sc, "toppra", path="family", parametrizer="ParametrizeSpline",
                         slow_to_limits=False, measure_polygon_cost=False))
        add("Drake Toppra family (inscribed box)", lambda: registry.plan(sc, "toppra-drake", path="family"))
        for J in jerks:
            add(f"Ruckig line J={J:g}", lambda J=J: registry.plan(sc, "ruckig", jerk_limit=J))
        jm = jerks[len(jerks) // 2]
        add(f"Ruckig joint J={jm:g}", lambda: registry.plan(sc, "ruckig", jerk_limit=jm, mode="joint"))
        add("trajopt (free path)", lambda: registry.plan(sc, "trajopt", **trajopt_kw))

        rows = []
        for label, plan in plans:
            if cosim:
                say(f"{name}: co-simulating {label}")
            rows.append(_row(sc, label, plan, cosim))
        fc_row = None
        no_search = hand_plugin(sc).carried_search_note  # why the hand's own search is elsewhere
        if cosim and carried and no_search is not None:
            result["scenarios"].setdefault(name, {})["fastest_carried_note"] = no_search
        elif cosim and carried:
            say(f"{name}: searching the fastest plan carried in the co-simulation")
            try:
                fc_plan, fc_row = fastest_carried(sc, quick=quick, progress=say, candidates=list(plans))
            except Exception as exc:  # noqa: BLE001 - a failed search is a note, not a crash
                say(f"{name}: fastest carried raised {type(exc).__name__}: {exc}")
                result["scenarios"].setdefault(name, {}).setdefault("errors", []).append(
                    {"label": CARRIED_LABEL, "error": f"{type(exc).__name__}: {exc}"})
            else:
                plans.append((fc_row["label"], fc_plan))
                rows.append(fc_row)
                # studies/success_probability.py reuses it (the same search) instead of repeating it
                fc_plan.write_json(out / f"fastest_carried_{name}.json")
                say(f"{name}: {fc_row['label']}: {fc_plan.motion_time_s:.4f} s, carried "
                    f"{fc_row['held']} ({fc_row['carried_wall_s']:.1f} s added)")
        feas = [r["motion_time_s"] for r in rows if r["feasible"]]
        fastest = min(feas) if feas else None
        for r in rows:
            r["ratio_to_fastest"] = (r["motion_time_s"] / fastest
                                     if fastest and r["motion_time_s"] > 0 else None)
        entry = result["scenarios"].setdefault(name, {})
        entry.update({"rows": rows, "fastest_feasible_s": fastest,
                      "closed_form_bound_s": closed_form_bound_s(sc),
                      "A_m_s2": bang_bang_acceleration_m_s2(sc),
                      "ratios": _ga_ratios(rows),
                      "fastest_carried": None if fc_row is None else {
                          k: fc_row[k] for k in ("label", "motion_time_s", "bang_bang_s", "excess_over_bang_bang",
                                                 "held", "max_slip_m", "feedforward", "cosim_time_step_s",
                                                 "search_variable", "search_chosen", "step_converged",
                                                 "step_convergence", "carried_wall_s")}})
        plans_by_scenario[name] = plans
        carried_by_scenario[name] = [r["held"] for r in rows]
    result["settings"]["fastest_carried_wall_s"] = sum(
        (e.get("fastest_carried") or {}).get("carried_wall_s") or 0.0 for e in result["scenarios"].values())
    write_text_atomic(out / "benchmark.json", json.dumps(jsonable(result), indent=1))
    write_text_atomic(out / "benchmark.md", benchmark_markdown(result))
    if figures:
        result["figures"] = write_figures(plans_by_scenario, out, carried_by_scenario)
    say(f"wrote {out / 'benchmark.json'} and {out / 'benchmark.md'}")
    return result


def _ga_ratios(rows) -> dict:
    by = {r["label"]: r for r in rows}
    ga = [r for r in rows if r["method"] == "ga" and r["feasible"]]
    out = {}
    if not ga:
        return out
    g = min(ga, key=lambda r: r["motion_time_s"])
    for key in ("TOPP-RA ga_path", "TOPP-RA family"):
        t = by.get(key)
        if t and t["feasible"] and t["motion_time_s"] > 0:
            out[f"GA / {key}: motion time"] = g["motion_time_s"] / t["motion_time_s"]
            out[f"GA / {key}: planning wall time"] = g["planner_wall_s"] / t["planner_wall_s"]
            tw = (t["extra"] or {}).get("toppra_solve_wall_s")
            if tw:
                out[f"GA / {key}: GA wall / toppra solve wall"] = g["planner_wall_s"] / tw
    return out
