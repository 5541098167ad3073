"""Plan identity by content (issue 30, item 2): every plan file (transfer, spatial, energy-time) records
the sha256 of its scenario's content by section, and a plan is refused on a scenario whose content
differs, whatever the names say; a file without the record keeps today's checks."""

import dataclasses
import json

import pytest  # noqa: I001
import yaml

from qmt_drake.apps.cli import main
from qmt_drake.config.scenario import SCENARIO_DIR
from qmt_drake.energy.energy_plan import make_energy_plan
from qmt_drake.energy.experiments import paper_initial_x
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.energy.steepest import restore_endpoint
from qmt_drake.errors import QmtInputError
from qmt_drake.plan_files import load_plan
from qmt_drake.plan_identity import IDENTITY_KEY, identity, transfer_sections
from qmt_drake.planners import plan_with
from qmt_drake.planners.spatial_methods import plan_toppra_spatial
from qmt_drake.planners.spatial_plan_io import write_spatial_plan
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.transfer_scenario import load_scenario
from tests.scenario_files import scenario_yaml


def _refusal(call) -> str:
    with pytest.raises(QmtInputError) as exc:
        call()
    assert "\n" not in str(exc.value)
    return str(exc.value)


def _spatial_copy(tmp_path, file_name, **actuators) -> str:
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-suction-bins.yaml").read_text())
    raw["actuators"].update(actuators)
    p = tmp_path / file_name
    p.write_text(yaml.safe_dump(raw))
    return str(p)


def test_spatial_plan_refused_by_a_same_named_copy_with_slower_joints(tmp_path):
    """The issue's case: ur5-suction-bins's plan on a copy with 1 rad/s joint limits, same name."""
    sc = load_spatial_scenario("ur5-suction-bins")
    path = tmp_path / "plan.json"
    write_spatial_plan(sc, plan_toppra_spatial(sc, n_grid=200), path)
    d = json.loads(path.read_text())
    assert d["scenario"] == "ur5-suction-bins" and set(d[IDENTITY_KEY]["sections"]) >= {"arm", "hand", "limits", "task"}
    slow = load_spatial_scenario(_spatial_copy(tmp_path, "slow.yaml", velocity_limit_rad_s=[1.0] * 6))
    assert slow.name == sc.name
    msg = _refusal(lambda: load_plan(path, slow))
    assert msg == (f"plan file {path} was made for scenario 'ur5-suction-bins' with other content than scenario "
                   "'ur5-suction-bins' (limits differ); plan again with `qmt-drake plan ur5-suction-bins --json PATH`")
    # the same content elsewhere (another file, another folder) is the same scenario
    same = load_spatial_scenario(_spatial_copy(tmp_path, "same.yaml"))
    assert load_plan(path, same).duration_s == pytest.approx(json.loads(path.read_text())["motion_time_s"])
    # and the CLI refuses it in one line before simulating
    rc = main(["simulate", _spatial_copy(tmp_path, "slow2.yaml", velocity_limit_rad_s=[1.0] * 6), "--plan", str(path)])
    assert rc == 2


def test_transfer_plan_refused_on_changed_limits_and_task_whatever_the_name(tmp_path, capsys):
    sc = load_scenario("thesis-ch4")
    path = tmp_path / "p.json"
    plan_with("thesis", sc).write_json(path)
    tight = scenario_yaml(tmp_path, limits__motor_torque_limit_Nm=[0.05, 0.02])
    assert load_scenario(tight).name == "thesis-ch4"
    assert "(limits differ)" in _refusal(lambda: load_plan(path, load_scenario(tight)))
    heavier = scenario_yaml(tmp_path, payload__mass_kg=0.02, hand__friction=0.4)
    assert "(hand, payload differ)" in _refusal(lambda: load_plan(path, load_scenario(heavier)))
    assert main(["simulate", tight, "--plan", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "with other content than scenario 'thesis-ch4' (limits differ)" in err and len(err.splitlines()) == 1
    # content, not names: a renamed copy with the same content and a prose edit are the same scenario
    renamed = scenario_yaml(tmp_path, name="my-ch4", description="a copy", ga__max_generations=7)
    assert load_plan(path, load_scenario(renamed)).motion_time_s == pytest.approx(plan_with("thesis", sc).motion_time_s)


def test_transfer_file_without_identity_keeps_todays_checks(tmp_path):
    """Files written before the record (goldens, users' saved plans) load as before: the joint count,
    task points and genes are checked, and the plan is re-checked on the scenario it is run with."""
    sc = load_scenario("thesis-ch4")
    path = tmp_path / "old.json"
    d = plan_with("thesis", sc).to_json_dict()
    assert d[IDENTITY_KEY] == identity(transfer_sections(sc))
    del d[IDENTITY_KEY]
    path.write_text(json.dumps(d))
    assert load_plan(path, sc).feasible
    tight = load_scenario(scenario_yaml(tmp_path, limits__motor_torque_limit_Nm=[0.003, 0.001]))
    again = load_plan(path, tight)
    assert not again.feasible and again.check.peak_motor_torque_ratio > 1  # the re-check on the new limits
    moved = load_scenario(scenario_yaml(tmp_path, task__points_m=[[0.30, 0.10], [-0.18, 0.10]]))
    assert "was made for task points" in _refusal(lambda: load_plan(path, moved))


def test_energy_plan_refused_on_other_torque_limits(tmp_path):
    E = get_experiment("ohsaka-fig2")
    P = E.problem(m=3)
    x = restore_endpoint(P, paper_initial_x(P, {}, E.fixed_T_s))
    path = tmp_path / "e.json"
    make_energy_plan(E, P, "test", x, True).write_json(path)
    assert load_plan(path, E).motion_time_s == pytest.approx(float(x[-1]))
    other = dataclasses.replace(E, torque_limit_Nm=tuple([1.0] * len(P.theta0)))
    assert "(limits differ)" in _refusal(lambda: load_plan(path, other))
    renamed = dataclasses.replace(E, name="my-fig2", description="same content")
    assert load_plan(path, renamed).motion_time_s == pytest.approx(float(x[-1]))
