"""Energy-time scenario files (qmt_drake/energy/scenario.py): the built-ins are the experiments,
a user's own file works by path through `qmt-drake plan`, and bad values give one line, exit 2."""

import json

import pytest
import yaml

from qmt_drake.apps.cli import main
from qmt_drake.config.scenario import builtin_scenarios
from qmt_drake.energy.scenario import ENERGY_SCENARIO_DIR, EXPERIMENTS, get_experiment

FIG3 = ENERGY_SCENARIO_DIR / "ohsaka-fig3.yaml"


def test_builtins_are_the_papers_experiments():
    assert sorted(EXPERIMENTS) == ["ohsaka-fig2", "ohsaka-fig3", "ohsaka-fig4"]
    f2, f3, f4 = (get_experiment(n) for n in sorted(EXPERIMENTS))
    assert f2.coordinate_vector_m == (0.7, 0.0, 0.0, 0.7) and f2.fixed_T_s == 4.6 and f2.moving_joints == (0,)
    assert f3.coordinate_vector_m == (0.7, 0.0, 0.0, 0.2) and (f3.c1, f3.c2, f3.m, f3.divisions) == (1, 1e5, 5, 40)
    assert f4.paper_initial_a == {(3, 1): 0.575} and f4.reported["T_s"][1e4] == 0.330
    assert f3.torque_limit_Nm == (200.0, 200.0, 200.0)
    # they share models/scenarios/ with the transfer scenarios, told apart by their `kind`
    assert not set(EXPERIMENTS) & set(builtin_scenarios())
    assert sorted(builtin_scenarios("energy_time")) == sorted(EXPERIMENTS)


def test_the_two_kinds_refuse_each_others_commands_in_one_line(capsys):
    assert main(["simulate", "ohsaka-fig3", "--method", "ga"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "energy-time" in err and "--plan" in err
    assert main(["plan", "ohsaka-fig3", "--method", "thesis"]) == 2  # snopt, collocation plan a planar arm too
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not energy-time ones; energy-time scenarios take snopt|" in err


def test_scenarios_lists_every_kind(capsys):
    assert main(["scenarios"]) == 0
    names = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    spatial = builtin_scenarios("spatial_transfer")
    assert {"ur5-suction-bins", "ur5-magnet-part", "panda-tray-cup"} <= set(spatial)
    assert set(names) == set(builtin_scenarios()) | set(EXPERIMENTS) | set(spatial)


def _user_file(tmp_path, **changes):
    raw = yaml.safe_load(FIG3.read_text())
    raw["arm"]["urdf"] = str((FIG3.parent / raw["arm"]["urdf"]).resolve())
    for dotted, v in changes.items():
        sec, key = dotted.split("__") if "__" in dotted else (None, dotted)
        if sec is None:
            raw[key] = v
        elif v is None:
            raw[sec].pop(key)
        else:
            raw[sec][key] = v
    p = tmp_path / "mine.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


def test_user_file_plans_through_qmt_drake_plan(tmp_path, capsys):
    p = _user_file(tmp_path, task__coordinate_vector_m=[0.7, 0.0, 0.1, 0.3], objective__c2="1e4")
    out = tmp_path / "r.json"
    assert main(["plan", str(p), "--pattern=-+-", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d["XT"] == [0.1, 0.3] and d["c2"] == 1e4
    (opt,) = d["optima"]
    assert opt["success"] and opt["z"] == pytest.approx(1e4 * opt["T_s"] + opt["energy"], rel=1e-12)


@pytest.mark.parametrize("change,msg", [
    ({"task__coordinate_vector_m": [0.7, 0.0, 0.0, 0.9]}, "out of reach"),
    ({"task__coordinate_vector_m": [0.7, 0.0, 0.0]}, "task.coordinate_vector_m has 3 entries; give 4"),
    ({"family__m": 0}, "family.m must be >= 1, got 0"),
    ({"family__m": 2.5}, "must be an integer"),
    ({"objective__c1": -1.0}, "c1 = -1"),
    ({"objective__c2": 0.0}, "no stable solution"),
    ({"objective__c2": "lots"}, "objective.c2 must be a number, got 'lots'"),
    ({"objective__divisions": 1}, "objective.divisions must be >= 2, got 1"),
    ({"limits": {"joint_torque_Nm": [200, -1, 200]}}, "limits.joint_torque_Nm must be a list of positive numbers"),
    ({"limits": {"joint_torque_Nm": [200, 200]}}, "limits.joint_torque_Nm has 2 entries; give 3"),
    ({"family__moving_joints": [4]}, "moving_joints"),
    ({"family__kind": "via_cubic"}, "family.kind 'via_cubic' is not one of fourier_velocity"),
    ({"payload": {"mass_kg": 1}}, "unknown key 'payload'"),
    ({"task__start_posture": "highest"}, "only lowest_cog"),
    ({"arm__urdf": "/nonexistent.urdf"}, "does not exist"),
    ({"objective__c1": None}, "objective: missing key 'c1'"),
])
def test_bad_values_one_line_exit_2(tmp_path, capsys, change, msg):
    p = _user_file(tmp_path, **change)
    assert main(["plan", str(p), "--pattern=-+-"]) == 2
    err = capsys.readouterr().err.strip()
    assert msg in err and "\n" not in err and "Traceback" not in err and str(p) in err


def test_other_kinds_go_to_the_shared_loader(tmp_path, capsys):
    p = tmp_path / "x.yaml"
    p.write_text("name: x\n")
    assert p.as_posix() not in EXPERIMENTS
    assert main(["plan", str(p), "--method", "collocation"]) == 2  # every kind's method: the transfer loader says why
    assert "missing section 'arm'" in capsys.readouterr().err
