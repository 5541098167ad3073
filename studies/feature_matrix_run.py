"""Running one cell of studies/feature_matrix.py and classifying it: ok (exit 0, or 3 with its output),
refused (exit 2, its message), error (a traceback, a timeout, another exit, or an exit 0 that ignored the
option); the GA cell's Ctrl-C at the first progress line and its resume."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from studies.feature_matrix_cells import Cell


@dataclass
class Result:
    status: str  # ok | refused | error
    rc: int | None
    message: str
    seconds: float
    one_line: bool = True


def expand(argv: list) -> list:
    """'qmt-drake' -> this interpreter running the CLI module; 'python' -> this interpreter."""
    if argv and argv[0] == "qmt-drake":
        return [sys.executable, "-m", "qmt_drake.apps.cli", *argv[1:]]
    if argv and argv[0] == "python":
        return [sys.executable, *argv[1:]]
    return list(argv)


def run_step(argv: list, cwd: Path, timeout: float, env: dict | None = None) -> tuple[int | None, str, str, float]:
    """(exit code or None on timeout, stdout, stderr, seconds); the step's whole process group is killed
    on timeout (a sweep's Dask workers included)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(expand(argv), cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        out, err = proc.communicate()
        rc = None
    return rc, out, err, time.perf_counter() - t0


def _error_line(stderr: str) -> str:
    lines = [x.strip() for x in stderr.splitlines() if x.strip()]
    errs = [x for x in lines if re.match(r"^(qmt-drake|usage)?[\w -]*: error: ", x) or x.startswith("qmt-drake: error")]
    line = errs[-1] if errs else (lines[-1] if lines else "")
    return re.sub(r"^[\w -]*: error: ", "", line)


def traceback_summary(stderr: str) -> str:
    """The exception line of the last traceback and the innermost project frame ('file:line')."""
    i = stderr.rfind("Traceback (most recent call last)")
    tail = stderr[i:].splitlines()
    frames = [re.search(r'File "([^"]+)", line (\d+)', x) for x in tail]
    ours = [m for m in frames if m and ("qmt_drake" in m.group(1) or "studies" in m.group(1))]
    exc = next((x.strip() for x in reversed(tail) if x.strip() and not x.startswith(" ")), "?")
    where = f" (at {Path(ours[-1].group(1)).name}:{ours[-1].group(2)})" if ours else ""
    return exc + where


def classify(rc: int | None, stdout: str, stderr: str, missing: list, seconds: float, timeout: float) -> Result:
    """ok / refused / error of one finished step (module docstring)."""
    if rc is None:
        return Result("error", None, f"timeout after {timeout:g} s", seconds)
    if "Traceback (most recent call last)" in stderr:
        return Result("error", rc, traceback_summary(stderr), seconds, one_line=False)
    if rc in (0, 3):
        if missing:
            return Result("error", rc, f"exit {rc} but {', '.join(missing)} not written", seconds)
        return Result("ok", rc, "" if rc == 0 else "exit 3: limits no plan meets, least-violating plan written",
                      seconds)
    if rc == 2:
        lines = [x for x in stderr.splitlines() if x.strip()]
        usage = [x for x in lines if x.startswith(("usage:", " "))]  # argparse prints its usage first
        return Result("refused", rc, _error_line(stderr), seconds, one_line=len(lines) - len(usage) == 1)
    last = _error_line(stderr) or (stdout.strip().splitlines() or [""])[-1]
    return Result("error", rc, f"exit {rc}: {last}", seconds)



def run_interrupted(argv: list, cwd: Path, timeout: float, pattern: str = r"generation \d+"):
    """Run `argv` and press Ctrl-C (SIGINT to the process) at its first stderr line matching `pattern`
    (at the latest after `timeout`); (exit code or None, stdout, stderr, seconds, interrupted)."""
    t0 = time.perf_counter()
    with open(cwd / "interrupted.stdout", "w+") as out_f:
        # SIGINT back to its default in the child: a shell's `&` starts jobs with SIGINT ignored, and a Python
        # child that inherits SIG_IGN installs no KeyboardInterrupt handler, so the Ctrl-C would be lost
        proc = subprocess.Popen(expand(argv), cwd=cwd, stdout=out_f, stderr=subprocess.PIPE, text=True,
                                start_new_session=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        lines, seen = [], threading.Event()

        def read():
            for line in proc.stderr:
                lines.append(line)
                if re.search(pattern, line):
                    seen.set()
        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        while not seen.is_set() and proc.poll() is None and time.perf_counter() - t0 < timeout:
            seen.wait(0.2)
        interrupted = proc.poll() is None
        if interrupted:
            proc.send_signal(signal.SIGINT)
        try:
            rc = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            rc = None
        reader.join(10)
        out_f.seek(0)
        out = out_f.read()
    return rc, out, "".join(lines), time.perf_counter() - t0, interrupted


_ANY = object()


def _holds(x, key: str, subkey: str | None, value=_ANY) -> bool:
    """Some mapping inside `x` has `key` (whose value is a mapping holding `subkey`, when given; equal to
    `value`, when given)."""
    if isinstance(x, dict):
        if key in x and (subkey is None or (isinstance(x[key], dict) and subkey in x[key])) and (
                value is _ANY or x[key] == value):
            return True
        return any(_holds(v, key, subkey, value) for v in x.values())
    if isinstance(x, list):
        return any(_holds(v, key, subkey, value) for v in x)
    return False


def check_evidence(c: Cell, d: Path, res: Result) -> Result:
    if c.evidence is None or res.status != "ok":
        return res
    fname, key, subkey, *value = c.evidence
    try:
        found = _holds(json.loads((d / fname).read_text()), key, subkey, *value)
    except (OSError, ValueError):
        found = False
    if found:
        return res
    what = f"'{key}'" + (f" with '{subkey}'" if subkey else "") + (f" = {value[0]!r}" if value else "")
    return Result("error", res.rc, f"exit {res.rc} but {fname} holds no {what}: the option was ignored (or its "
                  "use is not recorded)", res.seconds)


def _checkpoint_generation(path: Path) -> int | None:
    try:
        return int(json.loads(path.read_text())["generation"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def run_steps(c: Cell, d: Path, timeout: float) -> tuple[Result, list]:
    res, steps = None, []
    for i, step in enumerate(c.steps):
        mode = step.get("mode", "run") if isinstance(step, dict) else "run"
        argv = list(step["argv"] if isinstance(step, dict) else step)
        last = i == len(c.steps) - 1
        missing = [f for f in c.expect if not (d / f).exists()] if last else []
        if mode == "interrupt":
            rc, out, err, dt, hit = run_interrupted(argv, d, timeout)
            res = classify(rc, out, err, [], dt, timeout) if rc is not None else Result(
                "error", None, "did not stop within 60 s of Ctrl-C", dt)
            if res.status != "refused" and "Traceback (most recent call last)" not in err and rc is not None:
                ckpt = d / argv[argv.index("--checkpoint") + 1]
                if ckpt.is_file():
                    res = Result("ok", rc, f"Ctrl-C {'sent' if hit else 'after the run ended'}, checkpoint kept", dt)
                else:
                    res = Result("error", rc, f"no checkpoint after Ctrl-C{'' if hit else ' (no progress line seen)'}"
                                 f" (exit {rc}): {_error_line(err)}", dt)
        else:
            if mode == "resume":
                ckpt = d / argv[argv.index("--checkpoint") + 1]
                gen = _checkpoint_generation(ckpt)
                argv = [str((gen or 3) + 2) if w == "{GEN}" else w for w in argv]
            rc, out, err, dt = run_step(argv, d, timeout)
            missing = [f for f in c.expect if not (d / f).exists()] if last else []
            res = classify(rc, out, err, missing, dt, timeout)
            if last:
                res = check_evidence(c, d, res)
            if mode == "resume" and res.status == "ok" and not re.search(r"resum", err, re.I):
                res = Result("error", rc, "finished but did not say it resumed from the checkpoint", dt)
        steps.append({"argv": argv, "rc": rc, "seconds": round(dt, 2), "stderr_tail": err.strip().splitlines()[-3:]})
        if res.status != "ok":
            if len(c.steps) > 1:
                res.message = f"step {i + 1}: {res.message}"
            break
    return res, steps
