"""Spatial scenarios: every planner against the TOPP-RA bound, re-checked, and co-simulated.

    cd <checkout> && PYTHONPATH=. .venv/bin/python -m studies.spatial_benchmark [--scenario ur5-suction-bins ur5-magnet-part panda-tray-cup]
        [--out out] [--ga-generations 150] [--actuator ideal|dc_motor]

For each method of planners/spatial_methods (TOPP-RA, Ruckig, the via-cubic family optimum, the GA,
trajopt), and for the rest-to-rest families (planners/spatial_families: the hand on straight Cartesian
lines, `<method>-line_cubic_velocity`, and the joint-space trapezoidal PTP, `<method>-trapezoid_ptp`)
TOPP-RA on their own path (stopping at every task pose), their family optimum and the GA:
motion time, its ratio to the bound (TOPP-RA's time-optimal duration along the IK'd geometric path;
the joint-space methods follow other paths, so a ratio below 1 would be possible and is not an
error), planning time, the time scale applied so the fine re-check holds, the largest limit ratio
re-checked at 10x the check rate, the largest task-pose error by Drake forward kinematics, and the
co-simulation outcome (sim/spatial_cosim). One more row plays the TOPP-RA plan 1.5x faster (time
scale 0.67): the part should be lost. When the TOPP-RA plan itself is not carried (a plan on the limit
leaves no margin for tracking error), a row `toppra_carried` gives the smallest slow-down that the
co-simulation carries (bisection over the time scale). A method that refuses the task is a row with
its one-line reason. Prints a Markdown table and writes OUT/spatial/<scenario>.json
and .md atomically (the JSON with each plan's hand ratio and largest ratio over time, thinned to 500
points, and the clearance with obstacles), the figures OUT/spatial/<scenario>-{hand_ratio,times,clearance}.png
(apps/spatial_figures.py), and each plan as OUT/spatial/<scenario>-<method>-plan.json (planners/spatial_plan_io:
1 kHz samples and the exact trajectory; `qmt-drake simulate <scenario> --plan FILE` replays it).
--actuator dc_motor co-simulates through DC motors with gears (sim/spatial_actuation.py, full feedforward;
the scenario's actuators.motor) instead of ideal torque actuators, and writes <scenario>-dc_motor.{json,md}.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from functools import partial
from pathlib import Path

from qmt_drake.apps.spatial_figures import plan_series, write_spatial_figures
from qmt_drake.energy.energy_plan import METHODS as ENERGY_TIME_METHODS
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.clearance import HORIZON_M, collision_model
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic
from qmt_drake.planners.spatial_carried import carried_plan, carried_search
from qmt_drake.planners.spatial_methods import FAMILY_METHODS, PLANNERS, plan_ga_spatial
from qmt_drake.planners.spatial_plan_io import write_spatial_plan
from qmt_drake.planners.spatial_trajectory import TimeScaled, check
from qmt_drake.sim.spatial_actuation import ACTUATORS, motor_params_for_spatial
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario

FAST_SCALE = 0.67
FAMILY_ROWS = ("line_cubic_velocity", "trapezoid_ptp")
NOTES = {"suction": "The co-simulation checks the cup on a finer grip polyhedron than the planners (24x8 rim/pyramid "
                    "vs 8x4); on the pull-off face both coincide, so a plan resting on that face has no margin left "
                    "for tracking error (the co-sim hand ratio column: the largest ratio while the part was held).",
         "magnet": "The magnet's moment limit is the same in the planners and the co-simulation: a plan resting on it "
                   "has no margin for tracking error, and TOPP-RA's steps in joint acceleration (bang-bang s-ddot) "
                   "make the 30 g part on its weld constraint overshoot the limit by about 2 % in the closed loop, "
                   "as do the trapezoid's; the smooth via-cubic and straight-line family plans stay within it "
                   "(co-sim hand ratio column).",
         "tray": "The cup stands unfixed on the tray: in the co-simulation only point contacts with Coulomb friction hold "
                 "it (no weld), so the outcome is the contact's own (slid off / tipped / slipped beyond 5 mm); the co-sim "
                 "hand ratio column is the planners' tray ratio (friction cone, centre of pressure, lift-off) of the "
                 "cup's simulated contact wrench. The planners' pyramid and polygon are inscribed (8 edges), the "
                 "re-check uses the circles."}


def run(scenario: str, ga_generations: int, actuator: str = "ideal") -> dict:
    t0 = time.perf_counter()
    sc = load_spatial_scenario(scenario)
    simulate = partial(simulate_spatial, actuator=actuator)
    if actuator != "ideal":  # refused before any planning when the scenario has no motor constants
        motor_params_for_spatial(sc)
    # the minimum-time methods: the energy-time ones (energy_plan.METHODS) minimise another cost and take c1, c2
    planners = {m: f for m, f in PLANNERS.items() if m not in ENERGY_TIME_METHODS}
    planners["ga"] = partial(plan_ga_spatial, generations=ga_generations)
    for family in FAMILY_ROWS:  # the rest-to-rest families: TOPP-RA on their path, their optimum, the GA
        for m in FAMILY_METHODS:
            planners[f"{m}-{family}"] = partial(planners[m], family=family)
    rows, plans, errors = {}, {}, {}
    for m, f in planners.items():
        try:
            plans[m] = p = f(sc)
        except QmtInputError as exc:  # one method's refusal is a row of the table, not the end of the study
            errors[m] = str(exc)
            continue
        rows[m] = dict(p.summary(), method=m)
    if "toppra" not in plans:
        raise QmtInputError(f"{sc.name}: TOPP-RA (the bound) failed: {errors['toppra']}")
    bound = plans["toppra"].raw_duration_s
    for m, p in plans.items():
        rows[m]["ratio_to_bound"] = p.duration_s / bound
        rows[m]["cosim"] = simulate(sc, p.trajectory)
    fast = TimeScaled(plans["toppra"].trajectory, FAST_SCALE)
    rows["toppra_x0.67"] = {"method": "toppra_x0.67", "duration_s": fast.duration_s, "ratio_to_bound": fast.duration_s / bound,
                            "planning_s": 0.0, "hold_scale": FAST_SCALE,
                            "recheck_max_ratio": check(sc, fast, sc.recheck_rate_hz)["max"],
                            "max_pose_position_error_m": rows["toppra"]["max_pose_position_error_m"],
                            "max_pose_angle_error_rad": rows["toppra"]["max_pose_angle_error_rad"],
                            "cosim": simulate(sc, fast)}
    if not rows["toppra"]["cosim"]["held"]:
        rows["toppra_carried"] = carried_row(sc, plans["toppra"], bound, actuator)
    clear = None
    if collision_model is not None and getattr(sc, "obstacles", None):
        model = collision_model(sc)
        clear = lambda q: model.distance(q)[0]  # noqa: E731 (smallest signed distance, m)
    for m, p in plans.items():  # the figures' series (apps/spatial_figures.py), at the re-check rate
        rows[m]["series"] = plan_series(sc, p.trajectory, sc.recheck_rate_hz, clear, HORIZON_M)
    rows["toppra_x0.67"]["series"] = plan_series(sc, fast, sc.recheck_rate_hz, clear, HORIZON_M)
    carried = [r for r in rows.values() if r["cosim"]["held"] and r["recheck_max_ratio"] <= 1.0]
    fastest = min(carried, key=lambda r: r["duration_s"])["method"] if carried else None
    return {"sc": sc, "plans": plans, "errors": errors, "scenario": sc.name, "actuator": actuator,
            "hand_kind": sc.hand_kind, "bound_s": bound, "check_rate_hz": sc.check_rate_hz,
            "recheck_rate_hz": sc.recheck_rate_hz, "rows": rows, "fastest_carried": fastest,
            "wall_s": time.perf_counter() - t0}


def carried_row(sc, plan, bound: float, actuator: str = "ideal") -> dict:
    """The table row of the TOPP-RA plan slowed by the smallest time scale in (1, 2.5] (bisection,
    planners/spatial_carried) whose co-simulation carries the part: the margin the closed loop needs
    over the planned limit. Called only when the plan as planned was lost (so k = 1 is not tried again)."""
    search = carried_search(sc, plan, k_max=2.5, iterations=7, try_planned=False,
                            actuator=actuator)
    if search["chosen"] is None:
        return {"method": "toppra_carried", "duration_s": float("nan"), "ratio_to_bound": float("nan"),
                "planning_s": 0.0, "hold_scale": search["k_max"], "recheck_max_ratio": float("nan"),
                "max_pose_position_error_m": float("nan"), "max_pose_angle_error_rad": float("nan"),
                "cosim": {"outcome": f"not carried even at {search['k_max']}x", "held": False,
                          "max_grip_ratio_while_held": float("nan")}}
    p = carried_plan(sc, plan, search)
    return {"method": "toppra_carried", "duration_s": p.duration_s, "ratio_to_bound": p.duration_s / bound,
            "planning_s": 0.0, "hold_scale": search["chosen"], "recheck_max_ratio": p.recheck["max"],
            "max_pose_position_error_m": float(p.pose_error[:, 0].max()),
            "max_pose_angle_error_rad": float(p.pose_error[:, 1].max()), "cosim": search["cosim"]}


def markdown(res: dict) -> str:
    lines = [f"Scenario {res['scenario']} ({res['actuator']} actuators): bound (TOPP-RA time-optimal on the IK'd path) {res['bound_s']:.4f} s; "
             f"re-check at {res['recheck_rate_hz']:g} Hz (10x the {res['check_rate_hz']:g} Hz check).", "",
             "| method | time s | / bound | planning s | scale to hold | max ratio (re-check) | pose error m / rad "
             "| co-simulation | co-sim hand ratio |", "|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"].values():
        c = r["cosim"]
        verdict = c["outcome"] + (f" at {c['lost_at_s']:.3f} s" if c.get("lost_at_s") is not None else "")
        lines.append(f"| {r['method']} | {r['duration_s']:.4f} | {r['ratio_to_bound']:.4f} | {r['planning_s']:.2f} | "
                     f"{r['hold_scale']:.4f} | {r['recheck_max_ratio']:.5f} | {r['max_pose_position_error_m']:.1e} / "
                     f"{r['max_pose_angle_error_rad']:.1e} | {verdict} | {c['max_grip_ratio_while_held']:.4f} |")
    for m, e in res["errors"].items():
        lines.append(f"| {m} | - | - | - | - | - | - | refused: {e} | - |")
    lines += ["", f"Fastest carried plan: {res['fastest_carried']}. Benchmark wall time {res['wall_s']:.1f} s.",
              NOTES[res["hand_kind"]]]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", nargs="+", default=["ur5-suction-bins", "ur5-magnet-part", "panda-tray-cup"])
    ap.add_argument("--out", default="out")
    ap.add_argument("--ga-generations", type=int, default=150)
    ap.add_argument("--actuator", choices=ACTUATORS, default="ideal")
    a = ap.parse_args(argv)
    try:
        check_output_dir(a.out, "--out")
        if a.ga_generations < 1:
            raise QmtInputError(f"--ga-generations {a.ga_generations}: give a positive integer")
        results = [run(name, a.ga_generations, a.actuator) for name in a.scenario]
    except QmtInputError as exc:
        print(f"spatial_benchmark: error: {exc}", file=sys.stderr)
        return 2
    out = Path(a.out) / "spatial"
    for res in results:
        md = markdown(res)
        print(md)
        plans, sc = res.pop("plans"), res.pop("sc")
        stem = res["scenario"] + ("" if a.actuator == "ideal" else f"-{a.actuator}")
        write_text_atomic(out / f"{stem}.json", json.dumps(jsonable(res), indent=1))
        write_text_atomic(out / f"{stem}.md", md)
        for m, p in plans.items():
            write_spatial_plan(sc, p, out / f"{res['scenario']}-{m}-plan.json")
        if a.actuator == "ideal":  # the figures of the ideal-actuator run (the report shows them)
            for f in write_spatial_figures(jsonable(res), out):
                print(f"figure {f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
