"""Seed 002 study (studies/crane_tray.py): the fastest carried tray transfers. Each plan (TOPP-RA on
the IK line, the GA over the line family, Ruckig) keeps the tray terms and is executed through the
servos at the smallest time scale that carries the bottle (geometric bisection); and the sweep of
that over friction x fill."""

from __future__ import annotations

import math

from qmt_drake.systems.dynamixel_servo import SEED_GAINS_AFTER
from qmt_drake.tray.conditions import level_tray_acceleration_cap_m_s2
from qmt_drake.tray.cosim import simulate_tray
from qmt_drake.tray.waypoints import toppra_line
from studies.crane_tray_runs import SETTLE_S, carried_ok, fill_bottle, run


def fastest_executed(make, bottle, k_hi: float = 8.0, iters: int = 4) -> dict:
    """Smallest time scale k (geometric bisection on [1, k_hi]) at which the streamed plan make(k),
    executed through the servos (seed's retuned PID), carries the bottle without slip."""
    runs = []

    def ok(k):
        sched, info = make(k)
        r = simulate_tray(sched, SEED_GAINS_AFTER, bottle, keep_series=False)
        runs.append({"time_scale": k, "duration_s": info["duration_s"], "outcome": r.outcome, "slip_m": r.slip_m,
                     "creep_m": r.creep_m, "rtf": r.real_time_factor})
        return carried_ok(r), info["duration_s"]

    good1, d1 = ok(1.0)
    if good1:
        return {"duration_s": d1, "time_scale": 1.0, "runs": runs}
    good_hi, d_hi = ok(k_hi)
    if not good_hi:
        return {"duration_s": None, "time_scale": None, "runs": runs, "note": f"not carried even at x{k_hi}"}
    lo, hi, d_best = 1.0, k_hi, d_hi
    for _ in range(iters):
        mid = math.sqrt(lo * hi)
        good, d = ok(mid)
        if good:
            hi, d_best = mid, d
        else:
            lo = mid
    return {"duration_s": d_best, "time_scale": hi, "time_scale_failing": lo, "runs": runs}


def _plan_summary(plan) -> dict:
    return {"method": plan.method, "feasible": plan.feasible, "planned_duration_s": plan.motion_time_s,
            "recheck_rate_hz": plan.check.rate_hz, "peak_ratios": dict(plan.check.peak_ratios),
            "planner_wall_s": plan.planner_wall_s, "genes": plan.genes}


def _plan_maker(plan):
    from qmt_drake.tray.execute import plan_schedule
    return lambda k: (plan_schedule(plan, time_scale=k, settle_s=SETTLE_S),
                      {"duration_s": plan.motion_time_s * k})


def qmt_section(quick: bool, jerk_m_s3: float = 5.0, ga_seed: int = 0) -> dict:
    """Fastest carried straight-line transfer at the default bottle (mu 0.3, 30 g water): TOPP-RA on
    the 1000-waypoint IK line, the GA over the thesis's line family and Ruckig with a jerk limit, all
    with the tray terms (plan margin 0.8, re-checked by sampling), each executed through the servos
    at the fastest time scaling that carries the bottle; against the seed's 5 s eased line."""
    from qmt_drake.planners import plan_with
    from qmt_drake.tray.planning import tray_scenario
    bottle = fill_bottle(0.030, 0.3)
    sc = tray_scenario(bottle)
    out = {"friction": 0.3, "com_height_m": bottle.com_height_m, "plan_margin": sc.hand.plan_margin, "methods": {}}
    k_iters = 3 if quick else 5
    sched, info = toppra_line(bottle)
    out["methods"]["toppra"] = {"plan": info, "executed": fastest_executed(
        lambda k: toppra_line(bottle, time_scale=k), bottle, iters=k_iters)}
    print("qmt toppra", info["duration_s"], out["methods"]["toppra"]["executed"]["duration_s"], flush=True)
    for method, kw in (("ruckig", {"jerk_limit": jerk_m_s3}),
                       ("ga", {"max_generations": 60, "stall_generations": 20} if quick else {})):
        plan = plan_with(method, sc, seed=ga_seed, **kw)
        entry = {"plan": _plan_summary(plan) | kw}
        if method == "ga":
            entry["plan"].update(generations=plan.generations, evaluations=plan.evaluations,
                                 family_optimum_s=math.sqrt(1.5) * 2 * math.sqrt(
                                     0.36 / level_tray_acceleration_cap_m_s2(bottle, sc.hand.plan_margin)))
        entry["executed"] = fastest_executed(_plan_maker(plan), bottle, iters=k_iters)
        out["methods"][method] = entry
        print("qmt", method, plan.motion_time_s, entry["executed"]["duration_s"], flush=True)
    seed = run("after", mu=0.3)
    out["methods"]["seed_eased_5s"] = {"executed": {"duration_s": 5.0, "outcome": seed.outcome,
                                                    "slip_m": seed.slip_m, "carried": carried_ok(seed),
                                                    "rtf": seed.real_time_factor}}
    return out


SWEEP_MUS = (0.2, 0.3, 0.4, 0.5, 0.6)


# Water in the 20 g bottle: 30 g (the seed's 50 g bottle, COM 44 mm), 150 g (COM 32 mm: water at the
# bottom lowers it), 300 g (49 mm), 480 g (nearly full, 74 mm: tipping binds before sliding from mu 0.4).
SWEEP_WATER_KG = (0.030, 0.150, 0.300, 0.480)


def sweep_section(quick: bool) -> dict:
    """Success over friction x fill: (a) the nominal fastest carried transfer (TOPP-RA at mu 0.3, 30 g
    water, at its fastest carried time scale) executed unchanged on every bottle; (b) per bottle the
    fastest carried TOPP-RA transfer (planned for that bottle, time scale searched)."""
    mus = (0.2, 0.4, 0.6) if quick else SWEEP_MUS
    waters = (0.030, 0.480) if quick else SWEEP_WATER_KG
    nominal = fill_bottle(0.030, 0.3)
    best = fastest_executed(lambda k: toppra_line(nominal, time_scale=k), nominal, iters=3 if quick else 5)
    k_nom = best["time_scale"]
    nominal_sched, nominal_info = toppra_line(nominal, time_scale=k_nom)
    out = {"mu": list(mus), "water_kg": list(waters), "nominal": {"time_scale": k_nom,
                                                                  "duration_s": nominal_info["duration_s"]},
           "cells": []}
    for w in waters:
        for mu in mus:
            b = fill_bottle(w, mu)
            r = simulate_tray(nominal_sched, SEED_GAINS_AFTER, b, keep_series=False)
            cell = {"mu": mu, "water_kg": w, "mass_kg": b.mass_kg, "com_height_m": b.com_height_m,
                    "nominal_plan": {"outcome": r.outcome, "slip_m": r.slip_m, "carried": carried_ok(r),
                                     "max_tilt_rad": r.max_tilt_rad}}
            _, info = toppra_line(b)
            cell["toppra_plan_s"] = info.get("duration_s")
            cell["binding"] = ("tip" if info.get("max_tip_ratio", 0) > info.get("max_slide_ratio", 0) else "slide")
            cell["toppra_peak_ratios"] = {k: info.get(k) for k in ("max_slide_ratio", "max_tip_ratio",
                                                                    "max_speed_ratio")}
            cell["fastest"] = fastest_executed(lambda k, b=b: toppra_line(b, time_scale=k), b, iters=3 if quick else 4)
            out["cells"].append(cell)
            print("sweep", w, mu, cell["nominal_plan"]["outcome"], cell["toppra_plan_s"],
                  cell["fastest"]["duration_s"], flush=True)
    return out
