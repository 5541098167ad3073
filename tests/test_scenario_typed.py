"""Typed scenario sections (arm, hand, actuator, payload body), pickling and the fingerprint.

The hand, the motors and the payload's body come from the scenario's own data, never from its
file names or the payload's mass; scenarios and plans pickle; the fingerprint changes with every
edit that can change a result and with the URDF's bytes, and not with where the files are."""

import pickle
import shutil

import numpy as np
import pytest
import yaml

from qmt_drake.config.scenario import (
    SCENARIO_DIR,
    DcMotorGear,
    DynamixelServos,
    MagnetHand,
    PayloadBody,
    TrayHand,
    UrdfArm,
    builtin_scenarios,
)
from qmt_drake.systems.electromagnet import THESIS_COILS
from qmt_drake.systems.payload import PayloadSpec
from qmt_drake.transfer_scenario import load_scenario


def _write(tmp_path, raw, name="s.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(raw))
    return p


def _raw(name="thesis-ch4"):
    raw = yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text())
    raw["arm"]["urdf"] = str((SCENARIO_DIR / raw["arm"]["urdf"]).resolve())
    return raw


@pytest.mark.parametrize("name", builtin_scenarios())
def test_builtins_have_explicit_typed_sections(name):
    sc = load_scenario(name)
    assert isinstance(sc.arm_spec, UrdfArm) and sc.arm_spec.urdf_path == sc.urdf_path
    if isinstance(sc.hand, TrayHand):  # seed 002: a tray with Dynamixel servos
        assert isinstance(sc.actuator, DynamixelServos) and len(sc.actuator.servos) == sc.arm.n_dof
        assert sc.bottle.mass_kg == sc.payload.mass_kg and sc.bottle.com_height_m == sc.payload.com_offset_m
    else:
        assert isinstance(sc.hand, MagnetHand) and sc.hand.slip_boundary_Nm is not None
        assert isinstance(sc.actuator, DcMotorGear) and len(sc.actuator.motors) == sc.arm.n_dof
    assert isinstance(sc.payload.body, PayloadBody)
    raw = yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text())
    assert {"hand", "actuator"} <= set(raw) and "body" in raw["payload"]  # written out, not inferred


def test_the_thesis_hands_are_those_the_cosimulation_used_before():
    """The values cosim.py inferred from file names and masses (the chapter-2 bolt on the Table 2.2
    coil; the ch.3-4 steel cylinder on the Table 3.2 coil) now come from the YAML: same numbers."""
    ch2, ch4 = load_scenario("thesis-ch2"), load_scenario("thesis-ch4")
    assert ch2.hand.coil == THESIS_COILS["table_2_2"] and ch4.hand.coil == THESIS_COILS["table_3_2"]
    assert ch2.hand.slip_boundary_Nm == (3.168e-5, 3.344e-5)  # seed 000 Table 2.3
    assert ch4.hand.slip_boundary_Nm == (0.633e-3, 0.727e-3)  # seed 000 Table 4.2
    assert PayloadSpec.for_scenario(ch2) == PayloadSpec.m8_bolt(0.022, 0.016)
    assert PayloadSpec.for_scenario(ch4) == PayloadSpec.steel_cylinder(0.030, 0.028)


def test_no_dispatch_on_mass_or_file_name(tmp_path):
    # A ch.4 scenario whose part weighs 22 g (the ch.2 bolt's mass) keeps its steel cylinder, and
    # a copy of the ch.2 arm under another file name keeps the hand its scenario names.
    raw = _raw("thesis-ch4")
    raw["payload"]["mass_kg"] = 0.022
    sc = load_scenario(_write(tmp_path, raw))
    spec = PayloadSpec.for_scenario(sc)
    assert spec.name == "steel part" and spec == PayloadSpec.steel_cylinder(0.022, 0.028)
    raw = _raw("thesis-ch2")
    urdf = tmp_path / "my_arm.urdf"
    shutil.copy(raw["arm"]["urdf"], urdf)
    raw["arm"]["urdf"] = str(urdf)
    raw["hand"]["coil"] = "table_3_2"
    sc = load_scenario(_write(tmp_path, raw, "other.yaml"))
    assert sc.hand.coil == THESIS_COILS["table_3_2"]
    from qmt_drake.sim import calibrated_coil_current_A, magnet_params_for
    spec = PayloadSpec.for_scenario(sc)
    assert magnet_params_for(sc, spec).coil.turns == 156
    # The calibrated current follows the named coil: fewer turns, more current for the same pull.
    ref = load_scenario("thesis-ch2")
    assert calibrated_coil_current_A(sc, spec) == pytest.approx(
        calibrated_coil_current_A(ref, PayloadSpec.for_scenario(ref)) * 420 / 156, rel=1e-12)


