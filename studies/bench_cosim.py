"""Real-time factor of the chapter-4 closed loop (PID + DC motors + gears + arm + magnet + payload in
friction contact) against the plant's time step, for both stepping schemes.

For each scheme and step the thesis GA move (genes 0.622/0.532/0.562 s, 1.716 s, plus 0.2 s lead and
0.5 s settle) is simulated `--repeats` times; the fastest wall time is kept (the machine is shared).
Each row also says what the step does to the result, against the motors driving the plant
explicitly at 0.25 ms: held or not, slip, tracking error, peak motor torques.

  * explicit: the motors' torque goes straight into the plant. The thesis-gain position loop is
    stiff (poles out to -900 rad/s); sampled at 2 ms it is unstable (the motors chatter between
    their current limits and shake the part off), so 1 ms is its largest usable step.
  * implicit loop damping (the default, cosim.add_implicit_damping_actuation): the loop's velocity
    feedback is stepped implicitly by the plant; stable at 2-4 ms with the same motion and motor
    torques. With the payload's coordinates relative to the hand a held part no longer drifts with
    the step (studies/contact_drift.py); what limits the step is the accuracy of the motor torques
    and energy against the 0.25 ms reference (the table's last columns): 2 ms is the default.

Writes out/bench_cosim.json. Run: .venv/bin/python -m studies.bench_cosim [--repeats 5]
"""

from __future__ import annotations

import os

# One BLAS thread: numpy's OpenBLAS workers otherwise spin on the second core between the tiny
# matrix products of the Python systems (seen in `perf` as blas_thread_server).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from qmt_drake import malloc_tuning  # noqa: E402
from qmt_drake.errors import QmtSimulationError  # noqa: E402
from qmt_drake.outputs import write_text_atomic  # noqa: E402
from qmt_drake.sim import IMPLICIT_TIME_STEP_S, GenesPlan, build_transfer_diagram, make_result, run_diagram  # noqa: E402
from qmt_drake.transfer_scenario import load_scenario  # noqa: E402

EXPLICIT_STEPS_S = (0.25e-3, 0.5e-3, 1e-3, 2e-3)
IMPLICIT_STEPS_S = (1e-3, 2e-3, 3e-3, 4e-3)


def bench(time_step_s: float, repeats: int, *, implicit: bool, with_contact: bool = True) -> dict:
    sc = load_scenario("thesis-ch4")
    plan = GenesPlan(sc, (0.622, 0.532, 0.562), method="thesis_ga")
    walls, cpus, res = [], [], None
    row = dict(scheme="implicit loop damping" if implicit else "explicit", time_step_s=time_step_s,
               with_contact=with_contact)
    for _ in range(repeats):
        kw = {} if with_contact else {"coil_current_A": 0.0}
        # step_logs: what simulate_transfer runs (the explicit scheme keeps the per-step monitor)
        td = build_transfer_diagram(sc, plan, time_step_s=time_step_s, implicit_loop_damping=implicit,
                                    log_period_s=0, step_logs=True, allow_unstable_step=True, **kw)
        c0 = time.process_time()
        try:
            summary, wall = run_diagram(td)
        except QmtSimulationError as exc:
            return dict(row, error=str(exc))
        cpus.append(time.process_time() - c0)
        walls.append(wall)
        res = make_result(sc, plan, td, summary, wall, 1.0, {})
    best = min(walls)
    return dict(row, sim_time_s=res.sim_time_s, wall_s_best=best, wall_s_all=walls,
                real_time_factor=res.sim_time_s / best,
                real_time_factor_median=res.sim_time_s / float(np.median(walls)), cpu_s_best=min(cpus),
                real_time_factor_cpu=res.sim_time_s / min(cpus),
                us_per_step=best / (res.sim_time_s / time_step_s) * 1e6, held=res.held,
                max_slip_m=res.max_slip_m, max_tracking_error_rad=res.max_tracking_error_rad,
                peak_motor_torque_Nm=[float(x) for x in res.peak_motor_torque_Nm], energy_J=res.energy_J)


