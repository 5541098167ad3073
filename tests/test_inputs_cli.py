"""Every bad input of issue 9's list, through the CLI: one line naming the input and the fix, exit 2,
before any long computation (a GA of 10,000 generations would take minutes: these run in
milliseconds because the check comes first). BAD_INPUTS.md lists the same inputs and lines."""

import json
import time

import pytest

from qmt_drake.apps.cli import EXPLICIT_MAX_TIME_STEP_MS, main
from tests.scenario_files import scenario_yaml


def _run(capsys, *argv):
    t = time.perf_counter()
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err, time.perf_counter() - t


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


_yaml = scenario_yaml


@pytest.fixture()
def a_file(tmp_path):
    f = tmp_path / "a_file"
    f.write_text("x")
    return f


# The default GA runs 10,000 generations: any of these that started planning first would take minutes.
@pytest.mark.parametrize("argv, needle", [
    (["plan", "thesis-ch4", "--json", "{file}/p.json"], "--json {file}/p.json: {file} is a file, not a folder"),
    (["plan", "thesis-ch4", "--json", "{dir}"], "--json {dir} is a directory"),
    (["plan", "thesis-ch4", "--trajectory-csv", "/proc/nowhere/t.csv"], "cannot create folder /proc/nowhere"),
    (["plan", "thesis-ch4", "--checkpoint", "/proc/c.json"], "--checkpoint /proc/c.json: folder /proc is not writable"),
    (["simulate", "thesis-ch4", "--record", "{file}/r.html"], "--record {file}/r.html: {file} is a file"),
    (["simulate", "thesis-ch4", "--json", "/proc/x/r.json"], "--json /proc/x/r.json: cannot create folder"),
    (["benchmark", "--out", "{file}"], "--out {file}: {file} is a file, not a folder"),
    (["bench", "--out", "/proc/x"], "--out /proc/x: cannot create folder"),
    (["plan", "thesis-ch4", "--seed", "-1"], "--seed -1 must be >= 0"),
    (["simulate", "thesis-ch4", "--seed", "-1"], "--seed -1 must be >= 0"),
    (["plan", "thesis-ch4", "--generations", "0"], "--generations 0 must be >= 1"),
    (["plan", "thesis-ch4", "--stall", "-5"], "--stall -5 must be >= 0"),
    (["simulate", "thesis-ch4", "--time-scale", "inf"], "--time-scale inf must be a finite positive number"),
    (["simulate", "thesis-ch4", "--time-scale", "nan"], "--time-scale nan must be a finite positive number"),
    (["simulate", "thesis-ch4", "--time-scale", "0"], "--time-scale 0.0 must be a finite positive number"),
    (["simulate", "thesis-ch4", "--time-scale", "-2"], "--time-scale -2.0 must be a finite positive number"),
    (["simulate", "thesis-ch4", "--time-step-ms", "inf"], "--time-step-ms inf must be a finite positive"),
    (["simulate", "thesis-ch4", "--explicit", "--time-step-ms", "2"], "known unstable above 1 ms"),
    (["bench", "--seeds", "0"], "--seeds 0 must be >= 1"),
    (["benchmark", "--ga-seeds", "-1"], "--ga-seeds -1 must be >= 0"),
    (["benchmark", "--jerk-limits", "0"], "--jerk-limits 0.0 must be a finite positive number"),
    (["plan", "thesis-ch4", "--method", "thesis", "--checkpoint", "c.json"], "--checkpoint: not an option of the planar thesis planner (the planners that take it: planar ga"),
    (["plan", "thesis-ch4", "--option", "novalue"], "--option 'novalue' must be KEY=VALUE"),
])
def test_bad_argument_is_refused_before_any_work(tmp_path, a_file, capsys, argv, needle):
    fill = {"file": str(a_file), "dir": str(tmp_path)}
    rc, _, err, wall = _run(capsys, *[a.format(**fill) for a in argv])
    assert rc == 2
    assert needle.format(**fill) in _one_line(err)
    assert wall < 5.0  # refused before planning or simulating


def test_explicit_step_limit_agrees_with_the_simulation():
    from qmt_drake.sim import EXPLICIT_MAX_TIME_STEP_S
    assert EXPLICIT_MAX_TIME_STEP_MS * 1e-3 == EXPLICIT_MAX_TIME_STEP_S


