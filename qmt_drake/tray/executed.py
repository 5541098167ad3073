"""The executed motion of a tray co-simulation measured against its plan: joint tracking error and the
executed limit ratio (issue 20: what shaped goals change).

The co-simulation logs the arm's state at every plant step (tray/cosim.build_tray_diagram
step_log). The plant is discrete (semi-implicit Euler, h = 1 ms): the state logged at t_k is the one
before the step at t_k, and the plant's generalized acceleration at t_k is (v_{k+1} - v_k) / h
(logged too; tests/test_tray_executed.py checks the two are equal). That per-step acceleration
carries the servos' ripple: the firmware's integer law changes the voltage every 1 ms period, and the
tray terms are affine in qdd, so the ripple goes straight into the ratio (shaped TOPP-RA transfer at
x1.0, friction 0.3: slide peak 1.62 with the 2 ms central difference, 1.44 over 10 ms;
`python -m studies.tray_carried --quick`, executed_peak_ratio_2ms / executed_peak_ratio). The ripple
lasts one period (a few m/s^2 for 1 ms moves the bottle by microns, a h^2 / 2); what loses it is
the sustained ratio. The executed
acceleration here is therefore the mean of the per-step accelerations over `ACCEL_WINDOW_S` centred on
t_k, which telescopes to the central difference (v_{k+m} - v_{k-m}) / (2 m h), m = window / (2 h):
its first zero is at 1 / window = 100 Hz, it passes the plan's acceleration phases (0.1-0.4 s)
within 7 % in amplitude up to 20 Hz, it is exact for a quadratic velocity at any window, and on a
co-simulated run in which the bottle sticks it equals the ratio of the contact force Drake applied
to the bottle over the same 10 ms (tests/test_tray_executed.py).

The limit terms are the scenario's LimitSet (the planner's: the tray terms with friction and ring
radius x hand.plan_margin, so the plan's peaks are <= 1 and an executed 1.25 at margin 0.8 is the
friction cone's edge itself). The executed ratio is evaluated on (q, qd, qdd) over the move and the
tail (from the end of the settle phase to the end of the run: a lagging arm still moves after the
plan ends); the tracking error is the logged joint positions minus the plan's at the replay's time
(t - move start) / time_scale, the plan holding its end state after T.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.tray.cosim import TIME_STEP_S, simulate_tray
from qmt_drake.tray.execute import check_tray_simulation, plan_schedule
from qmt_drake.tray.limit_terms import TrayLiftTerm, TraySlideTerm, TrayTipTerm

ACCEL_WINDOW_S = 0.010
TRAY_TERMS = (TraySlideTerm.name, TrayTipTerm.name, TrayLiftTerm.name)


def central_acceleration(t_s: np.ndarray, qd: np.ndarray, window_s: float = ACCEL_WINDOW_S):
    """(keep, qdd): the joint accelerations [rad/s^2] at the samples `keep` (a boolean mask over t_s),
    the mean of the per-step accelerations (qd_{k+1} - qd_k) / h over window_s [s] centred on t_k,
    i.e. (qd_{k+m} - qd_{k-m}) / (t_{k+m} - t_{k-m}) with m = round(window_s / (2 h)) (m >= 1; the
    first and last m samples have no full window and are left out). qd: (K, n) [rad/s] at the
    uniformly spaced times t_s (K,) [s]."""
    t_s, qd = np.asarray(t_s, float), np.asarray(qd, float)
    if t_s.ndim != 1 or qd.shape[0] != t_s.size or t_s.size < 3:
        raise QmtInputError(f"executed motion: {t_s.size} samples of shape {qd.shape}; need (K, n) with K >= 3")
    h = float(np.median(np.diff(t_s)))
    if not h > 0 or np.max(np.abs(np.diff(t_s) - h)) > 1e-6 * h:
        raise QmtInputError("executed motion: the samples are not uniformly spaced (log every plant step)")
    m = max(1, int(round(window_s / (2.0 * h))))
    if t_s.size <= 2 * m:
        raise QmtInputError(f"executed motion: {t_s.size} samples are shorter than the {window_s * 1e3:g} ms window")
    keep = np.zeros(t_s.size, bool)
    keep[m:-m] = True
    qdd = (qd[2 * m:] - qd[:-2 * m]) / (t_s[2 * m:] - t_s[:-2 * m])[:, None]
    return keep, qdd


def executed_against_plan(scenario, plan, series: dict, *, move_start_s: float, time_scale: float = 1.0,
                          window_s: float = ACCEL_WINDOW_S) -> dict:
    """Tracking error [rad] and executed vs planned peak ratios of the tray terms (module docstring).
    series: tray/cosim.logged_series of a run with step_log ('t_step', 'arm_state_step' (2n, K));
    move_start_s: when the plan's replay starts in the run (the schedule's move phase)."""
    if "arm_state_step" not in series:
        raise QmtInputError("executed motion: the run was not logged every plant step (simulate_tray(step_log=True))")
    t = np.asarray(series["t_step"], float)
    x = np.asarray(series["arm_state_step"], float).T
    n = x.shape[1] // 2
    keep, qdd = central_acceleration(t, x[:, n:], window_s)
    m = keep & (t >= move_start_s)
    qdd = qdd[m[keep]]
    t, q, qd = t[m], x[m, :n], x[m, n:]
    # the plan itself replayed at the same scale, on the same samples with its exact derivatives
    qp, qdp, qddp = plan.sample((t - move_start_s) / time_scale)
    err = q - qp
    ls = scenario.limit_set
    cols = ls.columns(q, qd, qdd)
    names = [k for k in TRAY_TERMS if k in ls.slices]
    if not names:
        raise QmtInputError(f"{scenario.source_path}: executed limit ratios need a tray scenario (hand kind tray)")
    executed = {k: float(cols[:, ls.slices[k]].max()) for k in names}
    when = {k: float(t[int(np.argmax(cols[:, ls.slices[k]].max(axis=1)))] - move_start_s) for k in names}
    planned_cols = ls.columns(qp, qdp / time_scale, qddp / time_scale**2)
    planned = {k: float(planned_cols[:, ls.slices[k]].max()) for k in names}
    return {"time_scale": float(time_scale), "accel_window_s": float(window_s),
            "plan_margin": float(scenario.hand.plan_margin),
            "executed_peak_ratio": executed, "executed_peak_time_s": when, "planned_peak_ratio": planned,
            "tracking_error_rms_rad": float(np.sqrt(np.mean(err**2))),
            "tracking_error_max_rad": float(np.max(np.abs(err))),
            "per_joint_tracking_error_max_rad": [float(v) for v in np.max(np.abs(err), axis=0)]}


def execute_and_measure(scenario, plan, time_scale: float = 1.0, window_s: float = ACCEL_WINDOW_S) -> dict:
    """Co-simulate `plan` on the tray `scenario` at `time_scale` (its actuator.reference: shaped or
    plain goals; its servo period, plant step and bottle) logged every plant step, and return
    executed_against_plan's dict with the run's outcome ('on_tray' / 'slid_off' / 'tipped'), slip
    [m] and, as executed_peak_ratio_2ms, the peaks with the 2 ms central difference (the 1 kHz
    servo ripple kept)."""
    check_tray_simulation(scenario)
    act = scenario.actuator
    sched = plan_schedule(plan, time_scale=time_scale, period_s=act.control_period_s,
                          shaped_for=scenario if act.reference == "shaped" else None)
    r = simulate_tray(sched, act.gains(), scenario.bottle, servo_period_s=act.control_period_s, step_log=True)
    start = sched.phases["move"][0]
    d = executed_against_plan(scenario, plan, r.series, move_start_s=start, time_scale=time_scale, window_s=window_s)
    raw = executed_against_plan(scenario, plan, r.series, move_start_s=start, time_scale=time_scale, window_s=2 * TIME_STEP_S)
    d.update(executed_peak_ratio_2ms=raw["executed_peak_ratio"], reference=act.reference, outcome=r.outcome,
             slip_m=float(r.slip_m), max_slide_m=float(r.max_slide_m))
    return d
