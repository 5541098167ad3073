"""The command line: outputs, exit codes and one-line errors on bad input."""

import json

import pytest

from qmt_drake.apps.cli import main
from qmt_drake.config.scenario import SCENARIO_DIR
from tests.scenario_files import scenario_yaml

_yaml = scenario_yaml


def _run(capsys, *argv):
    rc = main(list(argv))
    out, err = capsys.readouterr()
    return rc, out, err


def test_scenarios_lists_builtins(capsys):
    rc, out, _ = _run(capsys, "scenarios")
    assert rc == 0 and all(n in out for n in ("thesis-ch2", "thesis-ch3", "thesis-ch4"))


def test_plan_json_and_csv(tmp_path, capsys):
    j, c = tmp_path / "p.json", tmp_path / "p.csv"
    rc, out, _ = _run(capsys, "plan", "thesis-ch4", "--method", "ga", "--generations", "30",
                      "--json", str(j), "--trajectory-csv", str(c), "--quiet")
    assert rc == 0
    d = json.loads(j.read_text())
    for k in ("scenario", "method", "feasible", "motion_time_s", "genes", "peak_moment_Nm",
              "moment_limit_Nm", "peak_moment_ratio", "peak_motor_torque_Nm",
              "motor_torque_limit_Nm", "peak_motor_torque_ratio", "payload_mass_kg",
              "payload_com_offset_m", "link_lengths_m", "planner_wall_s", "evaluations",
              "generations"):
        assert k in d, k
    assert list(d["genes"]) == ["T1", "T2", "T3"]
    assert d["generations"] == 30 and d["feasible"] and d["peak_moment_ratio"] <= 1
    lines = c.read_text().splitlines()
    assert lines[0] == "t,q1,q2,qd1,qd2,qdd1,qdd2"
    t = [float(r.split(",")[0]) for r in lines[1:]]
    assert max(b - a for a, b in zip(t, t[1:])) <= 1e-3 + 1e-12
    assert t[-1] == pytest.approx(d["motion_time_s"])
    # The file loads again and re-checks to the same numbers.
    from qmt_drake.plan_files import load_plan
    assert load_plan(j).check.peak_moment_ratio == pytest.approx(d["peak_moment_ratio"], rel=1e-12)


def test_json_to_stdout(capsys):
    rc, out, _ = _run(capsys, "plan", "thesis-ch2", "--method", "thesis", "--json", "-")
    assert rc == 0 and json.loads(out)["motion_time_s"] == pytest.approx(3.69)


@pytest.mark.parametrize("changes, needle", [
    ({"task__points_m": [[0.30, 0.20], [-0.18, 0.10]], "family__genes": {"T1": [0.5, 3.0]}},
     "start point (0.3000, 0.2000) m is unreachable"),
    ({"task__ik_branch": "elbow_negative"}, "leaves its range"),
    ({"family__genes": {"T1": [3.0, 0.5], "T2": [0.5, 3.0], "T3": [0.5, 3.0]}},
     "min 3.0 >= max 0.5"),
    ({"limits__moment_limit_Nm": 0.0}, "moment_limit_Nm must be positive"),
    ({"limits__motor_torque_limit_Nm": [0.064, -1.0]}, "list of positive numbers"),
    ({"payload__colour": "red"}, "unknown key 'colour'"),
    ({"arm__urdf": "/nowhere/arm.urdf"}, "does not exist"),
])
def test_bad_input_one_line_and_exit_2(tmp_path, capsys, changes, needle):
    rc, out, err = _run(capsys, "plan", _yaml(tmp_path, **changes), "--method", "thesis")
    assert rc == 2
    assert needle in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_unknown_scenario_name(capsys):
    rc, _, err = _run(capsys, "plan", "thesis-ch9")
    assert rc == 2 and "thesis-ch9" in err


def test_infeasible_gives_exit_3_and_least_violating_plan(tmp_path, capsys):
    j = tmp_path / "p.json"
    rc, _, _ = _run(capsys, "plan", _yaml(tmp_path, limits__motor_torque_limit_Nm=[1e-5, 1e-5]),
                    "--generations", "20", "--json", str(j), "--quiet")
    assert rc == 3
    d = json.loads(j.read_text())
    assert d["feasible"] is False and d["peak_motor_torque_ratio"] > 1


def test_unparsable_plan_file(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    rc, _, err = _run(capsys, "simulate", "thesis-ch4", "--plan", str(bad))
    assert rc == 2 and "bad.json" in err and "not valid JSON" in err


def test_copied_builtin_scenario_finds_its_model(tmp_path, capsys):
    copy = tmp_path / "my_task.yaml"
    copy.write_text((SCENARIO_DIR / "thesis-ch4.yaml").read_text())
    rc, out, err = _run(capsys, "plan", str(copy), "--method", "thesis")
    assert rc == 0, err


def test_unknown_planner_option_is_one_line(capsys):
    rc, _, err = _run(capsys, "plan", "thesis-ch4", "--method", "ruckig", "--option", "foo=1")
    assert rc == 2 and "foo" in err and "Traceback" not in err


def test_simulate_chooses_the_stepping_scheme(capsys):
    """`simulate --method thesis` runs the default implicit 2 ms loop; --explicit the 1 ms one."""
    rc, out, err = _run(capsys, "simulate", "thesis-ch4", "--method", "thesis", "--json", "-")
    assert rc == 0, err
    d = json.loads(out)
    assert d["held"] and d["implicit_loop_damping"] is True and d["time_step_s"] == 2e-3
    rc, out, err = _run(capsys, "simulate", "thesis-ch4", "--method", "thesis", "--explicit", "--json", "-")
    assert rc == 0, err
    d = json.loads(out)
    assert d["held"] and d["implicit_loop_damping"] is False and d["time_step_s"] == 1e-3


def test_simulate_rejects_a_bad_time_step(capsys):
    rc, _, err = _run(capsys, "simulate", "thesis-ch4", "--method", "thesis", "--time-step-ms", "0")
    assert rc == 2 and "--time-step-ms" in err and "\n" not in err.strip()


def test_simulate_feedforward_option(capsys):
    """--feedforward full removes the back-EMF lag: tracking error falls from ~11 to < 0.1 mrad."""
    from qmt_drake.apps.cli import FEEDFORWARD_CHOICES
    from qmt_drake.sim import FEEDFORWARD_OPTIONS
    assert set(FEEDFORWARD_CHOICES) == set(FEEDFORWARD_OPTIONS)
    errors = {}
    for ff in ("none", "full"):
        rc, out, err = _run(capsys, "simulate", "thesis-ch4", "--method", "thesis", "--feedforward", ff, "--json", "-")
        assert rc == 0, err
        d = json.loads(out)
        assert d["held"] and d["feedforward"] == ff
        errors[ff] = d["max_tracking_error_rad"]
    assert errors["none"] > 5e-3 and errors["full"] < 1e-4
