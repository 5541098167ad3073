"""studies/feature_matrix.py: the cell list covers every kind x feature, the classifier tells a refusal
from a defect (tiny fake commands), a rerun skips the cells already in the JSON, and a few cheap real
cells run."""

from __future__ import annotations

import json
import sys

import pytest

from studies import feature_matrix as fm


def _py(code: str) -> list:
    return [sys.executable, "-c", code]


def _run(code: str, tmp_path, timeout: float = 60.0, missing=()):
    rc, out, err, dt = fm.run_step(_py(code), tmp_path, timeout)
    return fm.classify(rc, out, err, list(missing), dt, timeout)


def test_cells_cover_every_kind_and_feature():
    cells = fm.all_cells()
    keys = [c.key for c in cells]
    assert len(keys) == len(set(keys)) == len(fm.FEATURES) * len(fm.KINDS)
    assert {(c.feature, c.kind) for c in cells} == {(f, k) for f in fm.FEATURES for k in fm.KINDS}
    assert set(fm.KINDS) == {"planar magnet", "tray", "energy-time", "UR5 suction", "UR5 magnet", "Panda tray"}
    for c in cells:
        assert c.steps and c.shown()
        scenario = fm.KINDS[c.kind][0]
        # every cell runs the kind's own scenario (by name, or a copy of its YAML, or a spec naming it)
        assert scenario in c.shown() or c.prep, c.key


def test_a_traceback_is_an_error(tmp_path):
    r = _run("def f():\n    raise ValueError('boom')\nf()", tmp_path)
    assert (r.status, r.rc) == ("error", 1)
    assert r.message.startswith("ValueError: boom")


def test_a_one_line_exit_2_is_a_refusal(tmp_path):
    r = _run("import sys; print('qmt-drake: error: --x 3: not for this arm; drop it', file=sys.stderr); sys.exit(2)",
             tmp_path)
    assert (r.status, r.message, r.one_line) == ("refused", "--x 3: not for this arm; drop it", True)
    # argparse's refusal: its usage lines, then one error line
    r = _run("import argparse; p = argparse.ArgumentParser(prog='qmt-drake plan'); p.parse_args(['--nope'])", tmp_path)
    assert r.status == "refused" and r.one_line and "unrecognized arguments: --nope" in r.message


def test_exit_codes_and_outputs(tmp_path):
    assert _run("pass", tmp_path).status == "ok"
    assert _run("import sys; sys.exit(3)", tmp_path).status == "ok"
    r = _run("import sys; sys.exit(3)", tmp_path, missing=["plan.json"])
    assert r.status == "error" and "plan.json not written" in r.message
    r = _run("import sys; print('odd', file=sys.stderr); sys.exit(5)", tmp_path)
    assert (r.status, r.message) == ("error", "exit 5: odd")
    r = _run("import time; time.sleep(30)", tmp_path, timeout=0.5)
    assert (r.status, r.rc) == ("error", None) and "timeout" in r.message


def test_ctrl_c_at_the_first_progress_line(tmp_path):
    """run_interrupted sends SIGINT once the progress line is out; the fake GA writes its checkpoint then."""
    code = ("import sys, time\n"
            "try:\n    print('generation 1 of at most 9', file=sys.stderr, flush=True)\n    time.sleep(30)\n"
            "except KeyboardInterrupt:\n    open('ga.ckpt', 'w').write('{\"generation\": 7}')\n    sys.exit(130)\n")
    rc, out, err, dt, hit = fm.run_interrupted(_py(code), tmp_path, timeout=20)
    assert (rc, hit) == (130, True) and dt < 20
    assert fm._checkpoint_generation(tmp_path / "ga.ckpt") == 7


def test_rerun_skips_cells_in_the_json_and_writes_the_table(tmp_path):
    key = "plan --method thesis|planar magnet"
    row = {"feature": "plan --method thesis", "kind": "planar magnet", "scenario": "thesis-ch4",
           "command": fm.cell("plan --method thesis", "planar magnet").shown(), "status": "refused", "rc": 2,
           "message": "a message no judgement knows", "one_line": True, "seconds": 1.0, "steps": []}
    js, md = tmp_path / "m.json", tmp_path / "m.md"
    js.write_text(json.dumps({"cells": {key: row}}))
    assert fm.main(["--json", str(js), "--md", str(md), "--only", "plan --method thesis", "--kinds", "thesis-ch4"]) == 0
    assert json.loads(js.read_text())["cells"] == {key: row}  # skipped, not rerun
    text = md.read_text()
    assert all(f"| {f} |" in text for f in fm.FEATURES)
    assert "a message no judgement knows | not judged" in text


@pytest.mark.parametrize("feature", ["plan --method thesis", "overrides (API)"])
def test_cheap_real_cells_run(tmp_path, feature):
    """The reported genes and the API's overrides on the thesis arm (a few seconds each): both work today."""
    row = fm.run_cell(fm.cell(feature, "planar magnet"), tmp_path, fm.Bases(tmp_path, 120), 120)
    assert (row["status"], row["rc"]) == ("ok", 0), row["message"]


def test_a_real_refusal_is_one_line(tmp_path):
    """An energy-time solver on the thesis arm: refused in one line (or, once it plans, a plan); never a defect."""
    row = fm.run_cell(fm.cell("plan --method snopt", "planar magnet"), tmp_path, fm.Bases(tmp_path, 120), 120)
    assert row["status"] in ("ok", "refused"), row["message"]
    if row["status"] == "refused":
        assert row["one_line"] and row["message"] and row["rc"] == 2


def test_an_ignored_option_is_an_error(tmp_path):
    """Exit 0 without the feature's trace in its output (e.g. --success silently dropped) is a defect."""
    c = fm.cell("plan --success P", "planar magnet")
    ok = fm.Result("ok", 0, "", 1.0)
    (tmp_path / "plan.json").write_text(json.dumps({"optima": [{"success": True}]}))
    r = fm.check_evidence(c, tmp_path, ok)
    assert r.status == "error" and "option was ignored" in r.message
    (tmp_path / "plan.json").write_text(json.dumps({"extra": {"success": {"search": {}, "fresh_check": {}}}}))
    assert fm.check_evidence(c, tmp_path, ok) is ok


def test_a_simulate_option_must_show_in_its_result(tmp_path):
    c = fm.cell("simulate --time-step-ms", "planar magnet")
    ok = fm.Result("ok", 0, "", 1.0)
    (tmp_path / "sim.json").write_text(json.dumps({"time_step_s": 0.002}))
    assert fm.check_evidence(c, tmp_path, ok).status == "error"
    (tmp_path / "sim.json").write_text(json.dumps({"run": {"time_step_s": 0.001}}))
    assert fm.check_evidence(c, tmp_path, ok) is ok
