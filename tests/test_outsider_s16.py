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


def _ur5_text() -> str:
    from qmt_drake.model.urdf_package import example_robot_urdf
    return example_robot_urdf("ur5")[0].read_text()


_PAN_LIMIT = '<limit effort="150.0" lower="-6.28318530718" upper="6.28318530718" velocity="3.15"/>'


@pytest.mark.parametrize("old, new, needle", [
    # each reached Drake's parser: a bare ValueError traceback, or (lower > upper) a C++ assertion, exit 1
    ('<axis xyz="0 0 1"/>', '<axis xyz="0 0 nan"/>', r"'shoulder_pan_joint' <axis xyz=\"0 0 nan\">: give three"),
    ('xyz="0.0 0.0 0.089159"', 'xyz="0.0 0.0 nan"', r"'shoulder_pan_joint' <origin xyz=\"0.0 0.0 nan\">: give three"),
    (_PAN_LIMIT, '<limit effort="150" lower="1" upper="-1" velocity="3.15"/>', "the lower limit exceeds the upper one"),
    (_PAN_LIMIT, '<limit effort="150" lower="-1" upper="1" velocity="fast"/>', r"<limit velocity=\"fast\">: give a fin"),
    # read as a branch ("movable joints ... are not on the chain"): the misspelt link was not named
    ('<child link="forearm_link"/>', '<child link="nolink"/>', "names child link 'nolink', which the URDF does not"),
    # a mimic joint on the chain was planned as an independent joint (a motion the robot cannot make)
    ('<axis xyz="0 1 0"/>\n    <limit effort="28.0"', '<axis xyz="0 1 0"/>\n    <mimic joint="elbow_joint"/>\n'
     '    <limit effort="28.0"', "chain joint 'wrist_1_joint' mimics 'elbow_joint'"),
])
def test_malformed_urdf_joint_is_one_line(old, new, needle):
    from qmt_drake.model.urdf_check import load_arm_plant
    text = _ur5_text()
    assert old in text
    with pytest.raises(QmtInputError, match=needle):
        load_arm_plant(text.replace(old, new, 1), "tool0", source="ur5 edited")


def test_urdf_without_links_says_so():
    # a xacro file (or ur3.urdf of example-robot-data 6.0, an empty <robot>) was answered "name one of []"
    from qmt_drake.model.urdf_check import load_arm_plant
    with pytest.raises(QmtInputError, match=r"declares no <link> \(a xacro file"):
        load_arm_plant('<robot name="x"><xacro:include xmlns:xacro="x" filename="a.xacro"/></robot>', "tool0")


_JOINTS = ["j1", "j2", "j3"]
_ROWS = "0.1,0.2,0.3\n0.4,0.5,0.6\n"


def test_retime_csv_with_a_byte_order_mark_reads(tmp_path):
    # a spreadsheet's CSV ("CSV UTF-8") starts with U+FEFF: its first joint was '\ufeffj1', "not a joint of the arm"
    from qmt_drake.joint_path_files import read_joint_path
    p = tmp_path / "p.csv"
    p.write_text("\ufeffj1,j2,j3\n" + _ROWS, encoding="utf-8")
    assert read_joint_path(p, _JOINTS).tolist() == [[0.1, 0.2, 0.3], [0.4, 0.5, 0.6]]


@pytest.mark.parametrize("content, needle", [
    (bytes(range(256)), "not a text file"),                       # was a UnicodeDecodeError traceback
    (b"j1,j2,j1\n" + _ROWS.encode(), "joint 'j1' is named twice"),  # was "no column for joint 'j3'"
    (b"j1;j2;j3\n0.1;0.2;0.3\n0.4;0.5;0.6\n", "columns separated by ';'"),  # was joint 'j1;j2;j3' unknown
    (_ROWS.encode(), "the first row holds numbers, not joint names"),  # was joint '0.1' unknown
])
def test_retime_csv_mistakes_named(tmp_path, content, needle):
    from qmt_drake.joint_path_files import read_joint_path
    p = tmp_path / "p.csv"
    p.write_bytes(content)
    with pytest.raises(QmtInputError, match=needle):
        read_joint_path(p, _JOINTS)


@pytest.mark.parametrize("argv, needle", [
    # each was refused only after the plan and the whole search (minutes), naming no flag
    (["--success-max-scale", "0.5"], "--success-max-scale 0.5 must exceed 1"),
    (["--success-check-cases", "100000000"], "--success-check-cases 100000000: sweep spec"),
    (["--success-check-cases", "100000"], "--success-check-cases 100000: a sweep of 100000 cases"),
    # could never confirm the target (all 10 carried: lower bound 0.78 < 0.9): the search ran, then the check missed
    (["--success-check-cases", "10"], "--success-check-cases 10 cannot confirm P >= 0.9"),
])
def test_success_options_refused_before_planning(tmp_path, capsys, monkeypatch, argv, needle):
    from qmt_drake.apps import spatial_cli

    def no_planning(*_a, **_k):
        raise AssertionError("planned before refusing")
    monkeypatch.setattr(spatial_cli, "_plan", no_planning)
    line = _refused(capsys, "plan", "ur5-suction-bins", "--method", "toppra", "--success", "0.9",
                    "--success-out", tmp_path / "s", *argv, within_s=60)
    assert needle in line


def test_success_search_cases_that_cannot_certify_refused(tmp_path, capsys, monkeypatch):
    # monte_carlo.cases 4 for P >= 0.9: 4/4 carried gives a lower bound 0.51, so the search could only fail
    from qmt_drake.apps import spatial_cli
    monkeypatch.setattr(spatial_cli, "_plan", lambda *_a, **_k: pytest.fail("planned before refusing"))
    path = _spatial_yaml(tmp_path, uncertainty__monte_carlo={"cases": 4, "seed": 1})
    line = _refused(capsys, "plan", path, "--method", "toppra", "--success", "0.9", "--success-out", tmp_path / "s",
                    within_s=60)
    assert "uncertainty.monte_carlo.cases gives 4 cases" in line and "give >= 35" in line


