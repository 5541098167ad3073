"""Issue 27 item 6: a refusal remains only where physics makes the combination meaningless, and says so;
the other feature x kind cells of docs/features.md run (session 13, helper refusals)."""

from __future__ import annotations

import pytest

from qmt_drake.apps.commands import check_own_actuator
from qmt_drake.config.scenario import load_scenario
from qmt_drake.errors import QmtInputError


def test_planar_actuator_flag_names_the_yaml_actuator():
    thesis = load_scenario("thesis-ch4")
    check_own_actuator(thesis, None)
    check_own_actuator(thesis, "dc_motor")  # its YAML actuator: DC motors with gears
    with pytest.raises(QmtInputError, match="actuator.kind dc_motor_gear \\(--actuator dc_motor\\)"):
        check_own_actuator(thesis, "ideal")
    tray = load_scenario("crane-tray")
    with pytest.raises(QmtInputError, match="Dynamixel position servos .* firmware closes the position loop"):
        check_own_actuator(tray, "dc_motor")


@pytest.fixture(scope="module")
def energy_plan(tmp_path_factory):
    from qmt_drake.apps.cli import main
    pj = tmp_path_factory.mktemp("energy") / "p.json"
    assert main(["plan", "ohsaka-fig3", "--method", "snopt", "--pattern=+--", "--json", str(pj), "--quiet"]) == 0
    return pj


def test_energy_time_margin_is_the_final_error_against_the_arrival_tolerance(energy_plan, tmp_path, capsys):
    import json

    from qmt_drake.apps.cli import main
    from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    sj = tmp_path / "s.json"
    assert main(["simulate", "ohsaka-fig3", "--plan", str(energy_plan), "--margin", "--json", str(sj)]) == 0
    s = json.loads(sj.read_text())
    m = s["margin"]
    assert m["quantity"] == "final_error_rad" and m["value"] == s["final_error_rad"]
    assert m["threshold"] == ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    assert m["ratio"] == pytest.approx(s["final_error_rad"] / ARRIVAL_TOLERANCE_DC_MOTOR_RAD, rel=1e-12)
    assert s["reached_goal"] == (m["ratio"] <= 1.0)
    assert "ideal, unlimited torque sources" in m["flip"]
    assert "margin: final_error_rad" in capsys.readouterr().out


@pytest.mark.parametrize("argv,reason", [
    (["--time-step-ms", "1"], "plant is continuous, integrated by an error-controlled integrator"),
    (["--actuator", "dc_motor"], "ideal torque sources (the paper models no motor"),
    (["--explicit"], "no motor-voltage loop to step explicitly"),
    (["--feedforward", "back-emf"], "no motor voltage and no back-EMF"),
])
def test_energy_time_simulate_refusals_state_the_physics(energy_plan, capsys, argv, reason):
    from qmt_drake.apps.cli import main
    assert main(["simulate", "ohsaka-fig3", "--plan", str(energy_plan), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert reason in err and "\n" not in err and "Traceback" not in err
