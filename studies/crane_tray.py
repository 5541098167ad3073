"""Seed 002 study: the CRANE-X7 tray transfer, the fall/carry pair and what its outcome hinges on.

    PYTHONPATH=. python -m studies.crane_tray [--quick] [--no-recordings] [--sections ...] [--out DIR]
    PYTHONPATH=. python -m studies.crane_tray plan [--start X Y] [--goal X Y] [--mu MU] [--com-height H]
        (fastest TOPP-RA tray line as JSON; exit 2 on bad input, 3 when infeasible; the shared CLI
        does the same with `qmt-drake plan crane-tray --method toppra|ruckig|ga|thesis`)

The study's parts: crane_tray_runs.py (the seed's two runs and what is read from a run),
crane_tray_qmt.py (the fastest carried transfers and their friction x fill sweep),
crane_tray_figures.py (every figure); this module runs the sections and writes the results.

Writes out/crane_tray/ (sections: pair, req, friction, fill, rec, qmt, sweep, efficiency, timing):
    ik.json                     our IK vs the seed's printed joints, the fitted tool offset
    pair.json, pair_*.png       the two seed runs (P-only + linear, PID + eased) at the default
                                bottle (mu 0.3): outcome, slide, tilt, normal force, RTF;
                                Fig. 9/10-like joint responses; bottle slide/tilt/force over time
    required_friction.json/png  max |f_t|/f_n per phase of a sticking bottle (mu = 1) for the 2x2
                                of gains x spacing and over the servo period (the hinge parameters)
    friction_sweep.json/png     max slide and outcome over mu for both seed runs
    fill_sweep.json/png         max tilt over the bottle's centre-of-mass height (fill)
    fall.html, carry.html       Meshcat replays of the pair at the friction where it splits
    qmt.json, qmt.png           fastest carried transfer at mu 0.3, 30 g water: TOPP-RA on the
                                1000-waypoint IK line, the GA over the thesis's line family
                                (families/line.py) and Ruckig (jerk 5 m/s^3), all with the tray
                                terms (tray/limit_terms.py, plan margin 0.8) and re-checked by sampling;
                                each executed through the servos at the fastest time scaling that
                                carries the bottle without slip (> 1 mm); the seed's 5 s eased line
    sweep.json, sweep.png       success over friction 0.2-0.6 x fill (30/150/300/480 g water): the
                                nominal fastest carried transfer executed unchanged on each bottle,
                                and the fastest carried TOPP-RA transfer planned for each bottle
    efficiency.json             gear efficiency models at the hold (lossless / switched / smooth)
    toppra_timing.json          TOPP-RA solve time on the 1000-waypoint line with the tray limits,
                                batched constraint parameters vs toppra's per-grid-point evaluation,
                                interleaved in one run; the co-simulation's real-time factor

Findings (this script, 1 ms plant step and servo period, bottle PET 500 mL with 30 g water,
COM 44 mm, ring 29 mm; numbers from out/crane_tray/*.json):
- IK: Table 1 gives (1.1927, -2.0705, 0.8778) / (1.3402, -0.6632, -0.6770) rad; the seed prints
  (1.1183, -1.9650, 0.8299) / (1.2057, -0.4617, -0.7440). The printed joints put the tray 22 mm
  above y = 0.4; a tool offset of 0.1232 m instead of L0 + L3 = 0.148 m fits them to 12 mrad
  (the maker's joint-7 frame, 0.019 m past the wrist axis: crane_ik.py).
- P-only (800) sags under gravity (datasheet torque per volt): at the far goal 59 / 51 pulses on
  shoulder / elbow, the tray tilts ~10 deg for the whole hold; the retuned I gain removes the sag
  in seconds (pair_bottle.png, top panel).
- Required friction of a sticking bottle (required_friction.png): the return start needs 0.26
  with P-only + linear spacing but 0.06 with PID + eased (where the seed lost the bottle), while
  the arrival at the goal needs 0.27 vs 0.32 (eased spacing ends at 1.5x the mean speed, abruptly).
- Friction sweep (friction_sweep.png): at mu 0.10-0.175 the P-only/linear run loses the bottle
  (slides off the 0.24 m tray at 5.8-6.3 s, the arrival, or tips over its edge at 7.3 s) while
  PID/eased carries it (26-82 mm of slip); at mu 0.2 both are carried but P-only slips 11 mm at
  the start of the return (the seed's moment); from mu 0.25 neither slips. The pair hinges on mu
  (and on the tray's size and where the bottle stands, not given in the seed). Tipping is not the
  failure mode: with mu = 1 the bottle rocks < 0.25 deg up to a 100 mm COM (fill_sweep.png).
- The servo period matters for the PID run only (D acts per sample): return-start requirement
  0.06 -> 0.19 from 1 to 4 ms.
- Fastest carried transfer (qmt.png; mu 0.3, 30 g water, time scale found by 5 geometric bisection
  steps on [1, 8]: resolution x1.07): TOPP-RA plans 0.782 s (= the bang-bang closed form
  2 sqrt(L / (0.8 mu g))) and is carried at 2.69 s (x3.44; x3.22 slips); the GA over the line
  family plans 0.958 s (= the family optimum sqrt(1.5) x 0.782 s, found in 68 generations) and is
  carried at 3.09 s; Ruckig with jerk 5 m/s^3 plans 1.32 s and is carried at 3.07 s; the seed's
  eased line takes 5 s. The plans keep the tray limits x0.8; the servos lag them (tracking error
  ~0.13 rad at x1), so each must be played 2.3-3.4x slower to keep the bottle: the executed speed
  is set by the servos, not by the bottle's limits.
- Sweep (sweep.png, 4 bisection steps per cell: resolution x1.14): the nominal 2.69 s transfer
  keeps the bottle from mu 0.3 up for 30-300 g of water, fails at mu 0.2 for every fill (slips
  31-49 mm, the 300 g bottle tips, the 480 g one slides off) and slips 18 mm with 480 g at mu 0.3.
  Planned per bottle, the fastest carried transfer shortens with mu (30 g: 3.51 s at 0.2 to 1.31 s
  at 0.6); the nearly full bottle (COM 74 mm, r_c / h_G = 0.39) is tip-limited from mu 0.4 up
  (2.52 s at 0.4-0.6). Water at the bottom lowers the COM (150 g: 32 mm) and that bottle is the
  fastest at most frictions.
- Gear efficiency (efficiency.json): with the datasheet's eta switched at zero speed the hold
  chatters (bottle normal force 0.42-0.71 N for a 0.49 N weight); the smooth blend (w_b 0.01-0.05
  rad/s) keeps it at 0.46-0.52 N like the lossless equivalent (0.47-0.51 N).
- TOPP-RA on the 1000-waypoint line with the tray limits (toppra_timing.json, load ~3.5 on 2
  cores): 48 ms (min of 7; median 54 ms) with the batched LimitSet constraint vs 0.96 s with
  toppra's per-grid-point evaluation (x20); same 0.782 s. Co-simulation real-time factor 5.0 at a
  1 ms plant step and servo period (3.5 s wall for 17.5 s, seed eased run).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2  # noqa: E402
from qmt_drake.outputs import write_text_atomic  # noqa: E402
from qmt_drake.systems.dynamixel_servo import SEED_GAINS_AFTER, SEED_GAINS_BEFORE  # noqa: E402
from qmt_drake.systems.tray_object import BottleSpec  # noqa: E402
from qmt_drake.tray import crane_ik  # noqa: E402
from qmt_drake.tray.cosim import simulate_tray  # noqa: E402
from qmt_drake.tray.waypoints import seed_motion, toppra_line  # noqa: E402
from studies.crane_tray_figures import (  # noqa: E402
    plot_fill_sweep,
    plot_friction_sweep,
    plot_pair,
    plot_qmt,
    plot_req,
    plot_sweep,
)
from studies.crane_tray_qmt import qmt_section, sweep_section  # noqa: E402
from studies.crane_tray_runs import (  # noqa: E402
    CASES,
    SEED_REST_TILT_RAD,
    SETTLE_S,
    fill_bottle,
    phase_mu,
    run,
)

OUT = ROOT / "out" / "crane_tray"


def _json(path: Path, obj) -> None:
    write_text_atomic(path, json.dumps(obj, indent=2, default=float))


def ik_report() -> dict:
    ours = {k: crane_ik.tray_ik(*xy).tolist() for k, xy in (("start", crane_ik.SEED_START_XY_M),
                                                           ("goal", crane_ik.SEED_GOAL_XY_M))}
    h, res = crane_ik.fit_tool_offset()
    return {"ours_rad": ours,
            "seed_rad": {"start": crane_ik.SEED_START_THETA_RAD, "goal": crane_ik.SEED_GOAL_THETA_RAD},
            "difference_rad": crane_ik.seed_joint_residual().tolist(),
            "fk_of_seed_joints_xy_phi": {"start": crane_ik.tray_fk(crane_ik.SEED_START_THETA_RAD).tolist(),
                                         "goal": crane_ik.tray_fk(crane_ik.SEED_GOAL_THETA_RAD).tolist()},
            "table1_tool_offset_L0_plus_L3_m": crane_ik.TABLE1.L0 + crane_ik.TABLE1.L3,
            "fitted_tool_offset_m": h, "fitted_max_residual_rad": res,
            "residual_with_fit_rad": crane_ik.seed_joint_residual(h).tolist()}


def efficiency_section() -> dict:
    """The servo motors' gear efficiency at the hold: the lossless equivalent (default), the
    datasheet's eta switched at zero speed, and the smooth (tanh) blend (dc_motor.py), on the seed's
    PID eased run: the normal force and joint-speed dither over the hold (from 1 s after arrival)."""
    from qmt_drake.systems.dynamixel_servo import CRANE_X7_PLANAR_SERVOS, motor_params
    sched = seed_motion(1.5, settle_s=SETTLE_S)
    bottle = fill_bottle(0.030, 0.3)
    out = {"weight_N": bottle.mass_kg * STANDARD_GRAVITY_M_S2, "cases": {}}
    for name, kw in (("lossless equivalent (default)", {}),
                     ("datasheet eta, switched at qd = 0", {"lossless_equivalent": False}),
                     ("datasheet eta, smooth w_b = 0.05 rad/s", {"lossless_equivalent": False,
                                                                 "efficiency_blend_speed_rad_s": 0.05}),
                     ("datasheet eta, smooth w_b = 0.01 rad/s", {"lossless_equivalent": False,
                                                                 "efficiency_blend_speed_rad_s": 0.01})):
        r = simulate_tray(sched, SEED_GAINS_AFTER, bottle, motor=motor_params(CRANE_X7_PLANAR_SERVOS, **kw))
        t = r.series["t"]
        h0, h1 = r.phases["hold"]
        m = (t > h0 + 1.0) & (t < h1)
        fn = r.series["contact_force"][2][m]
        qd = r.series["arm_state"][3:6][:, m]
        out["cases"][name] = {"outcome": r.outcome, "slip_m": r.slip_m, "hold_normal_force_N": [float(fn.min()),
                                                                                               float(fn.max())],
                              "hold_max_joint_speed_rad_s": np.abs(qd).max(axis=1).tolist(),
                              "real_time_factor": r.real_time_factor}
        print("efficiency", name, out["cases"][name]["hold_normal_force_N"], flush=True)
    return out


def timing_section(repeats: int = 7) -> dict:
    """TOPP-RA solve time with the tray limits on the 1000-waypoint line, constraint parameters
    batched (LimitSet.toppra_constraint) vs toppra's per-grid-point evaluation, interleaved in one
    run (the machine's load hits both alike); and the tray co-simulation's real-time factor."""
    bottle = fill_bottle(0.030, 0.3)
    toppra_line(bottle)  # warm-up: imports, scenario load
    t = {True: [], False: []}
    cpu = {True: [], False: []}
    dur = {}
    for _ in range(repeats):
        for batched in (True, False):
            _, info = toppra_line(bottle, batched=batched)
            t[batched].append(info["solve_s"])
            cpu[batched].append(info["solve_cpu_s"])
            dur[batched] = info["planned_duration_s"]
    seed = run("after", mu=0.3)
    return {"gridpoints": 1001, "repeats": repeats,
            "batched_s": {"min": min(t[True]), "median": float(np.median(t[True])), "all": t[True]},
            "per_gridpoint_s": {"min": min(t[False]), "median": float(np.median(t[False])), "all": t[False]},
            "batched_cpu_s": {"min": min(cpu[True]), "median": float(np.median(cpu[True]))},
            "per_gridpoint_cpu_s": {"min": min(cpu[False]), "median": float(np.median(cpu[False]))},
            "speedup_min": min(t[False]) / min(t[True]),
            "load_average_1min": os.getloadavg()[0],
            "planned_duration_s": {"batched": dur[True], "per_gridpoint": dur[False]},
            "last_session_s": "0.17-0.21 (tray_constraint: Drake kinematics per sample, batched parameters)",
            "cosim": {"time_step_s": seed.time_step_s, "servo_period_s": seed.servo_period_s,
                      "sim_time_s": seed.sim_time_s, "wall_s": seed.sim_wall_s,
                      "real_time_factor": seed.real_time_factor, "run": "seed eased 5 s line, PID, mu 0.3"}}


def plan_command(argv) -> int:
    """`crane_tray.py plan ...`: the fastest TOPP-RA tray line as JSON on stdout. Exit 2 on bad input
    (one line on stderr), 3 when no parametrisation keeps the bottle (feasible: false)."""
    from qmt_drake.errors import QmtInputError
    ap = argparse.ArgumentParser(prog="crane_tray.py plan")
    ap.add_argument("--start", type=float, nargs=2, default=list(crane_ik.SEED_START_XY_M), metavar=("X", "Y"))
    ap.add_argument("--goal", type=float, nargs=2, default=list(crane_ik.SEED_GOAL_XY_M), metavar=("X", "Y"))
    ap.add_argument("--mu", type=float, default=0.3, help="bottle-tray friction coefficient")
    ap.add_argument("--com-height", type=float, default=None, help="bottle centre of mass above its base [m]")
    ap.add_argument("--margin", type=float, default=0.8)
    a = ap.parse_args(argv)
    try:
        bottle = BottleSpec.pet_500ml(friction=a.mu)
        if a.com_height is not None:
            bottle = bottle.with_com_height(a.com_height)
        bottle.check_rests(SEED_REST_TILT_RAD)
        crane_ik.tray_ik(*a.start)
        crane_ik.tray_ik(*a.goal)
        _, info = toppra_line(bottle, start_xy=a.start, goal_xy=a.goal, margin=a.margin)
    except QmtInputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(json.dumps(info, indent=2, default=float))
    return 0 if info["feasible"] else 3


def main(argv=None) -> int:
    global OUT
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["plan"]:
        return plan_command(argv[1:])
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer sweep points")
    ap.add_argument("--no-recordings", action="store_true")
    ap.add_argument("--sections", default="pair,req,friction,fill,rec,qmt,sweep,efficiency,timing",
                    help="comma list of: pair, req, friction, fill, rec, qmt, sweep, efficiency, timing")
    ap.add_argument("--rec-mu", type=float, default=0.3, help="friction of the recordings when the sweep is not run")
    ap.add_argument("--out", default=str(OUT), help="output folder (default out/crane_tray)")
    args = ap.parse_args(argv)
    sections = set(args.sections.split(","))
    OUT = Path(args.out)
    OUT.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    _json(OUT / "ik.json", ik_report())

    if "replot" in sections:  # figures from the JSON already written
        plot_req(json.loads((OUT / "required_friction.json").read_text()), OUT / "required_friction.png")
        for name, plot in (("qmt", plot_qmt), ("sweep", plot_sweep)):
            if (OUT / f"{name}.json").is_file():
                plot(json.loads((OUT / f"{name}.json").read_text()), OUT / f"{name}.png")
    if "pair" in sections:
        # 1. the pair at the default bottle
        pair = {c: run(c) for c in CASES}
        _json(OUT / "pair.json", {c: r.summary_dict() | {"required_friction_by_phase": phase_mu(r)}
                                  for c, r in pair.items()})
        plot_pair(pair, OUT / "pair_joints.png", OUT / "pair_bottle.png")
        print("pair:", {c: (r.outcome, r.slip_m, round(r.real_time_factor, 2)) for c, r in pair.items()})

    if "req" in sections:
        # 2. required friction (sticking bottle) per phase: gains x spacing, and the servo period
        req = {}
        combos = {"P-only, linear": (1.0, SEED_GAINS_BEFORE), "P-only, eased": (1.5, SEED_GAINS_BEFORE),
                  "PID, linear": (1.0, SEED_GAINS_AFTER), "PID, eased": (1.5, SEED_GAINS_AFTER)}
        for name, (e, g) in combos.items():
            r = run("before", mu=1.0, exponent=e, gains=g)
            req[name] = {"period_1ms": phase_mu(r)}
            print("required mu", name, req[name])
        periods = (2e-3, 4e-3) if args.quick else (2e-3, 4e-3, 8e-3)
        for p in periods:
            for name in ("P-only, linear", "PID, eased"):
                e, g = combos[name]
                r = run("before", mu=1.0, exponent=e, gains=g, period_s=p)
                req[name][f"period_{p * 1e3:g}ms"] = phase_mu(r)
                print("required mu", name, p, req[name][f"period_{p * 1e3:g}ms"])
        _json(OUT / "required_friction.json", req)
        plot_req(req, OUT / "required_friction.png")

    if "friction" in sections:
        # 3. friction sweep
        mus = (0.15, 0.2, 0.3) if args.quick else (0.1, 0.125, 0.15, 0.175, 0.2, 0.25, 0.3, 0.4)
        sweep = {c: [run(c, mu=m).summary_dict() for m in mus] for c in CASES}
        _json(OUT / "friction_sweep.json", {"mu": mus, **sweep})
        plot_friction_sweep(mus, sweep, OUT / "friction_sweep.png")

    if "fill" in sections:
        # 4. fill (centre-of-mass height) sweep at a sticking friction: tipping
        coms = (0.044, 0.08) if args.quick else (0.044, 0.06, 0.07, 0.08, 0.1)
        fill = {c: [run(c, mu=1.0, com_height=h).summary_dict() for h in coms] for c in CASES}
        _json(OUT / "fill_sweep.json", {"com_height_m": coms, **fill})
        plot_fill_sweep(coms, fill, OUT / "fill_sweep.png")

    if "rec" in sections:
        # 5. recordings of the pair at the friction where it splits (if any), else the default
        if "friction" in sections:
            lost = [m for m, b, a in zip(mus, sweep["before"], sweep["after"])
                    if b["outcome"] != "on_tray" and a["outcome"] == "on_tray"]
            slipped = [m for m, b, a in zip(mus, sweep["before"], sweep["after"]) if b["slipped"] and not a["slipped"]]
            split = lost or slipped
            mu_rec = max(split) if split else 0.3
        else:
            split, mu_rec = [], args.rec_mu
        if not args.no_recordings:
            rb = run("before", mu=mu_rec, recording=OUT / "fall.html")
            ra = run("after", mu=mu_rec, recording=OUT / "carry.html")
            _json(OUT / "recordings.json", {"mu": mu_rec, "split_found": bool(split), "before": rb.summary_dict(),
                                            "after": ra.summary_dict()})
    if "qmt" in sections:
        q = qmt_section(args.quick)
        _json(OUT / "qmt.json", q)
        plot_qmt(q, OUT / "qmt.png")
    if "sweep" in sections:
        sw = sweep_section(args.quick)
        _json(OUT / "sweep.json", sw)
        plot_sweep(sw, OUT / "sweep.png")
    if "efficiency" in sections:
        _json(OUT / "efficiency.json", efficiency_section())
    if "timing" in sections:
        tm = timing_section(3 if args.quick else 7)
        _json(OUT / "toppra_timing.json", tm)
        print("timing", tm["batched_s"]["min"], tm["per_gridpoint_s"]["min"], tm["cosim"]["real_time_factor"])
    print(f"done in {time.perf_counter() - t0:.0f} s -> {OUT}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