def test_explicit_coil_current_and_coil_data(tmp_path):
    raw = _raw()
    raw["hand"] = {"kind": "magnet", "coil": {"turns": 200, "resistance_ohm": 2.0, "core_diameter_m": 0.008,
                                             "outer_diameter_m": 0.012, "length_m": 0.02},
                   "coil_current_A": 0.5, "friction": 0.4}
    sc = load_scenario(_write(tmp_path, raw))
    assert sc.hand.coil.turns == 200 and sc.hand.coil_name == "explicit"
    from qmt_drake.sim import coil_current_for
    spec = PayloadSpec.for_scenario(sc)
    assert spec.friction == 0.4 and coil_current_for(sc, spec) == 0.5


def test_motors_by_rated_torque_match_the_catalogue_rule(tmp_path):
    from qmt_drake.systems.dc_motor import MOTOR_CATALOG, motor_for_rated_torque
    raw = _raw("thesis-ch2")
    raw["actuator"] = {"kind": "dc_motor_gear", "motors": "by_rated_torque"}
    sc = load_scenario(_write(tmp_path, raw))
    assert [MOTOR_CATALOG[m] for m in sc.actuator.motors] == \
        [motor_for_rated_torque(t) for t in sc.limits.motor_torque_limit_Nm]
    assert sc.actuator.motors == load_scenario("thesis-ch2").actuator.motors


@pytest.mark.parametrize("name", builtin_scenarios())
def test_scenario_pickles_and_builds_the_same_arm(name):
    sc = load_scenario(name)
    _ = sc.arm  # cached Drake object: must not be in the pickled state
    blob = pickle.dumps(sc)
    back = pickle.loads(blob)
    assert "arm" not in back.__dict__
    assert back.fingerprint() == sc.fingerprint()
    rng = np.random.default_rng(1)
    q = rng.uniform(-1, 1, (5, sc.arm.n_dof))
    qd, qdd = rng.uniform(-1, 1, q.shape), rng.uniform(-1, 1, q.shape)
    np.testing.assert_array_equal(back.arm.tip_position(q), sc.arm.tip_position(q))
    np.testing.assert_array_equal(back.arm.motor_torque(q, qd, qdd), sc.arm.motor_torque(q, qd, qdd))


def test_plans_pickle():
    from qmt_drake.planners import plan_with
    sc = load_scenario("thesis-ch4")
    t = np.linspace(0.0, 1.7, 501)
    for method in ("thesis", "ruckig"):
        plan = plan_with(method, sc)
        back = pickle.loads(pickle.dumps(plan))
        assert back.check.peak_moment_ratio == plan.check.peak_moment_ratio
        for a, b in zip(plan.sample(t), back.sample(t)):
            # family plans rebuild exactly; others travel as the plan file's samples (quintic Hermite)
            np.testing.assert_allclose(b, a, rtol=0, atol=0 if method == "thesis" else 1e-6)


def test_fingerprint_tracks_content_not_location(tmp_path):
    base = load_scenario("thesis-ch4").fingerprint()
    assert len(base) == 64 and int(base, 16) >= 0
    # Same content in another folder (URDF copied too): same fingerprint.
    raw = _raw()
    urdf = tmp_path / "arm.urdf"
    shutil.copy(raw["arm"]["urdf"], urdf)
    raw["arm"]["urdf"] = "arm.urdf"
    assert load_scenario(_write(tmp_path, raw)).fingerprint() == base
    # Prose does not count.
    raw["description"] = "edited words"
    assert load_scenario(_write(tmp_path, raw)).fingerprint() == base
    # Any edit that can change a plan or a simulation does.
    seen = {base}
    for key, value in (("limits", {"moment_limit_Nm": 0.571e-3, "motor_torque_limit_Nm": [0.064, 0.032]}),
                       ("ga", dict(_raw()["ga"], max_generations=9999)),
                       ("hand", dict(_raw()["hand"], friction=0.31))):
        r = dict(raw, **{key: value})
        fp = load_scenario(_write(tmp_path, r, f"{key}.yaml")).fingerprint()
        assert fp not in seen
        seen.add(fp)
    # The URDF's bytes count: one changed digit in the arm changes it.
    text = urdf.read_text()
    assert "0.16" in text
    urdf.write_text(text.replace("0.16", "0.161", 1))
    assert load_scenario(_write(tmp_path, raw)).fingerprint() not in seen


def test_plan_file_carries_the_fingerprint_and_task(tmp_path):
    import json

    from qmt_drake.planners import plan_with
    sc = load_scenario("thesis-ch4")
    plan = plan_with("thesis", sc)
    plan.write_json(tmp_path / "p.json")
    d = json.loads((tmp_path / "p.json").read_text())
    assert d["scenario_fingerprint"] == sc.fingerprint() and d["n_dof"] == 2
    np.testing.assert_array_equal(d["task_points_m"], sc.task.points_m)


def test_a_number_yaml_read_as_text_names_the_fix():
    """PyYAML (YAML 1.1) reads 1e-5 without a decimal point as a string: refused, with the fix."""
    import pytest

    from qmt_drake.config import fields
    from qmt_drake.errors import QmtInputError
    for call in (lambda: fields.vector({"k": [1.0, "1e-5"]}, "k", "w"), lambda: fields.num({"k": "2e3"}, "k", "w")):
        with pytest.raises(QmtInputError, match="write it with a decimal point"):
            call()
