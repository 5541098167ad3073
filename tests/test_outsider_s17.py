"""Session 17, an outsider's inputs to the Python API, retime/export files, hand-edited plan files and
scenario sections: each either works or is refused in one line naming the input and the fix (exit 2),
before any long work. Each test is a defect found by feeding such an input (a traceback, a silent
acceptance, a wrong answer, a refusal only after seconds of building)."""

import time

import pytest
import yaml

from qmt_drake.apps import spatial_cli
from qmt_drake.apps.cli import main
from qmt_drake.config.scenario import SCENARIO_DIR
from qmt_drake.errors import QmtInputError


def _spatial_yaml(tmp_path, base="ur5-suction-bins", file="s.yaml", **changes) -> str:
    """A shipped spatial scenario with `changes` (section__key: value; value None deletes the key)."""
    raw = yaml.safe_load((SCENARIO_DIR / f"{base}.yaml").read_text())
    for path, value in changes.items():
        d = raw
        keys = path.split("__")
        for k in keys[:-1]:
            d = d[k]
        if value is None:
            d.pop(keys[-1], None)
        else:
            d[keys[-1]] = value
    p = tmp_path / file
    p.write_text(yaml.safe_dump(raw))
    return str(p)


def _refused(capsys, *argv, within_s=5.0) -> str:
    """The one line a refused command prints (exit 2, no traceback), within `within_s`."""
    t = time.perf_counter()
    rc = main([str(a) for a in argv])
    dt = time.perf_counter() - t
    _, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and "Traceback" not in err, (rc, err)
    assert dt < within_s, dt
    return lines[0]


def _no_build(monkeypatch):
    """Building the arm (URDF, IK of every path point: ~9 s on ANYmal + Kinova) fails the test."""
    def build(data):
        raise AssertionError("the scenario was built before the refusal")
    monkeypatch.setattr(spatial_cli, "build_spatial_scenario", build)


@pytest.mark.parametrize("argv", [
    ["simulate", "{p}", "--actuator", "dc_motor"],
    ["plan", "{p}", "--method", "toppra", "--carried", "--carried-feedforward", "full"],
])
def test_dc_motor_without_motor_section_refused_before_building(tmp_path, capsys, monkeypatch, argv):
    # the refusal came only after the arm was built (IK of every path point): ~9 s on ANYmal + Kinova
    path = _spatial_yaml(tmp_path, actuators__motor=None)
    _no_build(monkeypatch)
    line = _refused(capsys, *[a.format(p=path) for a in argv])
    assert "actuator dc_motor needs actuators.motor" in line
