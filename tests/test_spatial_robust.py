"""The spatial uncertainty on the DC-motor drive (issue 29 item 3): the drawn plant differs from the
controller's model, and the drive `--success` runs (the section's `sim`, or success_spec(sim=)) is
refused in one line where it means nothing."""

import numpy as np
import pytest
import yaml

from qmt_drake.api import load_scenario
from qmt_drake.config.resolve import SCENARIO_DIR
from qmt_drake.errors import QmtInputError
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.sweep.cases import build_cases
from qmt_drake.sweep.robust import success_spec
from qmt_drake.sweep.spatial_cases import build_spatial_cases, drawn_drive, perturbed_scenario
from qmt_drake.sweep.spec import load_spec


@pytest.fixture(scope="module")
def magnet():
    return load_spatial_scenario("ur5-magnet-part")


def test_the_drawn_plant_differs_from_the_controllers_model(magnet):
    sc = magnet
    nominal = SpatialMotorDrive.for_scenario(sc, sc.q_path_rad[0], "shaped")
    drawn = {"motor_torque_constant_scale": 0.9, "motor_resistance_scale": 1.1, "gear_efficiency": 0.92,
             "kp_scale": 1.1, "kd_scale": 0.95, "mass_scale": 1.05}
    physical = perturbed_scenario(sc, drawn)
    d = drawn_drive(nominal, sc, physical, drawn)
    # the simulated motors are the drawn ones ...
    np.testing.assert_allclose(d.plant_params.torque_constant_Nm_per_A, 0.9 * nominal.params.torque_constant_Nm_per_A)
    np.testing.assert_allclose(d.plant_params.resistance_ohm, 1.1 * nominal.params.resistance_ohm)
    np.testing.assert_allclose(d.plant_params.efficiency, 0.92)
    np.testing.assert_array_equal(d.plant_params.current_limit_A, nominal.params.current_limit_A)  # the amplifier's
    # ... the law's motor model, its feedforward plant and the loop damping are the nominal ones
    assert d.params is nominal.params and d.id_plant is nominal.id_plant and d.feedforward == "shaped"
    np.testing.assert_array_equal(d.loop_damping_Nms, nominal.loop_damping_Nms)
    assert not np.allclose(nominal.params.efficiency, 0.92)
    # the executed PD law's gains are drawn around the designed ones
    np.testing.assert_allclose(d.gains.kp_V_per_rad, 1.1 * nominal.gains.kp_V_per_rad)
    np.testing.assert_allclose(d.gains.kd_V_s_per_rad, 0.95 * nominal.gains.kd_V_s_per_rad)
    # the part drawn heavier; the nominal scenario (the controller's) untouched
    assert physical.body.mass_kg == pytest.approx(1.05 * sc.body.mass_kg) and physical.motor is not sc.motor
    # nothing drawn: the nominal drive itself
    assert drawn_drive(nominal, sc, perturbed_scenario(sc, {}), {}) is nominal


def test_the_gains_reach_the_drive_not_the_payload(magnet):
    spec = {"name": "g", "scenario": "ur5-magnet-part", "plans": [{"method": "toppra"}],
            "sim": {"actuator": "dc_motor", "feedforward": "shaped"},
            "parameters": {"kp_scale": 1.1, "kd_scale": 0.9, "mass_scale": 1.02}}
    cases, _ = build_spatial_cases(load_spec(spec))
    c = cases[0]
    assert c.motor_scales == {"kp_scale": 1.1, "kd_scale": 0.9} and c.payload == {"mass_scale": 1.02}
    assert c.sim["feedforward"] == "shaped" and c.sim["actuator"] == "dc_motor"


def test_success_runs_the_drive_asked_for(tmp_path, magnet):
    assert "sim" not in success_spec(magnet).raw  # default: the scenario's real drive, full feedforward
    cases, _ = build_spatial_cases(success_spec(magnet, cases=2, sim={"actuator": "dc_motor", "feedforward": "shaped"}))
    assert {c.sim["feedforward"] for c in cases} == {"shaped"}
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-magnet-part.yaml").read_text())
    raw["uncertainty"]["sim"] = {"feedforward": "shaped"}  # the section's own drive
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(raw))
    cases, _ = build_spatial_cases(success_spec(load_spatial_scenario(str(path)), cases=2))
    assert {(c.sim["actuator"], c.sim["feedforward"]) for c in cases} == {("dc_motor", "shaped")}


@pytest.mark.parametrize("sim, says", [
    ({"actuator": "ideal"}, "motor parameters act through sim.actuator dc_motor"),  # the section draws motors
    ({"feedforward": "back-emf"}, "choose full"),
    ({"actuator": "servo"}, "choose one of ideal, dc_motor"),
    ({"loop": 1}, "loop"),
])
def test_a_meaningless_drive_is_refused_in_one_line(magnet, sim, says):
    with pytest.raises(QmtInputError) as e:
        success_spec(magnet, sim=sim)
    assert says in str(e.value) and "\n" not in str(e.value)


def test_a_section_drive_is_checked_on_load(tmp_path):
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-magnet-part.yaml").read_text())
    raw["uncertainty"]["sim"] = {"feedforward": "none"}
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(QmtInputError) as e:
        load_spatial_scenario(str(path))
    assert "uncertainty.sim.feedforward" in str(e.value) and "\n" not in str(e.value)


def test_planar_scenarios_refuse_the_spatial_drive_in_one_line():
    with pytest.raises(QmtInputError) as e:
        success_spec(load_scenario("thesis-ch4"), sim={"feedforward": "shaped"})
    assert "planar" in str(e.value) and "\n" not in str(e.value)
    spec = {"name": "p", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}], "sim": {"feedforward": "shaped"},
            "parameters": {"time_scale": 1.1}}
    with pytest.raises(QmtInputError) as e:
        build_cases(load_spec(spec))
    assert "planar" in str(e.value) and "\n" not in str(e.value)