@pytest.mark.parametrize("content, needle", [
    ("{not json", "unreadable or corrupt (JSONDecodeError"),
    ("[1, 2]", "unreadable or corrupt (ValueError: not a qmt_drake GA checkpoint"),
    ('{"scenario": "thesis-ch4", "seed": 0}', "unreadable or corrupt (ValueError: not a qmt_drake GA checkpoint"),
    ('{"format": "qmt_drake GA checkpoint 2", "run": "abc"}', "belongs to another run"),
])
def test_corrupt_or_foreign_checkpoint(tmp_path, capsys, content, needle):
    ck = tmp_path / "ck.json"
    ck.write_text(content)
    rc, _, err, wall = _run(capsys, "plan", "thesis-ch4", "--checkpoint", ck, "--quiet")
    assert rc == 2 and needle in _one_line(err) and wall < 5.0


def test_checkpoint_of_the_same_scenario_is_accepted(tmp_path, capsys):
    from qmt_drake.transfer_scenario import load_scenario
    ck = tmp_path / "ck.json"
    rc, _, err, _ = _run(capsys, "plan", "thesis-ch4", "--generations", "3", "--checkpoint", ck, "--quiet")
    assert rc == 0, err
    if ck.exists():  # the GA writes one every N generations; with a fingerprint it must match
        state = json.loads(ck.read_text())
        assert state.get("scenario_fingerprint", load_scenario("thesis-ch4").fingerprint()) == \
            load_scenario("thesis-ch4").fingerprint()


def test_ctrl_c_exits_130_with_one_line(monkeypatch, capsys):
    import qmt_drake.apps.cli as cli
    import qmt_drake.apps.plan_command as plan_command

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(plan_command.registry, "plan", interrupted)  # the call cmd_plan makes
    rc, _, err, _ = _run(capsys, "plan", "thesis-ch4", "--quiet")
    assert rc == cli.EXIT_INTERRUPTED == 130
    assert _one_line(err).startswith("qmt-drake: interrupted")


@pytest.mark.parametrize("changes, needle", [
    ({"payload__mass_kg": True}, "payload.mass_kg must be a number, got True"),
    ({"payload__com_offset_m": "28 mm"}, "payload.com_offset_m must be a number, got '28 mm'"),
    ({"task__points_m": [[0.17, 0.20, 0.0], [-0.18, 0.10]]}, "task.points_m[0] has 3 coordinates"),
    ({"task__points_m": [[0.17, 0.20], [-0.18]]}, "task.points_m[1] has 1 coordinates"),
    ({"task__points_m": "start to goal"}, "task.points_m must be a list of at least two [x, y] points"),
    ({"task__points_m": [[0.17, True], [-0.18, 0.1]]}, "task.points_m[0] must hold numbers, got True"),
    ({"control__kp": [29.7]}, "control.kp has 1 entries but the arm (two_link_ch4.urdf) has 2 joints"),
    ({"control__kp": "stiff"}, "control.kp must be a list of numbers"),
    ({"control__kd": [104.0, True]}, "control.kd must be a list of numbers"),
    ({"limits__motor_torque_limit_Nm": [0.064, 0.032, 0.01]},
     "limits.motor_torque_limit_Nm has 3 entries but the arm (two_link_ch4.urdf) has 2 joints"),
    ({"limits__moment_limit_Nm": True}, "limits.moment_limit_Nm must be a number, got True"),
    ({"ga__population": "fifty"}, "ga.population must be an integer, got 'fifty'"),
    ({"ga__population": 50.0}, "ga.population must be an integer, got 50.0"),
    ({"ga__max_generations": True}, "ga.max_generations must be an integer, got True"),
    ({"ga__mutation_rate": [0.1]}, "ga.mutation_rate must be a number"),
    ({"ga__elite_count": 50}, "ga.elite_count 50 must be below the population 50"),
    ({"sampling": {"check_rate_hz": "fast"}}, "sampling.check_rate_hz must be a number"),
    ({"family__genes": {"T1": ["a", 3.0], "T2": [0.5, 3.0], "T3": [0.5, 3.0]}},
     "family.genes.T1 must be [min, max]"),
    ({"family__genes": "T1 T2 T3"}, "family.genes must map gene names"),
    ({"family__kind": 3}, "family.kind 3 is not one of"),
    ({"task__ik_branch": ["up"]}, "task.ik_branch ['up'] is not one of"),
    ({"arm__urdf": 5}, "arm.urdf must be a file path, got 5"),
    ({"arm__hand_frame": 7}, "arm.hand_frame must be a frame name, got 7"),
    ({"arm__kind": "generated"}, "arm.kind 'generated' is not available"),
    ({"hand__coil": "table_9"}, "hand.coil 'table_9' is not one of"),
    ({"hand__coil_current_A": 0.4}, "give exactly one of slip_boundary_Nm"),
    ({"hand__slip_boundary_Nm": [0.7e-3, 0.6e-3]}, "first below the second"),
    ({"hand__friction": "dry"}, "hand.friction must be a number"),
    ({"hand__kind": "tray"}, "hand.kind 'tray' is not available"),
    ({"actuator__motors": ["maxon_RE30_60W_24V"]}, "actuator.motors has 1 entries but the arm"),
    ({"actuator__motors": ["maxon_RE99", "maxon_RE30_60W_24V"]}, "actuator.motors: 'maxon_RE99' is not in the catalogue"),
    ({"actuator__kind": "servo"}, "actuator.kind 'servo' is not one of dc_motor_gear, ideal, dynamixel"),
    ({"payload__body": {"kind": "cylinder", "length_m": 0.05}}, "payload.body: missing key 'radius_m'"),
    ({"payload__body": "bolt"}, "payload.body must be a mapping"),
    ({"task": 5}, "'task' must be a mapping, got 5"),
    ({"ga": [1, 2]}, "'ga' must be a mapping"),
    ({"name": 12}, "name must be a non-empty string, got 12"),
    ({"notes": "one"}, "notes must be a list of strings"),
    ({"reported__genes": [0.6, 0.5, 0.5]}, "reported.genes must map gene names to numbers"),
    ({"reported__genes": {"T1": "fast", "T2": 0.5, "T3": 0.5}}, "reported.genes must map gene names to numbers"),
    ({"reported__motion_time_s": "1.7 s"}, "reported.motion_time_s must be a number"),
    ({"reported": 3}, "'reported' must be a mapping, got 3"),
])
def test_bad_scenario_value_is_one_line(tmp_path, capsys, changes, needle):
    rc, _, err, _ = _run(capsys, "plan", _yaml(tmp_path, **changes), "--method", "thesis")
    assert rc == 2
    assert needle in _one_line(err)


