"""Bad inputs of `qmt-drake design` through the real command line (issue 12, Must show): each exits
2 with exactly one line on stderr, no traceback, before any search."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
UNIT = "{name: P, position_m: [0.5, 0, 0.2], rpy_deg: [180, 0, 0], work: [x, y], constrained: [z]}"


def _run(args, cwd):
    env = {"PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"}
    return subprocess.run([sys.executable, "-m", "qmt_drake.apps.cli", "design", *args], cwd=cwd,
                          env=env, capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("case,args,match", [
    ("unknown type", ["peg_in_hole", "--types", "XQ"], "unknown"),
    ("excluded type", ["peg_in_hole", "--types", "BP,FB"], "not among"),
    ("unknown type in --design", ["peg_in_hole", "--design", "ZZ:0db000"], "unknown"),
    ("direction not a unit axis", ["dir.yaml"], "not a unit axis"),
    ("level above 15", ["peg_in_hole", "--design", "BP:0,13,11,0,0,16"], "integers 0-15"),
    ("negative level", ["peg_in_hole", "--design", "BP:0,-1,11,0,0,0"], "integers 0-15"),
    ("gene not hex", ["peg_in_hole", "--design", "BP:0dg000"], "six hex digits"),
    ("wrist offset L5", ["peg_in_hole", "--design", "BP:0db010"], "L5"),
    ("point out of every design's reach", ["far.yaml"], "no design"),
    ("point inside the work", ["inside.yaml"], "inside box"),
    ("generations", ["peg_in_hole", "--generations", "0,5"], "MAX must be"),
])
def test_bad_input_exits_2_with_one_line(tmp_path, case, args, match):
    (tmp_path / "dir.yaml").write_text("units:\n  - " + UNIT.replace("[x, y]", "[x, xy]") + "\n")
    (tmp_path / "far.yaml").write_text("units:\n  - " + UNIT.replace("[0.5, 0, 0.2]", "[6.0, 4.5, 2.0]") + "\n")
    (tmp_path / "inside.yaml").write_text(
        "units:\n  - " + UNIT + "\nwork_boxes:\n  - {name: plate, center_m: [0.5, 0, 0.2], size_m: [0.2, 0.2, 0.1]}\n")
    r = _run(args, tmp_path)
    assert r.returncode == 2, (case, r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("qmt-drake: error:") and match in lines[0], (case, r.stderr)
    assert "Traceback" not in r.stderr and not list(tmp_path.glob("out*"))
