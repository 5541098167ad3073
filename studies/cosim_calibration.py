"""Calibration of the co-simulated magnet hold against the thesis's slip experiments.

One calibration rule for both hands (qmt_drake.sim.magnet_hand.calibrated_coil_current_A): each coil's current
makes the quasi-static hold limit (F - m g) * min(rho, mu r_G) equal the geometric mean of the
thesis's last-success / first-failure moments. Then every row is simulated with its own profile:

  * Table 2.3 (ch.2): the straight line with v_xmax = 0.07 m/s, genes (T1, T2) as printed;
  * Table 4.2 (ch.4): the GA via-point move (genes 0.622/0.532/0.562 s) slowed or sped up in time
    so that its planned peak moment equals the row's moment (accelerations scale as 1/s^2).

Outputs (out/): cosim_calibration.json (rows, thresholds, parameters), cosim_calibration.md (table),
cosim_calibration_slip.png (max slip against peak moment). Run:
    .venv/bin/python studies/cosim_calibration.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from qmt_drake.sim import (  # noqa: E402
    MAGNET_EFFECTIVE_GAP_M,
    GenesPlan,
    hold_lever_m,
    planned_peak_moment_Nm,
    simulate_transfer,
)
from qmt_drake.transfer_scenario import load_scenario  # noqa: E402

# The hands' data come from the scenarios' typed `hand` sections (coil, thesis slip boundary).
_HANDS = {ch: load_scenario(name).hand for ch, name in (("ch2", "thesis-ch2"), ("ch4", "thesis-ch4"))}
SLIP_BOUNDARIES_NM = {ch: h.slip_boundary_Nm for ch, h in _HANDS.items()}
HAND_COIL = {ch: h.coil for ch, h in _HANDS.items()}
from qmt_drake.systems.payload import PayloadSpec  # noqa: E402

TABLE_2_3 = [  # peak moment [N*m], T1 [s], T2 [s], result (seed 000 Table 2.3, v_xmax = 0.07 m/s)
    (2.640e-5, 1.400, 1.457, "success"), (2.816e-5, 1.313, 1.545, "success"),
    (2.992e-5, 1.235, 1.621, "success"), (3.168e-5, 1.167, 1.690, "success"),
    (3.344e-5, 1.105, 1.752, "failure"), (3.520e-5, 1.050, 1.807, "failure"),
    (3.696e-5, 1.000, 1.857, "failure"), (3.872e-5, 0.955, 1.903, "failure")]
TABLE_4_2 = [(0.991e-3, "failure"), (0.843e-3, "failure"), (0.727e-3, "failure"),
             (0.633e-3, "success"), (0.557e-3, "success"), (0.497e-3, "success")]
CH4_GA_GENES = (0.622, 0.532, 0.562)


def run_row(sc, plan, scale):
    r = simulate_transfer(sc, plan, time_scale=scale, keep_series=False)
    return r


def ch2_plan(sc, T1, T2):
    return GenesPlan(sc, [T1, T2], method="table_2_3")


def threshold_by_bisection(moment_of, held_at, lo, hi, iters):
    """Bisect on peak moment between a held `lo` and a lost `hi` [N*m]."""
    for _ in range(iters):
        mid = math.sqrt(lo * hi)
        if held_at(mid):
            lo = mid
        else:
            hi = mid
    return lo, hi


def control_report(sc, genes) -> dict:
    """Closed-loop poles of the thesis gains (literal SI vs the adopted reading, at the plan's start
    posture), and the GA plan through motors, gears and PID at time scales 1.0 and 0.8."""
    from qmt_drake.sim import motor_params_for, pid_gains_for
    from qmt_drake.systems.joint_tracking import effective_joint_gains

    plan = GenesPlan(sc, genes, method="thesis_ga")
    q0 = plan.sample(np.array([0.0]))[0][0]
    plant = sc.arm.plant
    pc = plant.CreateDefaultContext()
    plant.SetPositions(pc, q0)
    M = plant.CalcMassMatrix(pc)
    n = len(q0)

    def poles(K, D):
        Minv = np.linalg.inv(M)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ np.diag(K), -Minv @ np.diag(D)]])
        return sorted(np.linalg.eigvals(A), key=lambda z: abs(z.real))

    kp, kd = np.array(sc.control["kp"], float), np.array(sc.control["kd"], float)
    K, D = effective_joint_gains(pid_gains_for(sc), motor_params_for(sc))
    out = dict(literal_si_poles=[[z.real, z.imag] for z in poles(kp, kd)],
               adopted_poles=[[z.real, z.imag] for z in poles(K, D)],
               adopted_stiffness_Nm_per_rad=K.tolist(), adopted_damping_Nm_s_per_rad=D.tolist(),
               motors=motor_params_for(sc).names, runs=[])
    for scale in (1.0, 0.8):
        r = simulate_transfer(sc, plan, time_scale=scale, keep_series=False)
        d = r.summary_dict()
        out["runs"].append({k: d[k] for k in ("time_scale", "held", "max_slip_m", "max_tilt_rad", "detached_at_s",
                                              "max_tracking_error_rad", "peak_motor_torque_Nm",
                                              "peak_motor_torque_planned_Nm", "peak_moment_ratio_planned",
                                              "energy_J", "real_time_factor")})
        print(f"{sc.name} GA x{scale}: held={r.held} slip={r.max_slip_m*1e3:.3f} mm "
              f"track={r.max_tracking_error_rad:.4f} rad "
              f"motor={np.round(r.peak_motor_torque_Nm, 5)} N m (plan/N {np.round(r.peak_motor_torque_planned_Nm, 5)})",
              flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer sweep points and bisection steps")
    ap.add_argument("--out", default=str(ROOT / "out"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    n_bisect = 3 if args.quick else 6
    n_sweep = 4 if args.quick else 10
    t0 = time.perf_counter()
    report = {"rule": "coil current: quasi-static hold limit (F - m g) * min(rho, mu r_G) = "
                      "sqrt(last success * first failure) of each thesis table",
              "effective_gap_m": MAGNET_EFFECTIVE_GAP_M, "chapters": {}}

    # ---------------- chapter 2: Table 2.3 rows, the line profile with (T1, T2) as printed
    sc2 = load_scenario("thesis-ch2")
    rows2 = []
    for m_print, T1, T2, res in TABLE_2_3:
        plan = ch2_plan(sc2, T1, T2)
        r = run_row(sc2, plan, 1.0)
        rows2.append(dict(table="2.3", peak_moment_thesis_Nm=m_print, T1=T1, T2=T2,
                          peak_moment_sim_plan_Nm=r.peak_moment_planned_Nm, thesis=res,
                          sim="held" if r.held else "lost", max_slip_m=r.max_slip_m, max_tilt_rad=r.max_tilt_rad,
                          detached_at_s=r.detached_at_s, max_tracking_error_rad=r.max_tracking_error_rad,
                          peak_motor_torque_Nm=[float(x) for x in r.peak_motor_torque_Nm],
                          coil_current_A=r.coil_current_A))
        print(f"ch2 T1={T1} T2={T2} M={r.peak_moment_planned_Nm:.4g} thesis={res} sim={'held' if r.held else 'lost'} "
              f"slip={r.max_slip_m*1e3:.3f} mm tilt={r.max_tilt_rad:.4f}", flush=True)

    # ---------------- chapter 4: Table 4.2 rows, the GA move time-scaled to each row's moment
    sc4 = load_scenario("thesis-ch4")
    plan4 = GenesPlan(sc4, CH4_GA_GENES, method="ga_thesis_genes")
    m4_1 = planned_peak_moment_Nm(sc4, plan4, 1.0)
    rows4 = []
    for m_print, res in TABLE_4_2:
        s = math.sqrt(m4_1 / m_print)
        r = run_row(sc4, plan4, s)
        rows4.append(dict(table="4.2", peak_moment_thesis_Nm=m_print, time_scale=s,
                          peak_moment_sim_plan_Nm=r.peak_moment_planned_Nm, thesis=res,
                          sim="held" if r.held else "lost", max_slip_m=r.max_slip_m, max_tilt_rad=r.max_tilt_rad,
                          detached_at_s=r.detached_at_s, max_tracking_error_rad=r.max_tracking_error_rad,
                          peak_motor_torque_Nm=[float(x) for x in r.peak_motor_torque_Nm],
                          coil_current_A=r.coil_current_A))
        print(f"ch4 scale={s:.4f} M={r.peak_moment_planned_Nm:.4g} thesis={res} sim={'held' if r.held else 'lost'} "
              f"slip={r.max_slip_m*1e3:.3f} mm tilt={r.max_tilt_rad:.4f}", flush=True)

    # ---------------- thresholds by bisection in peak moment, each with its chapter's own profile
    v = 0.07
    l0 = 0.20

    def ch2_plan_for_moment(M):
        # Same family and v_xmax: peak accel 1.5 v / T1 = M / (m r_G); T1 + T2 = l0 / v.
        T1 = 1.5 * v * sc2.moment_per_accel_kgm / M
        return ch2_plan(sc2, T1, l0 / v - T1)

    def held2(M):
        return run_row(sc2, ch2_plan_for_moment(M), 1.0).held

    def held4(M):
        return run_row(sc4, plan4, math.sqrt(m4_1 / M)).held

    thr = {}
    for ch, rows, held_fn in (("ch2", rows2, held2), ("ch4", rows4, held4)):
        ms = sorted(rows, key=lambda d: d["peak_moment_thesis_Nm"])
        held_ms = [d["peak_moment_sim_plan_Nm"] for d in ms if d["sim"] == "held"]
        lost_ms = [d["peak_moment_sim_plan_Nm"] for d in ms if d["sim"] == "lost"]
        monotone = not held_ms or not lost_ms or max(held_ms) < min(lost_ms)
        if held_ms and lost_ms and monotone:
            lo, hi = threshold_by_bisection(None, held_fn, max(held_ms), min(lost_ms), n_bisect)
        else:
            lo, hi = (max(held_ms) if held_ms else float("nan")), (min(lost_ms) if lost_ms else float("nan"))
        b_lo, b_hi = SLIP_BOUNDARIES_NM[ch]
        thr[ch] = dict(sim_threshold_between_Nm=[lo, hi], thesis_boundary_Nm=[b_lo, b_hi],
                       monotone=monotone, inside=bool(monotone and lo >= b_lo and hi <= b_hi),
                       agree_rows=sum((d["thesis"] == "success") == (d["sim"] == "held") for d in rows),
                       n_rows=len(rows))
        print(ch, thr[ch], flush=True)

    # ---------------- sweep for the figure: max slip against peak moment
    sweep = {"ch2": [], "ch4": []}
    for M in np.geomspace(2.2e-5, 4.4e-5, n_sweep):
        r = run_row(sc2, ch2_plan_for_moment(M), 1.0)
        sweep["ch2"].append((float(M), r.max_slip_m, r.held))
    for M in np.geomspace(0.45e-3, 1.05e-3, n_sweep):
        r = run_row(sc4, plan4, math.sqrt(m4_1 / M))
        sweep["ch4"].append((float(M), r.max_slip_m, r.held))

    for ch, sc, rows in (("ch2", sc2, rows2), ("ch4", sc4, rows4)):
        spec = PayloadSpec.for_scenario(sc)
        report["chapters"][ch] = dict(
            scenario=sc.name, coil=HAND_COIL[ch].name, coil_turns=HAND_COIL[ch].turns,
            coil_resistance_ohm=HAND_COIL[ch].resistance_ohm, coil_current_A=rows[0]["coil_current_A"],
            coil_voltage_V=rows[0]["coil_current_A"] * HAND_COIL[ch].resistance_ohm,
            payload=spec.name, mass_kg=spec.mass_kg, r_G_m=spec.com_offset_m, contact_radius_m=spec.contact_radius_m,
            friction=spec.friction, hold_lever_m=hold_lever_m(spec), rows=rows, threshold=thr[ch], sweep=sweep[ch])
    report["control"] = {"ch2": control_report(sc2, (1.59, 0.51)), "ch4": control_report(sc4, CH4_GA_GENES)}
    # One shared supply voltage? ratio of the two calibrated voltages
    v2 = report["chapters"]["ch2"]["coil_voltage_V"]
    v4 = report["chapters"]["ch4"]["coil_voltage_V"]
    report["voltage_ratio_ch2_over_ch4"] = v2 / v4
    # Counterfactual: both coils on one supply voltage (the other hand's calibrated one), quasi-static.
    from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2 as GRAVITY_M_S2
    from qmt_drake.systems.electromagnet import MagnetParams
    cf = {}
    for ch, sc, v_other in (("ch2", sc2, v4), ("ch4", sc4, v2)):
        spec = PayloadSpec.for_scenario(sc)
        coil = HAND_COIL[ch]
        f = MagnetParams(coil, MAGNET_EFFECTIVE_GAP_M, spec.face_radius_m).force_N(v_other / coil.resistance_ohm)
        hold = (f - spec.mass_kg * GRAVITY_M_S2) * hold_lever_m(spec)
        cf[ch] = dict(supply_V=v_other, pull_N=f, weight_N=spec.mass_kg * GRAVITY_M_S2, hold_moment_Nm=hold,
                      thesis_boundary_Nm=list(SLIP_BOUNDARIES_NM[ch]))
    report["shared_voltage_counterfactual"] = cf
    print("one supply voltage for both hands (quasi-static):", cf)
    report["wall_s"] = time.perf_counter() - t0
    (out / "cosim_calibration.json").write_text(json.dumps(report, indent=1, default=float))

    lines = ["| table | peak moment thesis [N m] | profile | thesis | simulated | max slip [mm] | max tilt [rad] |",
             "|---|---|---|---|---|---|---|"]
    for d in rows2:
        lines.append(f"| 2.3 | {d['peak_moment_thesis_Nm']:.3e} | T1={d['T1']}, T2={d['T2']} | {d['thesis']} | "
                     f"{d['sim']} | {d['max_slip_m']*1e3:.3f} | {d['max_tilt_rad']:.4f} |")
    for d in rows4:
        lines.append(f"| 4.2 | {d['peak_moment_thesis_Nm']:.3e} | GA move x{d['time_scale']:.4f} in time | "
                     f"{d['thesis']} | {d['sim']} | {d['max_slip_m']*1e3:.3f} | {d['max_tilt_rad']:.4f} |")
    for ch in ("ch2", "ch4"):
        t = thr[ch]
        lines.append(f"\n{ch}: simulated threshold between {t['sim_threshold_between_Nm'][0]:.4e} and "
                     f"{t['sim_threshold_between_Nm'][1]:.4e} N m; thesis boundary {t['thesis_boundary_Nm'][0]:.4e}"
                     f"..{t['thesis_boundary_Nm'][1]:.4e}; inside: {t['inside']}; rows agreeing "
                     f"{t['agree_rows']}/{t['n_rows']}")
    (out / "cosim_calibration.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, ch in zip(axes, ("ch2", "ch4")):
        sw = np.array([(m, s) for m, s, _ in sweep[ch]])
        held = np.array([h for _, _, h in sweep[ch]])
        ax.semilogy(sw[:, 0], np.maximum(sw[:, 1], 1e-6) * 1e3, "-", color="0.6", lw=1)
        ax.semilogy(sw[held, 0], np.maximum(sw[held, 1], 1e-6) * 1e3, "o", color="tab:blue", label="sim held")
        ax.semilogy(sw[~held, 0], np.maximum(sw[~held, 1], 1e-6) * 1e3, "x", color="tab:red", ms=8, label="sim lost")
        rows = report["chapters"][ch]["rows"]
        rm = np.array([d["peak_moment_sim_plan_Nm"] for d in rows])
        rs = np.array([max(d["max_slip_m"], 1e-6) * 1e3 for d in rows])
        rh = np.array([d["sim"] == "held" for d in rows])
        ax.semilogy(rm[rh], rs[rh], "s", mfc="none", mec="tab:blue", ms=9, label="thesis row, sim held")
        ax.semilogy(rm[~rh], rs[~rh], "s", mfc="none", mec="tab:red", ms=9, label="thesis row, sim lost")
        for d in rows:
            ax.axvline(d["peak_moment_thesis_Nm"], color="tab:green" if d["thesis"] == "success" else "tab:red",
                       ls=":", lw=0.8)
        b_lo, b_hi = SLIP_BOUNDARIES_NM[ch]
        ax.axvspan(b_lo, b_hi, color="0.85", zorder=0, label="thesis boundary")
        ax.axhline(1.0, color="k", ls="--", lw=0.8, label="1 mm")
        ax.set_xlabel("planned peak payload moment [N m]")
        ax.set_ylabel("max slip along the face [mm]")
        ax.set_title(f"{ch}: {report['chapters'][ch]['payload']} (dotted: thesis rows, green success / red failure)",
                     fontsize=8)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "cosim_calibration_slip.png", dpi=120)
    print(f"wrote {out}/cosim_calibration.json, .md, _slip.png in {report['wall_s']:.0f} s")


if __name__ == "__main__":
    main()