@pytest.mark.parametrize("content, needle", [
    (b"", "the file is empty"),
    (b"\xff\xfe\x00\x81 not text", "not a UTF-8 text file"),
    (b"- a\n- list\n", "a scenario file must be a YAML mapping"),
    (b"name: [unclosed\n", "not valid YAML"),
])
def test_bad_scenario_file_is_one_line(tmp_path, capsys, content, needle):
    p = tmp_path / "s.yaml"
    p.write_bytes(content)
    rc, _, err, _ = _run(capsys, "plan", p, "--method", "thesis")
    assert rc == 2 and needle in _one_line(err)


def test_directory_as_scenario_or_urdf_is_one_line(tmp_path, capsys):
    rc, _, err, _ = _run(capsys, "plan", tmp_path, "--method", "thesis")
    assert rc == 2 and "is a directory" in _one_line(err)
    rc, _, err, _ = _run(capsys, "plan", _yaml(tmp_path, arm__urdf=str(tmp_path)), "--method", "thesis")
    assert rc == 2 and "arm.urdf" in _one_line(err) and "is a directory" in err


@pytest.mark.parametrize("urdf, needle", [
    ("this is not XML", "is not a well-formed URDF"),
    ("<robot name='r'><link name='a'/><joint/></robot>", "Drake cannot parse this URDF"),
    (b"\xff\xfe<robot/>", "is not a well-formed URDF"),
])
def test_urdf_that_is_not_xml_is_one_line(tmp_path, capsys, urdf, needle):
    u = tmp_path / "arm.urdf"
    (u.write_bytes if isinstance(urdf, bytes) else u.write_text)(urdf)
    rc, _, err, _ = _run(capsys, "plan", _yaml(tmp_path, arm__urdf=str(u)), "--method", "thesis")
    assert rc == 2 and needle in _one_line(err) and "arm.urdf" in err


# ------------------------------------------------------------------------------------ plan files
@pytest.fixture(scope="module")
def plan_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("plans")
    for name, method in (("thesis-ch4", "thesis"), ("thesis-ch2", "thesis"), ("thesis-ch4", "ruckig")):
        assert main(["plan", name, "--method", method, "--json", str(d / f"{name}-{method}.json"),
                     "--quiet"]) == 0
    return d