def test_cases_to_certify_is_the_wilson_bound_of_all_successes():
    from qmt_drake.sweep.stats import cases_to_certify, wilson_interval
    for target in (0.1, 0.5, 0.8, 0.9, 0.95, 0.99):
        n = cases_to_certify(target)
        assert wilson_interval(n, n)[0] >= target and (n == 1 or wilson_interval(n - 1, n - 1)[0] < target)
    assert cases_to_certify(0.9) == 35


def test_success_line_says_when_the_fresh_check_misses():
    # "P(carried) 2/3 on fresh cases, 95 % Wilson lower bound 0.208" was all a --success 0.5 run printed
    from qmt_drake.apps.spatial_cli import success_text
    miss = {"carried": 2, "cases": 3, "ci_low": 0.208, "meets_target": False}
    assert "BELOW the target 0.5: not confirmed" in success_text(miss, 1.0, 0.5)
    assert "BELOW" not in success_text({**miss, "carried": 40, "cases": 40, "ci_low": 0.912, "meets_target": True},
                                       1.0, 0.9)


def test_two_outputs_on_one_file_refused(tmp_path, capsys):
    # --json and --trajectory-csv on one path: the CSV silently replaced the plan file
    same = tmp_path / "p.out"
    line = _refused(capsys, "plan", "ur5-suction-bins", "--method", "toppra", "--json", same, "--trajectory-csv", same)
    assert "--json and --trajectory-csv both name" in line and not same.exists()


def test_output_over_an_input_refused(tmp_path, capsys):
    # `plan my.yaml --json my.yaml` replaced the user's scenario with the plan
    path = _spatial_yaml(tmp_path)
    before = (tmp_path / "s.yaml").read_text()
    line = _refused(capsys, "plan", path, "--method", "toppra", "--json", path)
    assert "is the scenario file: writing it would replace the input" in line
    assert (tmp_path / "s.yaml").read_text() == before


def test_misspelt_spatial_builtin_lists_every_builtin(capsys):
    # was: "transfer scenario 'ur5-suction-binz' is neither a built-in (crane-tray, thesis-ch2, ...)": the planar
    # list only, without the spatial scenario the user meant
    line = _refused(capsys, "plan", "ur5-suction-binz", "--method", "toppra")
    assert "ur5-suction-bins" in line and "did you mean ur5-suction-bins?" in line and "transfer scenario" not in line


def test_infeasible_by_collision_names_the_collision():
    # a plan within every limit that collides was labelled "binding limit joint_acceleration[...] at 0.9999 of it"
    from types import SimpleNamespace

    from qmt_drake.apps.spatial_cli import infeasible_text
    rc = {"max": 0.9999, "binding": "joint_acceleration[j2]"}
    hit = SimpleNamespace(recheck=rc, clearance={"clearance_m": -0.13})
    assert "collides with world.obstacles" in infeasible_text(hit) and "0.9999" not in infeasible_text(hit)
    broke = SimpleNamespace(recheck={**rc, "max": 1.2}, clearance={"clearance_m": -0.13})
    assert "binding limit joint_acceleration[j2] at 1.2" in infeasible_text(broke)


def test_yaml_error_says_where_and_names_a_tab(tmp_path):
    # was "not valid YAML (while scanning for the next token)": no line, no cause
    p = tmp_path / "t.yaml"
    p.write_text("kind: spatial_transfer\narm:\n\tpackage: example-robot-data/ur5\n")
    with pytest.raises(QmtInputError, match=r"at line 3, column 1; indent with spaces, not tabs"):
        parse_spatial_data(p)
    q = tmp_path / "path.yaml"  # a JointTrajectory for retime: the same phrase
    q.write_text("joint_names: [j1, j2, j3\npoints: []\n")
    from qmt_drake.joint_path_files import read_joint_path
    with pytest.raises(QmtInputError, match=r"not YAML/JSON \(.* at line 2, column"):
        read_joint_path(q, _JOINTS)


def test_transfer_points_on_a_task_without_a_carry_refused(tmp_path):
    # two poses with transfer_points: 5 (the fix a branch-change refusal suggests) was silently ignored
    path = _spatial_yaml(tmp_path, task__poses_m=[[0.45, -0.3, 0.1], [0.45, 0.3, 0.1]], task__transfer_points=5)
    with pytest.raises(QmtInputError, match=r"transfer_points 5: .* this task has 2 poses; add the points"):
        parse_spatial_data(path)


@pytest.mark.parametrize("verb, what", [("sweep", "a sweep spec"), ("design", "a design task")])
def test_scenario_file_given_as_a_spec_or_task_is_named(tmp_path, capsys, verb, what):
    # was "unknown key 'actuators'; allowed keys are ..." (the scenario's first key the other file lacks)
    path = _spatial_yaml(tmp_path)
    line = _refused(capsys, verb, path, "--out", tmp_path / "out")
    assert f"is a scenario file, not {what}" in line


def test_plan_file_with_another_n_dof_names_it(tmp_path):
    import json

    from qmt_drake import load_scenario, plan_with
    from qmt_drake.retime import load_plan_file
    sc = load_scenario("ur5-suction-bins")
    f = tmp_path / "p.json"
    plan_with("ruckig", sc).write_json(f)
    d = json.loads(f.read_text())
    d["n_dof"] = 7  # edited by hand
    f.write_text(json.dumps(d))
    with pytest.raises(QmtInputError, match="n_dof 7"):
        load_plan_file(f, sc)
