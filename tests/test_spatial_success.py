"""Uncertainty on spatial scenarios (sweep/spatial_cases.py): the section, the drawn copy, and
`plan SPATIAL --success P` end to end on a tiny search."""

import json
import re

import numpy as np
import pytest
import yaml

from qmt_drake.apps.cli import main
from qmt_drake.config.resolve import SCENARIO_DIR
from qmt_drake.errors import QmtInputError
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.sweep.cases import build_cases
from qmt_drake.sweep.robust import success_spec
from qmt_drake.sweep.spatial_cases import build_spatial_cases, perturbed_scenario
from qmt_drake.sweep.spec import load_spec


def _copy(tmp_path, name: str, uncertainty) -> str:
    raw = yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text())
    raw["uncertainty"] = uncertainty
    if uncertainty is None:
        raw.pop("uncertainty")
    path = tmp_path / f"{name}-u.yaml"
    path.write_text(yaml.safe_dump(raw))
    return str(path)


@pytest.mark.parametrize("name", ["ur5-suction-bins", "ur5-magnet-part", "panda-tray-cup"])
def test_shipped_spatial_scenarios_have_a_usable_uncertainty_section(name):
    sc = load_spatial_scenario(name)
    spec = success_spec(sc)
    assert spec.mc_cases == 40 and set(spec.distributions) == set(sc.uncertainty["parameters"])


@pytest.mark.parametrize("bad, says", [
    ({"parameters": {"vacuum_force_scale": {"dist": "uniform", "low": 0.8, "high": 1.0}}}, "does not vary it"),
    ({"parameters": {"no_such": {"dist": "normal", "mean": 1, "std": 0.1}}}, "unknown parameter 'no_such'"),
    ({"parameters": {"mass_scale": {"dist": "normal", "mean": 1, "std": -0.1}}}, "negative"),
    ({"parameters": {"mass_scale": [1.0, 1.1]}}, "give a distribution"),
    ({"parameters": {"gear_efficiency": {"dist": "uniform", "low": 0.9, "high": 1.2}}}, "out of range"),
    ({"parameters": {}}, "must be a mapping"),
    ({"parameters": {"mass_scale": {"dist": "normal", "mean": 1, "std": 0.1}}, "monte_carlo": {"cases": 0}},
     "monte_carlo.cases"),
])
def test_bad_uncertainty_entries_are_refused_in_one_line(tmp_path, bad, says):
    with pytest.raises(QmtInputError) as e:
        load_spatial_scenario(_copy(tmp_path, "ur5-magnet-part", bad))
    assert says in str(e.value) and "\n" not in str(e.value) and "uncertainty" in str(e.value)


def test_motor_parameters_need_the_motors_when_used(tmp_path):
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-magnet-part.yaml").read_text())
    raw["actuators"].pop("motor")
    path = tmp_path / "no-motor.yaml"
    path.write_text(yaml.safe_dump(raw))
    sc = load_spatial_scenario(str(path))  # loads (a copy without its motors)
    with pytest.raises(QmtInputError, match="has no actuators.motor"):
        success_spec(sc)


def test_a_scenario_without_the_section_is_refused_by_success(tmp_path):
    sc = load_spatial_scenario(_copy(tmp_path, "ur5-magnet-part", None))
    with pytest.raises(QmtInputError, match="no uncertainty section"):
        success_spec(sc)


def test_a_perturbed_copy_changes_exactly_the_named_parameter():
    sc = load_spatial_scenario("ur5-suction-bins")
    heavy = perturbed_scenario(sc, {"mass_scale": 1.5})
    assert heavy.body.mass_kg == pytest.approx(1.5 * sc.body.mass_kg)
    np.testing.assert_array_equal(heavy.body.com_m, sc.body.com_m)
    assert heavy.grip is sc.grip and heavy.motor is sc.motor and heavy.plant is sc.plant
    assert sc.body.mass_kg == 2.0  # the nominal scenario is untouched
    # the limit check sees the heavier box: a higher suction ratio at every path point at rest
    zero = np.zeros_like(sc.q_path_rad)

    def ratios(s):
        return s.hand_term().columns(s.chain.evaluate(sc.q_path_rad, zero, zero)).max(axis=1)

    assert np.all(ratios(heavy) > ratios(sc) + 1e-6)
    weak = perturbed_scenario(sc, {"vacuum_force_scale": 0.8})
    assert weak.grip.pull_force_N == pytest.approx(0.8 * sc.grip.pull_force_N) and weak.body is sc.body
    assert weak.grip.friction == sc.grip.friction
    motor = perturbed_scenario(sc, {"motor_torque_constant_scale": 0.9})
    np.testing.assert_allclose(motor.motor.torque_constant_Nm_per_A, 0.9 * sc.motor.torque_constant_Nm_per_A)
    np.testing.assert_array_equal(motor.motor.resistance_ohm, sc.motor.resistance_ohm)
    np.testing.assert_array_equal(motor.motor.current_limit_A, sc.motor.current_limit_A)  # the amplifier's
    assert motor.body is sc.body
    lateral = perturbed_scenario(sc, {"com_lateral_m": 0.01})
    d = lateral.body.com_m - sc.body.com_m
    assert np.linalg.norm(d) == pytest.approx(0.01) and abs(d @ sc.face_axis) < 1e-12


