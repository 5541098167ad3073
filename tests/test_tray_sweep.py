"""Sweeps and `plan --success` on the tray: a case varies the simulated bottle (friction, mass,
centre of mass) while the plan and the servos' shaped goals keep the nominal scenario, and what
the tray co-simulation does not model is refused in one line before anything runs."""

import json
from pathlib import Path

import numpy as np
import pytest

from qmt_drake.apps.cli import main
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import jsonable
from qmt_drake.planners import plan_with
from qmt_drake.sweep.cases import build_cases, make_plan_doc, run_case
from qmt_drake.sweep.spec import load_spec
from qmt_drake.transfer_scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[1] / "models" / "scenarios"


def _tray_copy(tmp_path, uncertainty_yaml: str) -> Path:
    """crane-tray.yaml with its URDF path made absolute and its uncertainty section replaced."""
    text = (SCENARIOS / "crane-tray.yaml").read_text()
    text = text.replace("../crane_x7_planar.urdf", str((SCENARIOS.parent / "crane_x7_planar.urdf").resolve()))
    text = text[:text.index("uncertainty:")] + uncertainty_yaml
    p = tmp_path / "tray-u.yaml"
    p.write_text(text)
    return p


def test_success_on_the_tray_refuses_a_magnet_parameter_in_one_line(tmp_path, capsys):
    p = _tray_copy(tmp_path, "uncertainty:\n  parameters:\n    coil_current_scale: {dist: normal, mean: 1.0, std: 0.03}\n")
    assert main(["plan", str(p), "--method", "toppra", "--success", "0.9"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "coil_current_scale" in err and "tray hand" in err


def test_a_tray_sweep_refuses_a_dc_motor_option():
    spec = load_spec({"name": "t", "scenario": "crane-tray", "plans": [{"method": "toppra"}],
                      "sim": {"feedforward": "full"}, "parameters": {"friction": 0.3}})
    with pytest.raises(QmtInputError, match="sim.feedforward"):
        build_cases(spec)


def test_tray_cases_vary_the_simulated_bottle_and_not_the_plan(tmp_path):
    sc = load_scenario("crane-tray")
    plan = plan_with("toppra", sc)
    pf = tmp_path / "p.json"
    pf.write_text(json.dumps(jsonable(plan.to_json_dict())))
    spec = load_spec({"name": "t", "scenario": "crane-tray", "plans": [{"file": str(pf), "label": "toppra"}],
                      "parameters": {"time_scale": 1.1, "mass_scale": 1.2, "friction": {"values": [0.15, 0.3]}}})
    cases, refs = build_cases(spec)
    assert len(cases) == 2 and len(refs) == 1
    doc = make_plan_doc(next(iter(refs.values())))
    out = {c.parameters["friction"]: run_case(c, doc) for c in cases}
    for r in out.values():
        assert r["status"] == "ok"
        assert r["payload_mass_kg"] == pytest.approx(1.2 * sc.payload.mass_kg, rel=1e-12)
        assert r["plan_motion_time_s"] == pytest.approx(plan.motion_time_s, rel=1e-12)
    # TOPP-RA plans the slide ratio to 1 at mu = 0.3 x plan_margin 0.8 = 0.24; at mu 0.15 the
    # bottle must slide (the plan asks for up to 0.24 g of tangential acceleration per g)
    assert out[0.3]["outcome"] == "carried" and out[0.3]["held"] is True
    assert out[0.15]["outcome"] != "carried" and out[0.15]["held"] is False
    assert out[0.15]["max_slip_m"] > 1e-3


def test_a_delayed_goal_stream_is_the_same_stream_later():
    from qmt_drake.tray.execute import delayed, plan_schedule
    sc = load_scenario("crane-tray")
    s = plan_schedule(plan_with("toppra", sc), time_scale=1.1, period_s=1e-3, shaped_for=sc)
    d = delayed(s, 0.02)
    t = np.random.default_rng(0).uniform(0.0, s.t_end_s, 200)
    np.testing.assert_array_equal(d.goal_at(t + 0.02), s.goal_at(t))
    np.testing.assert_array_equal(d.goal_at(np.array([0.0, 0.019])), s.goals[[0, 0]])
    assert d.t_end_s == pytest.approx(s.t_end_s + 0.02)
    with pytest.raises(QmtInputError, match="servo delay"):
        delayed(s, 0.5)


def test_servo_delay_is_a_tray_parameter_and_refused_for_the_magnet():
    spec = load_spec({"name": "t", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
                      "parameters": {"servo_delay_s": 0.01}})
    with pytest.raises(QmtInputError, match="servo_delay_s.*magnet hand"):
        build_cases(spec)
    spec = load_spec({"name": "t", "scenario": "crane-tray", "plans": [{"method": "toppra"}],
                      "parameters": {"servo_delay_s": {"values": [0.0, 0.03]}, "time_scale": 1.1}})
    cases, refs = build_cases(spec)
    doc = make_plan_doc(next(iter(refs.values())))
    out = [run_case(c, doc) for c in cases]
    assert [r["parameters"]["servo_delay_s"] for r in out] == [0.0, 0.03]
    # the same motion 30 ms later: the bottle is carried either way and the arm arrives
    assert all(r["outcome"] == "carried" for r in out)
