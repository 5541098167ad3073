"""`--scheduler`: the same sweep on a separately started Dask scheduler and worker processes
(as on other machines), with one worker process killed while cases run: every case finishes."""

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from qmt_drake.sweep.runner import run_sweep
from qmt_drake.sweep.spec import load_spec

ROOT = Path(__file__).resolve().parent.parent
DASK = Path(sys.executable).with_name("dask")


def slow_plan(ref):
    return {"plan_key": ref.key}


def slow_case(case, plan_doc):
    import os
    import time
    time.sleep(0.3)
    return {"key": case.key, "label": case.label, "parameters": case.parameters, "status": "ok",
            "held": True, "max_slip_m": 1e-4, "motion_time_s": 1.0, "pid": os.getpid()}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.skipif(not DASK.exists(), reason="dask command-line tool not installed beside python")
def test_external_scheduler_survives_a_killed_worker(tmp_path):
    port = free_port()
    addr = f"tcp://127.0.0.1:{port}"
    # the workers import qmt_drake and, for the fake case functions, this test module
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "tests")]), OPENBLAS_NUM_THREADS="1")
    procs = []
    try:
        procs.append(subprocess.Popen([str(DASK), "scheduler", "--port", str(port), "--dashboard-address", ":0"],
                                      env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        procs.append(subprocess.Popen([str(DASK), "worker", addr, "--nthreads", "1", "--nworkers", "2",
                                       "--dashboard-address", ":0"],
                                      env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        spec = load_spec({"name": "remote", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
                          "parameters": {"friction": [0.2 + 0.01 * i for i in range(16)]}})
        import threading
        result = {}
        t = threading.Thread(target=lambda: result.update(run_sweep(
            spec, tmp_path, scheduler=addr, case_fn=slow_case, plan_fn=slow_plan, progress=False,
            figures=False, connect_timeout_s=30)))
        t.start()
        cases = tmp_path / "remote" / "cases"
        deadline = time.time() + 60
        while time.time() < deadline and len(list(cases.glob("*.json"))) < 3:
            time.sleep(0.1)
        # kill one worker process (a child of the `dask worker` process) while cases run
        kids = subprocess.run(["pgrep", "-P", str(procs[1].pid)], capture_output=True, text=True).stdout.split()
        assert kids, "no worker processes found"
        os.kill(int(kids[0]), signal.SIGKILL)
        t.join(120)
        assert not t.is_alive()
        assert result["computed"] == 16 and result["failed"] == 0, result["failures"][0]["error"]
        assert len({r["pid"] for r in result["results"]}) >= 2
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
