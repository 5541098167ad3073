"""Planned versus executed payload moment: how far the closed loop's tip acceleration overshoots a plan.

A plan bounds m_o r_G |a_tip| of its *reference*; the arm executes it through PID, motors and gears,
and the part feels the executed acceleration. For each time scale this co-simulates the plan and
reports, up to 20 ms before detachment (or over the whole run):

  * desired peak moment: m_o r_G |a_tip| of the reference the controller was given;
  * executed peak moment: the same from the arm's simulated joint motion (5 ms samples of q, qd;
    qdd by central differences, so peaks shorter than ~10 ms are smoothed);
  * time above the hold moment: how long the executed (and desired) moment exceeded 0.98 of the
    calibrated hold moment tau* (the geometric mean of the thesis's success/failure boundary).

Run: .venv/bin/python -m studies.executed_moment SCENARIO PLAN.json [--time-scale S ...]
     [--feedforward none|back-emf|full] [--json PATH]
(PLAN.json from `qmt-drake plan ... --json`). README, 'ch.2 time-optimal profiles', uses it.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from qmt_drake.outputs import write_text_atomic  # noqa: E402
from qmt_drake.plan_files import load_plan  # noqa: E402
from qmt_drake.sim import FEEDFORWARD_OPTIONS, simulate_transfer  # noqa: E402
from qmt_drake.transfer_scenario import load_scenario  # noqa: E402

NEAR_HOLD_FRACTION = 0.98


def executed_moment_row(scenario, plan, time_scale: float, feedforward: str = "none") -> dict:
    res = simulate_transfer(scenario, plan, time_scale=time_scale, **FEEDFORWARD_OPTIONS[feedforward])
    s = res.series
    t = s["t_s"]
    n = s["arm_state"].shape[1] // 2
    before = t < ((res.detached_at_s - 0.02) if res.detached_at_s is not None else math.inf)
    m_rg = scenario.moment_per_accel_kgm

    def moment(x):
        q, qd = x[:, :n], x[:, n:]
        qdd = np.gradient(qd, t, axis=0)
        return m_rg * np.linalg.norm(scenario.arm.tip_acceleration(q, qd, qdd), axis=-1)[before]

    executed, desired = moment(s["arm_state"]), moment(s["desired_state"])
    tau_star = math.sqrt(math.prod(scenario.hand.slip_boundary_Nm))
    dt = float(np.median(np.diff(t)))
    return dict(time_scale=time_scale, feedforward=feedforward, held=res.held,
                max_tracking_error_rad=res.max_tracking_error_rad, max_slip_m=res.max_slip_m, detached_at_s=res.detached_at_s,
                peak_moment_ratio_planned=res.peak_moment_ratio_planned, hold_moment_Nm=tau_star,
                desired_peak_moment_Nm=float(desired.max()), executed_peak_moment_Nm=float(executed.max()),
                executed_over_desired=float(executed.max() / desired.max()),
                executed_peak_at_s=float(t[before][int(np.argmax(executed))]),
                desired_peak_at_s=float(t[before][int(np.argmax(desired))]),
                desired_s_near_hold=float(np.sum(desired > NEAR_HOLD_FRACTION * tau_star) * dt),
                executed_s_near_hold=float(np.sum(executed > NEAR_HOLD_FRACTION * tau_star) * dt))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("plan", help="plan JSON written by `qmt-drake plan ... --json`")
    ap.add_argument("--time-scale", type=float, nargs="+", default=[1.0])
    ap.add_argument("--feedforward", choices=sorted(FEEDFORWARD_OPTIONS), default="none",
                    help="controller feedforward, as `qmt-drake simulate --feedforward`")
    ap.add_argument("--json", help="write the rows here (atomically)")
    args = ap.parse_args(argv)
    sc = load_scenario(args.scenario)
    plan = load_plan(args.plan)
    rows = []
    for scale in args.time_scale:
        r = executed_moment_row(sc, plan, scale, args.feedforward)
        rows.append(r)
        fate = "held" if r["held"] else f"lost (detached at {r['detached_at_s']})" if r["detached_at_s"] else "slipped"
        print(f"x{scale:g}: {fate}, tracking error {r['max_tracking_error_rad'] * 1e3:.2f} mrad, planned peak/limit {r['peak_moment_ratio_planned']:.3f}; peak moment desired "
              f"{r['desired_peak_moment_Nm']:.3e}, executed {r['executed_peak_moment_Nm']:.3e} N m "
              f"(x{r['executed_over_desired']:.2f}) at {r['executed_peak_at_s']:.3f} s (desired peak at "
              f"{r['desired_peak_at_s']:.3f} s); above {NEAR_HOLD_FRACTION} of the hold moment "
              f"{r['hold_moment_Nm']:.3e}: desired {r['desired_s_near_hold']:.2f} s, executed "
              f"{r['executed_s_near_hold']:.2f} s", flush=True)
    if args.json:
        write_text_atomic(args.json, json.dumps(dict(scenario=args.scenario, plan=str(args.plan), rows=rows), indent=1))


if __name__ == "__main__":
    main()