def test_tray_and_magnet_copies():
    tray = load_spatial_scenario("panda-tray-cup")
    t = perturbed_scenario(tray, {"friction": 0.3})
    assert t.cup.friction == 0.3 and t.cup.mass_kg == tray.cup.mass_kg and t.body is tray.body
    mag = load_spatial_scenario("ur5-magnet-part")
    m = perturbed_scenario(mag, {"magnet_pull_scale": 0.9})
    assert m.moment_limit_Nm == pytest.approx(0.9 * mag.moment_limit_Nm) and m.body is mag.body
    with pytest.raises(QmtInputError, match="does not vary it"):
        perturbed_scenario(mag, {"friction": 0.3})


def test_success_on_a_spatial_scenario_end_to_end(tmp_path, capsys):
    """A tiny search: one drawn case per step (a magnet 3x stronger than planned, so the TOPP-RA plan is
    carried as planned), one fresh case; the plan file records P and its Wilson bound."""
    u = {"parameters": {"magnet_pull_scale": {"dist": "uniform", "low": 3.0, "high": 3.1},
                        "motor_torque_constant_scale": {"dist": "normal", "mean": 1.0, "std": 0.02}},
         "monte_carlo": {"cases": 1, "seed": 3}}
    path = _copy(tmp_path, "ur5-magnet-part", u)
    out = tmp_path / "p.json"
    rc = main(["plan", path, "--method", "toppra", "--success", "0.1", "--success-check-cases", "1",
               "--success-max-scale", "1.05", "--success-out", str(tmp_path / "store"), "--json", str(out),
               "--quiet"])
    assert rc == 0
    doc = json.loads(out.read_text())
    s = doc["info"]["success"]
    fresh = s["fresh_check"]
    assert fresh["cases"] == 1 and fresh["carried"] == 1 and fresh["ci_low"] == pytest.approx(0.2065, abs=1e-3)
    assert s["search"]["found"] and s["search"]["time_scale"] == 1.0 and doc["info"]["time_scale"] == 1.0
    assert [t["time_scale"] for t in s["tries"]] == [1.0, 1.05]
    assert re.search(r"P\(carried\) 1/1 on fresh cases, 95 % Wilson lower bound 0\.2\d+", capsys.readouterr().out)
    # simulate replays the nominal cell only: the planned magnet, on which TOPP-RA's plan lets go at once
    sim = tmp_path / "sim.json"
    assert main(["simulate", path, "--plan", str(out), "--json", str(sim), "--quiet"]) == 0
    r = json.loads(sim.read_text())
    assert r["outcome"] == "detached" and r["lost_at_s"] < 0.1 and r["time_scale"] == 1.0
    # the store resumes: the same search again computes nothing new
    cases = sorted((tmp_path / "store").rglob("cases/*.json"))
    assert len(cases) == 3
    assert main(["plan", path, "--method", "toppra", "--success", "0.1", "--success-check-cases", "1",
                 "--success-max-scale", "1.05", "--success-out", str(tmp_path / "store"), "--json", str(out),
                 "--quiet"]) == 0
    assert sorted((tmp_path / "store").rglob("cases/*.json")) == cases


def test_sweep_specs_check_the_parameter_against_the_kind():
    magnet = {"name": "m", "scenario": "ur5-magnet-part", "plans": [{"method": "toppra"}],
              "parameters": {"friction": [0.3]}}
    with pytest.raises(QmtInputError, match="spatial magnet hand's co-simulation does not vary it"):
        build_spatial_cases(load_spec(magnet))
    planar = {"name": "p", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
              "parameters": {"vacuum_force_scale": [0.9]}}
    with pytest.raises(QmtInputError, match="for spatial scenarios"):
        build_cases(load_spec(planar))
    # the drawn timing multiplies the searched time scale, on planar and spatial cases alike
    planar["parameters"] = {"time_scale": 1.1, "time_scale_jitter": [0.99, 1.01]}
    cases, _ = build_cases(load_spec(planar))
    assert [c.sim["time_scale"] for c in cases] == pytest.approx([1.089, 1.111])
    magnet["parameters"] = {"time_scale": 1.1, "time_scale_jitter": [0.99, 1.01], "gear_efficiency": 0.95}
    cases, _ = build_spatial_cases(load_spec(magnet))
    assert [c.sim["time_scale"] for c in cases] == pytest.approx([1.089, 1.111])
    assert cases[0].sim["actuator"] == "dc_motor" and cases[0].motor_scales == {"gear_efficiency": 0.95}
