"""The main job (`make run`): every chapter of seed 000, the five-via task, the co-simulation
calibration, the benchmark and the planner bench into OUT (default out/), then one report of
everything, OUT/report.html. Each step writes its results as it finishes (a rerun reuses finished
GA runs); a step that fails is reported and the others still run."""

import argparse
import sys
import time
import traceback
from pathlib import Path

from qmt_drake import malloc_tuning


def _log(msg):
    print(msg, file=sys.stderr, flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", default="out")
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    malloc_tuning.tune()  # as the command line does: the GA's and the simulator's temporaries (malloc_tuning.py)
    out = Path(a.out)
    failed = []

    def step(name, fn):
        _log(f"=== {name}")
        t0 = time.perf_counter()
        try:
            fn()
        except Exception:
            traceback.print_exc()
            failed.append(name)
        _log(f"--- {name}: {time.perf_counter() - t0:.0f} s")

    from qmt_drake.apps.thesis_study import run_chapter
    for ch in ("thesis-ch2", "thesis-ch3", "thesis-ch4"):
        step(ch, lambda ch=ch: run_chapter(ch, out, seeds=a.seeds, workers=a.workers,
                                           progress=_log))
    from studies import via_points
    step("via5-ch4", lambda: via_points.main(["--out", str(out), "--seeds", str(a.seeds),
                                              "--workers", str(a.workers)]))
    try:
        from studies import cosim_calibration
        step("co-simulation calibration", lambda: cosim_calibration.main(["--out", str(out)]))
    except ImportError as exc:
        _log(f"co-simulation calibration unavailable: {exc}")
    try:
        from qmt_drake.apps.benchmark import run_benchmark
        step("benchmark", lambda: run_benchmark(out_dir=out / "benchmark", progress=_log))
    except ImportError as exc:
        _log(f"benchmark unavailable: {exc}")
    from qmt_drake.apps.bench import run_bench
    step("bench", lambda: run_bench(out_dir=out, progress=_log))
    # Seeds 001-003 and the sweeps (issues 10-13).
    from studies import ohsaka_1988
    step("seed 001: Ohsaka & Kurahashi 1988", lambda: ohsaka_1988.main(["--out", str(out / "ohsaka_1988")]))
    from studies import crane_tray
    step("seed 002: CRANE-X7 tray", lambda: crane_tray.main(["--out", str(out / "crane_tray")]))
    from studies import tray_carried
    step("seed 002: fastest carried through the servos, per friction and fill",
         lambda: tray_carried.main(["--out", str(out)]))
    from studies import kotosaka_1995
    step("seed 003: Kotosaka et al. 1995", lambda: kotosaka_1995.main(["--out", str(out / "kotosaka_1995")]))
    step("seed 003: exhaustive certificate of the GA (BP, Task-1)",
         lambda: kotosaka_1995.main(["--out", str(out / "kotosaka_1995"), "--skip-search",
                                     "--exhaustive", "BP:task1_welding_plate"]))
    step("seed 003: co-design of the ch.4 arm",
         lambda: kotosaka_1995.main(["--out", str(out / "kotosaka_1995"), "--codesign"]))
    from studies import success_probability
    step("success probability (Dask)", lambda: success_probability.main(
        ["--out", str(out), "--cases", "50", "--workers", str(a.workers), "--robust", "thesis-ch4"]))
    from studies import spatial_benchmark
    step("spatial arms: UR5 with a suction cup and with the magnet, Panda with a cup on a tray", lambda: spatial_benchmark.main(
        ["--out", str(out)]))
    from studies import bench_spatial
    step("spatial arms: the batched hand state and TOPP-RA against Drake (planning speed)",
         lambda: bench_spatial.main(["--out", str(out)]))
    from studies import spatial_ga_seeds
    step("spatial arms: the GA over 10 seeds against the family optimum (UR5, suction)",
         lambda: spatial_ga_seeds.main(["--out", str(out)]))
    from qmt_drake.apps.report import build_report
    step("report", lambda: _log(f"report: {build_report(out)}"))
    if failed:
        _log(f"steps that failed: {', '.join(failed)}")
        return 1
    _log(f"all results in {out}/ (open {out}/report.html)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
