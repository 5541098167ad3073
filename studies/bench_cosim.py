"""Real-time factor of the chapter-4 closed loop (PD + DC motors + gears + arm + magnet + payload in
friction contact) against the plant's time step.

For each step size the thesis GA move (genes 0.622/0.532/0.562 s, 1.716 s, plus 0.2 s lead and 0.5 s
settle) is simulated `--repeats` times; the fastest wall time is kept (the machine is shared). The
loop's outcome at each step (held, slip, tracking error) is printed too: the thesis-gain position
loop is stiff (poles out to -900 rad/s), and sampled at 2 ms it is unstable: the motors chatter
between their +-6 A current limits (both ch.4 joints get the RE 30) from the first steps on and
shake the part off, while the tracking error stays small (the chatter is fast). So 1 ms is the
largest usable step; the contact solve costs about as much as everything else together (compare
the run without contact).

Writes out/bench_cosim.json. Run: .venv/bin/python studies/bench_cosim.py [--repeats 3]
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

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from qmt_drake.cosim import GenesPlan, build_transfer_diagram, make_result, run_diagram  # noqa: E402
from qmt_drake.errors import QmtSimulationError  # noqa: E402
from qmt_drake.scenario import load_scenario  # noqa: E402

STEPS_S = (0.25e-3, 0.5e-3, 1e-3, 2e-3, 4e-3)


def bench(time_step_s: float, repeats: int, with_contact: bool = True) -> dict:
    sc = load_scenario("thesis-ch4")
    plan = GenesPlan(sc, (0.622, 0.532, 0.562), method="thesis_ga")
    walls, cpus, res = [], [], None
    for _ in range(repeats):
        kw = {} if with_contact else {"coil_current_A": 0.0}
        td = build_transfer_diagram(sc, plan, time_step_s=time_step_s, log_period_s=0, **kw)
        c0 = time.process_time()
        try:
            summary, wall = run_diagram(td)
        except QmtSimulationError as exc:
            return dict(time_step_s=time_step_s, with_contact=with_contact, error=str(exc))
        cpus.append(time.process_time() - c0)
        walls.append(wall)
        res = make_result(sc, plan, td, summary, wall, 1.0, time_step_s, {})
    best = min(walls)
    return dict(time_step_s=time_step_s, with_contact=with_contact, sim_time_s=res.sim_time_s,
                wall_s_best=best, wall_s_all=walls, real_time_factor=res.sim_time_s / best,
                cpu_s_best=min(cpus), real_time_factor_cpu=res.sim_time_s / min(cpus),
                us_per_step=best / (res.sim_time_s / time_step_s) * 1e6, held=res.held,
                max_slip_m=res.max_slip_m, max_tracking_error_rad=res.max_tracking_error_rad,
                peak_motor_torque_Nm=[float(x) for x in res.peak_motor_torque_Nm])


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "out"))
    args = ap.parse_args(argv)
    rows = []
    for dt in STEPS_S:
        r = bench(dt, args.repeats)
        rows.append(r)
        if "error" in r:
            print(f"dt={dt*1e3:.2f} ms: {r['error']}", flush=True)
        else:
            print(f"dt={dt*1e3:.2f} ms: real-time factor {r['real_time_factor']:.2f} wall, "
                  f"{r['real_time_factor_cpu']:.2f} by CPU time ({r['us_per_step']:.0f} us/step), "
                  f"held={r['held']} slip={r['max_slip_m']*1e3:.3f} mm track={r['max_tracking_error_rad']:.4f} rad",
                  flush=True)
    base = bench(1e-3, args.repeats, with_contact=False)
    rows.append(base)
    print(f"dt=1.00 ms without payload contact (coil off, part falls away): real-time factor "
          f"{base['real_time_factor']:.2f} wall, {base['real_time_factor_cpu']:.2f} by CPU time "
          f"({base['us_per_step']:.0f} us/step)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    info = dict(machine=platform.platform(), cpus=os.cpu_count(), python=platform.python_version(),
                note=("best of repeats; the machine was shared with other jobs, so wall times vary by ~2x run to "
                      "run; real_time_factor_cpu uses this process's CPU time"),
                when=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), rows=rows)
    (out / "bench_cosim.json").write_text(json.dumps(info, indent=1))
    print(f"wrote {out / 'bench_cosim.json'}")


if __name__ == "__main__":
    main()