def compare_to_reference(row: dict, ref: dict) -> None:
    """Relative deviations of a row's results from the fine explicit reference, in place."""
    if "error" in row or "error" in ref:
        return
    row["vs_reference"] = dict(
        held_same=row["held"] == ref["held"],
        tracking_error_rel=row["max_tracking_error_rad"] / ref["max_tracking_error_rad"] - 1.0,
        peak_motor_torque_rel=[a / b - 1.0 for a, b in zip(row["peak_motor_torque_Nm"], ref["peak_motor_torque_Nm"])],
        energy_rel=row["energy_J"] / ref["energy_J"] - 1.0,
        slip_ratio=row["max_slip_m"] / ref["max_slip_m"])


def describe(r: dict) -> str:
    head = f"{r['scheme']:22s} dt={r['time_step_s'] * 1e3:.2f} ms"
    if "error" in r:
        return f"{head}: {r['error']}"
    text = (f"{head}: real-time factor {r['real_time_factor']:.2f} wall (median of runs "
            f"{r['real_time_factor_median']:.2f}), {r['real_time_factor_cpu']:.2f} by CPU time ({r['us_per_step']:.0f} us/step), held={r['held']} slip={r['max_slip_m'] * 1e3:.3f} mm "
            f"track={r['max_tracking_error_rad'] * 1e3:.2f} mrad "
            f"motor={[round(x * 1e3, 2) for x in r['peak_motor_torque_Nm']]} mN m")
    if "vs_reference" in r:
        v = r["vs_reference"]
        text += (f" | vs 0.25 ms explicit: motor {max(abs(x) for x in v['peak_motor_torque_rel']) * 100:.1f}%, "
                 f"energy {v['energy_rel'] * 100:+.1f}%, slip x{v['slip_ratio']:.2f}")
    return text


def main(argv=None):
    malloc_tuning.tune()  # as the command line does (qmt_drake/malloc_tuning.py)
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "out"))
    args = ap.parse_args(argv)
    from qmt_drake.errors import QmtInputError
    from qmt_drake.outputs import check_output_dir
    try:  # before any simulation: a folder that cannot be written stops here, in one line
        check_output_dir(args.out, "--out")
    except QmtInputError as exc:
        print(f"{ap.prog}: error: {exc}", file=sys.stderr)
        return 2
    rows = [bench(dt, args.repeats, implicit=False) for dt in EXPLICIT_STEPS_S[:1]]
    ref = rows[0]
    print(describe(ref), flush=True)
    for dt in EXPLICIT_STEPS_S[1:]:
        rows.append(bench(dt, args.repeats, implicit=False))
        compare_to_reference(rows[-1], ref)
        print(describe(rows[-1]), flush=True)
    for dt in IMPLICIT_STEPS_S:
        rows.append(bench(dt, args.repeats, implicit=True))
        compare_to_reference(rows[-1], ref)
        print(describe(rows[-1]), flush=True)
    base = bench(IMPLICIT_TIME_STEP_S, args.repeats, implicit=True, with_contact=False)
    rows.append(base)
    print(f"without payload contact (coil off, the part falls away), {describe(base)}", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    info = dict(machine=platform.platform(), cpus=os.cpu_count(), python=platform.python_version(),
                note=("best of repeats; wall times on a shared machine vary by up to ~1.5x run to run; "
                      "real_time_factor_cpu uses this process's CPU time. Default scheme: implicit loop damping at "
                      f"{IMPLICIT_TIME_STEP_S * 1e3:g} ms; target: real-time factor >= 5"),
                default_time_step_s=IMPLICIT_TIME_STEP_S, target_real_time_factor=5.0,
                when=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), rows=rows)
    write_text_atomic(out / "bench_cosim.json", json.dumps(info, indent=1))
    print(f"wrote {out / 'bench_cosim.json'}")


if __name__ == "__main__":
    sys.exit(main())