def _edit(src, dst, fn):
    d = json.loads(src.read_text())
    fn(d)
    dst.write_text(json.dumps(d))
    return dst


def test_plan_file_against_other_task_points(tmp_path, capsys, plan_files):
    other = _yaml(tmp_path, task__points_m=[[0.17, 0.19], [0.08, 0.16], [-0.10, 0.12], [-0.18, 0.10]])
    for f in ("thesis-ch4-thesis.json", "thesis-ch4-ruckig.json"):
        rc, _, err, _ = _run(capsys, "simulate", other, "--plan", plan_files / f)
        assert rc == 2 and "was made for task points" in _one_line(err)
    # A file written before the points were stored: a sampled plan is checked by where it starts.
    old = _edit(plan_files / "thesis-ch4-ruckig.json", tmp_path / "old.json",
                lambda d: [d.pop(k) for k in ("task_points_m", "n_dof", "scenario_fingerprint")])
    rc, _, err, _ = _run(capsys, "simulate", other, "--plan", old)
    assert rc == 2 and "starts/ends 10/" in _one_line(err)


def test_plan_file_against_other_dof(capsys, plan_files):
    rc, _, err, _ = _run(capsys, "simulate", "thesis-ch4", "--plan", plan_files / "thesis-ch2-thesis.json")
    assert rc == 2 and "has 3 joints but scenario thesis-ch4's arm has 2" in _one_line(err)


@pytest.mark.parametrize("gene, value", [("T1", -0.5), ("T2", 0.0), ("T3", 99.0)])
def test_plan_file_with_genes_outside_the_bounds(tmp_path, capsys, plan_files, gene, value):
    bad = _edit(plan_files / "thesis-ch4-thesis.json", tmp_path / "g.json",
                lambda d: d["genes"].__setitem__(gene, value))
    rc, _, err, _ = _run(capsys, "simulate", "thesis-ch4", "--plan", bad)
    assert rc == 2 and f"gene {gene} = {value:g} lies outside the family's bounds" in _one_line(err)


@pytest.mark.parametrize("edit, needle", [
    (lambda d: d["trajectory"]["t_s"].__setitem__(3, float("nan")), "samples must be finite"),
    (lambda d: d["trajectory"].__setitem__("q_rad", 5), "cannot rebuild its trajectory"),
    (lambda d: d.__setitem__("trajectory", "samples"), "lacks the 'scenario' or 'trajectory' key"),
    (lambda d: d["trajectory"].__setitem__("kind", "spline"), "unknown trajectory kind 'spline'"),
])
def test_damaged_sampled_plan_file(tmp_path, capsys, plan_files, edit, needle):
    bad = _edit(plan_files / "thesis-ch4-ruckig.json", tmp_path / "d.json", edit)
    rc, _, err, _ = _run(capsys, "simulate", "thesis-ch4", "--plan", bad)
    assert rc == 2 and needle in _one_line(err)


def test_plan_file_that_is_a_directory_or_binary(tmp_path, capsys):
    rc, _, err, _ = _run(capsys, "simulate", "thesis-ch4", "--plan", tmp_path)
    assert rc == 2 and "is a directory" in _one_line(err)
    b = tmp_path / "b.json"
    b.write_bytes(b"\xff\xfe\x81")
    rc, _, err, _ = _run(capsys, "simulate", "thesis-ch4", "--plan", b)
    assert rc == 2 and "not a UTF-8 JSON text file" in _one_line(err)


def test_matching_plan_file_still_simulates(capsys, plan_files):
    rc, out, err, _ = _run(capsys, "simulate", "thesis-ch4", "--plan", plan_files / "thesis-ch4-thesis.json",
                           "--json", "-")
    assert rc == 0, err
    assert json.loads(out)["held"] is True


@pytest.mark.parametrize("extra, needle", [
    (["--feedforward", "back-emf"], "--feedforward back-emf needs DC motors"),
    (["--explicit"], "drop --explicit"),
])
def test_motor_options_on_an_ideal_actuator(tmp_path, capsys, extra, needle):
    p = _yaml(tmp_path, actuator={"kind": "ideal"}, control={"kp": [180.0, 48.0], "kd": [6.0, 1.6]})
    rc, _, err, wall = _run(capsys, "simulate", p, *extra)  # default GA: refused before planning
    assert rc == 2 and needle in _one_line(err) and wall < 5.0
