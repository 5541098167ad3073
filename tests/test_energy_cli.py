"""plan-energy CLI adapter: results, JSON and one-line input errors (exit 2)."""

import json

import pytest

from qmt_drake.apps.cli import main


@pytest.mark.parametrize("argv,msg", [
    (["--c2", "0"], "no stable solution"), (["--c2", "-1"], "c2 = -1"), (["--c1", "-1"], "c1 = -1"),
    (["--m", "0"], "m = 0"), (["--coords", "0.7", "0", "0", "0.9"], "out of reach"),
    (["--pattern", "xyz"], "--pattern"), (["--divisions", "1"], "divisions"),
])
def test_bad_input_exit_2_one_line(capsys, argv, msg):
    assert main(["plan-energy", "ohsaka-fig3", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and "\n" not in err and "Traceback" not in err


def test_one_pattern_json(tmp_path, capsys):
    path = tmp_path / "r.json"
    assert main(["plan-energy", "ohsaka-fig3", "--pattern", "npn", "--json", str(path)]) == 0
    d = json.loads(path.read_text())
    (opt,) = d["optima"]
    assert opt["success"] and opt["start"] == "(-,+,-)"
    assert opt["z"] == pytest.approx(1e5 * opt["T_s"] + opt["energy"], rel=1e-12)
