"""Session 18, an outsider's inputs: hand-edited plan files, the Python API beside the CLI, sweep and scenario
sections, arms nobody here wrote a scenario for. Each either works correctly or is refused in one line naming
the input and the fix (exit 2) before any long work; each test is a defect found by feeding such an input."""

import json

import pytest

from qmt_drake.errors import QmtInputError
from tests.test_outsider_s16 import _refused, _spatial_yaml  # noqa: F401  (the shared scenario-file helpers)


@pytest.fixture(scope="module")
def ch4():
    from qmt_drake import load_scenario
    return load_scenario("thesis-ch4")


def test_plan_file_without_scenario_kind_is_not_called_planar(tmp_path, capsys):
    # a spatial plan file whose scenario_kind was deleted by hand was refused as "a planar plan"
    path = tmp_path / "nokind.json"
    path.write_text(json.dumps({"scenario": "ur5-suction-bins", "method": "toppra", "trajectory": {"kind": "x"}}))
    line = _refused(capsys, "simulate", "ur5-suction-bins", "--plan", path)
    assert "planar" not in line and "without scenario_kind" in line and "scenario_kind: spatial_transfer" in line
    line = _refused(capsys, "simulate", "ohsaka-fig3", "--plan", path)
    assert "planar" not in line.split("energy-time scenario")[0] and "scenario_kind: energy_time" in line


def test_api_takes_a_planar_arms_own_actuator_by_name_as_the_cli_does(ch4, monkeypatch):
    # the CLI's --actuator dc_motor runs thesis-ch4 (its YAML's DC motors); simulate(actuator="dc_motor") refused it
    from qmt_drake import api, plan_with
    plan = plan_with("thesis", ch4)
    ran = []
    monkeypatch.setattr(api, "run", lambda cosim: ran.append(cosim) or {"outcome": "carried", "held": True})
    monkeypatch.setattr(api, "with_margin", lambda sc, plan, result, **kw: result)
    result = api.simulate(ch4, plan, actuator="dc_motor")
    assert len(ran) == 1 and result["actuator"] == "dc_motor" and result["actuator_kind"] == "dc_motor_gear"
    with pytest.raises(QmtInputError, match=r"^simulate: actuator ideal: thesis-ch4's actuator is its YAML's "
                                            r"actuator.kind dc_motor_gear .*drop simulate: actuator") as e:
        api.simulate(ch4, plan, actuator="ideal")
    assert "\n" not in str(e.value) and len(ran) == 1


@pytest.mark.parametrize("rate, says", [
    (-1.0, r"sweep sim.integral_rate_per_s must be a non-negative number \(or a list of 7.*got -1$"),
    (float("nan"), r"must be a non-negative number .*got nan$"),
    (11.0, r"must be at most 10 1/s .*got 11.0$"),
])
def test_sweep_integral_rate_named_as_given(rate, says):
    # one number given was echoed as seven ("must be a list of non-negative numbers, got [-1.0, -1.0, ...]")
    from qmt_drake.sweep.spatial_cases import build_spatial_cases
    from qmt_drake.sweep.spec import load_spec
    spec = {"name": "i", "scenario": "panda-tray-cup", "plans": [{"method": "toppra"}],
            "sim": {"actuator": "dc_motor", "integral_rate_per_s": rate}, "parameters": {"mass_scale": [1.0]}}
    with pytest.raises(QmtInputError, match=says) as e:
        build_spatial_cases(load_spec(spec))
    assert "\n" not in str(e.value)
