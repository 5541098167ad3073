"""Session 16, an outsider's inputs: scenarios and files nobody here wrote, each either working or refused
in one line naming the input and the fix (exit 2), before any long work. Each test is a defect found
by feeding such an input to the command line or the API (tracebacks, silent acceptance, wrong answers)."""

import time

import pytest
import yaml

from qmt_drake.apps.cli import main
from qmt_drake.config.scenario import SCENARIO_DIR
from qmt_drake.errors import QmtInputError
from qmt_drake.spatial_data import parse_spatial_data


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


def test_plan_misspelt_kind_is_one_line(tmp_path, capsys):
    # `kind: spatial` reached the planner registry's message table: KeyError 'spatial' (a traceback)
    path = _spatial_yaml(tmp_path, kind="spatial")
    line = _refused(capsys, "plan", path, "--method", "toppra")
    assert "kind 'spatial' is not a scenario kind" in line and "spatial_transfer" in line


def test_spatial_name_must_be_a_string(tmp_path):
    # `name: [1, 2]` was taken as the scenario's name "[1, 2]" (into every plan file and message)
    with pytest.raises(QmtInputError, match=r"name must be a non-empty string, got \[1, 2\]"):
        parse_spatial_data(_spatial_yaml(tmp_path, name=[1, 2]))


def test_lock_joints_listed_twice_is_refused(tmp_path):
    # a joint named twice in lock_joints was accepted silently (the joint the user meant stays free)
    path = _spatial_yaml(tmp_path, base="panda-tray-cup",
                         arm__lock_joints=["panda_finger_joint1", "panda_finger_joint1"])
    with pytest.raises(QmtInputError, match=r"lock_joints names \['panda_finger_joint1'\] more than once"):
        parse_spatial_data(path)
