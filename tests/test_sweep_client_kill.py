"""The sweep CLI's client killed mid-sweep (SIGKILL: no clean-up of any kind), then rerun: the rerun
finishes every case and recomputes none of those stored before the kill (their files are left
untouched). Real co-simulations: 8 cheap ch.4 cases on one LocalCluster worker."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SPEC = """name: killed-client
scenario: thesis-ch4
plans:
  - {method: thesis}
parameters:
  friction: [0.20, 0.22, 0.24, 0.26, 0.28, 0.30, 0.32, 0.34]
  time_scale: [0.8]
"""
N_CASES = 8


def _cli(args, **kw):
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    return subprocess.Popen([sys.executable, "-m", "qmt_drake.apps.cli", "sweep", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, **kw)  # own group: its workers are cleaned up with it


def _stop_group(proc):
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # the client's session: it and the LocalCluster it started
    except ProcessLookupError:
        pass
    proc.wait(30)


def test_killed_client_then_rerun_recomputes_nothing_finished(tmp_path):
    spec = tmp_path / "killed-client.yaml"
    spec.write_text(SPEC)
    cases = tmp_path / "out" / "killed-client" / "cases"
    first = _cli([str(spec), "--out", str(tmp_path / "out"), "--workers", "1", "--no-figures", "--quiet"])
    try:
        deadline = time.time() + 120
        while time.time() < deadline and len(list(cases.glob("*.json"))) < 2 and first.poll() is None:
            time.sleep(0.02)
        assert first.poll() is None, f"the sweep ended before it could be killed: {first.communicate()}"
        os.kill(first.pid, signal.SIGKILL)  # the client only
        first.wait(30)
    finally:
        _stop_group(first)
    assert first.returncode == -signal.SIGKILL
    before = {p.name: (p.stat().st_ino, p.stat().st_mtime_ns, p.read_text()) for p in cases.glob("*.json")}
    assert 2 <= len(before) < N_CASES, f"{len(before)} cases stored at the kill: nothing left to show"
    assert not [p for p in cases.iterdir() if not p.name.endswith(".json") and not p.name.startswith(".")]

    rerun = _cli([str(spec), "--out", str(tmp_path / "out"), "--workers", "1", "--no-figures", "--quiet",
                  "--json", str(tmp_path / "rerun.json")])
    try:
        out, err = rerun.communicate(timeout=180)
    finally:
        _stop_group(rerun)
    assert rerun.returncode == 0, err[-2000:]
    summary = json.loads((tmp_path / "rerun.json").read_text())
    assert summary["from_store"] == len(before)
    assert summary["computed"] == N_CASES - len(before) and summary["failed"] == 0
    after = {p.name: p for p in cases.glob("*.json")}
    assert len(after) == N_CASES
    for name, (ino, mtime, text) in before.items():  # finished before the kill: not written again
        st = after[name].stat()
        assert (st.st_ino, st.st_mtime_ns) == (ino, mtime) and after[name].read_text() == text
    assert sum(r["n"] for r in summary["rows"]) == N_CASES
