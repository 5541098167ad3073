"""Session 17, an outsider's inputs to the Python API, retime/export files, hand-edited plan files and
scenario sections: each either works or is refused in one line naming the input and the fix (exit 2),
before any long work. Each test is a defect found by feeding such an input (a traceback, a silent
acceptance, a wrong answer, a refusal only after seconds of building)."""

import time

import numpy as np
import pytest
import yaml

from qmt_drake.apps import spatial_cli
from qmt_drake.config.scenario import SCENARIO_DIR
from qmt_drake.errors import QmtInputError
from tests.test_outsider_s16 import _refused, _spatial_yaml  # the same scenario-file and refusal helpers


def _no_build(monkeypatch):
    """Building the arm (URDF, IK of every path point: ~9 s on ANYmal + Kinova) fails the test."""
    def build(data):
        raise AssertionError("the scenario was built before the refusal")
    monkeypatch.setattr(spatial_cli, "build_spatial_scenario", build)


@pytest.mark.parametrize("argv", [
    ["simulate", "{p}", "--actuator", "dc_motor"],
    ["plan", "{p}", "--method", "toppra", "--carried", "--carried-feedforward", "full"],
])
def test_dc_motor_without_motor_section_refused_before_building(tmp_path, capsys, monkeypatch, argv):
    # the refusal came only after the arm was built (IK of every path point): ~9 s on ANYmal + Kinova
    path = _spatial_yaml(tmp_path, actuators__motor=None)
    _no_build(monkeypatch)
    line = _refused(capsys, *[a.format(p=path) for a in argv])
    assert "actuator dc_motor needs actuators.motor" in line


# --- the Python API -------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def ur5():
    from qmt_drake import load_scenario
    return load_scenario("ur5-suction-bins")


@pytest.fixture(scope="module")
def ur5_plan(ur5):
    from qmt_drake import plan_with
    return plan_with("toppra", ur5, n_grid=100)


@pytest.fixture(scope="module")
def ch4():
    from qmt_drake import load_scenario
    return load_scenario("thesis-ch4")


def test_plan_sample_2d_times_refused_on_every_kind(ur5_plan, ch4):
    # a (1, 2) array of times: a pybind TypeError traceback on a spatial plan, a (1, 2, n) answer on a planar one
    from qmt_drake import plan_with
    planar = plan_with("thesis", ch4)
    for p in (ur5_plan, planar):
        with pytest.raises(QmtInputError, match=r"Plan.sample: t_s: got an array of shape \(1, 2\); give a time"):
            p.sample([[0.1, 0.2]])
        assert p.sample([0.1, 0.2])[0].shape[0] == 2  # a 1-D array still works


def test_retime_cli_n_grid_and_ga_priced(tmp_path, capsys, monkeypatch):
    # --n-grid 10^9 filled 23 GB until the kernel killed the process; --generations 10^8 ran for months, unpriced
    from qmt_drake.apps import retime_command

    def reached(*a, **k):
        raise AssertionError("reached the retime (without the check: 23 GB or months here)")
    monkeypatch.setattr(retime_command, "retime_path", reached)
    monkeypatch.setattr(retime_command, "retime_planar_path", reached)
    path = tmp_path / "p.csv"
    path.write_text("shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint\n"
                    "-0.791,-1.145,1.993,-2.418,-1.571,0.0\n0.780,-1.145,1.993,-2.418,-1.571,0.0\n")
    line = _refused(capsys, "retime", "ur5-suction-bins", "--path", path, "--n-grid", 10 ** 9)
    assert "--n-grid 1000000000 must be <= 100000" in line
    line = _refused(capsys, "retime", "ur5-suction-bins", "--path", path, "--method", "ga", "--generations", 10 ** 8)
    assert line.startswith("qmt-drake: error: --generations 100000000: a spatial GA") and "--allow-large" in line
    line = _refused(capsys, "retime", "thesis-ch4", "--path", path, "--n-grid", 10 ** 9)
    assert "--n-grid 1000000000 must be <= 100000" in line


def test_retime_planar_n_grid_range_and_numpy_int(ch4, monkeypatch):
    # retime_planar_path(n_grid=10**9) reached TOPP-RA (23 GB), and np.int64(200) was refused as "not an integer"
    from qmt_drake import retime_planar

    def reached(*a, **k):
        raise RuntimeError("reached TOPP-RA")
    monkeypatch.setattr(retime_planar, "toppra_segment", reached)  # (without the check: no 23 GB here)
    with pytest.raises(QmtInputError, match=r"n_grid 1000000000 must be <= 100000"):
        retime_planar.retime_planar_path(ch4, [[0.0, 0.0], [1.0, 1.0]], n_grid=10 ** 9)
    with pytest.raises(RuntimeError, match="reached TOPP-RA"):  # the n_grid check passed
        retime_planar.retime_planar_path(ch4, [[0.0, 0.0], [1.0, 1.0]], n_grid=np.int64(200))


# --- export: the stream as the controller interpolates it ---------------------------------------------------------

def test_export_stream_that_cuts_into_a_tote_does_not_hold(ur5, ur5_plan, tmp_path):
    # at 1 Hz the linear stream kept every limit and was reported "keeps the limits" (exit 0) while it put the
    # box 81 mm into bin B's wall: the stream's clearance was never checked
    from qmt_drake.apps.export_command import summary_line
    from qmt_drake.export import export_plan
    from qmt_drake.limits.clearance import clearance
    rep = export_plan(ur5, ur5_plan, "csv", 1.0, tmp_path / "s.csv", "linear")
    rc = rep["stream_recheck"]
    independent = clearance(ur5, rep["stream"], 4000.0)["clearance_m"]  # a finer sampling of the same stream
    assert rc["clearance_m"] < -0.01 and independent < -0.01
    assert not rep["stream_holds"] and "the stream COLLIDES" in summary_line(rep)


def test_export_rate_slower_than_the_plan_refused(ur5, ur5_plan, tmp_path):
    # --rate 0.001 wrote 2 samples (start, and the goal at 1000 s), re-checked 2e6 points for 54 s (the budget
    # priced the plan's 2 s, not the stream's 1000 s) and said "keeps the limits": the plan's path was gone
    from qmt_drake.export import export_plan
    t = time.perf_counter()
    with pytest.raises(QmtInputError, match=r"--rate 0.001: one period \(1e\+03 s\) is longer than the"):
        export_plan(ur5, ur5_plan, "ros2", 1e-3, tmp_path / "s.yaml")
    assert time.perf_counter() - t < 1.0 and not (tmp_path / "s.yaml").exists()


# --- defects in files owned by other helpers this session: the failing test, the fix in the report -----------------

def _no_timing(monkeypatch):
    """retime.py's TOPP-RA and GA fail the test if reached (an unchecked n_grid of 10^9 filled 23 GB)."""
    from qmt_drake import retime

    def reached(*a, **k):
        raise AssertionError("the timing ran before the refusal")
    monkeypatch.setattr(retime, "_retime_toppra", reached)
    monkeypatch.setattr(retime, "plan_ga_spatial", reached)


@pytest.mark.parametrize("path, kw, needle", [
    ([[0.0, 1.0], [1.0, 2.0, 3.0]], {}, r"joint path: .*\(K, 6\) array"),  # ragged: numpy's ValueError traceback
    ([["a"] * 6, ["b"] * 6], {}, r"joint path: .*numbers"),  # text: "could not convert string to float"
    ({"joint_names": "shoulder_pan_joint", "points": []}, {}, r"joint_names must be a list"),  # "joint 'o' is named twice"
    ("Q", {"n_grid": 10 ** 9}, r"n_grid 1000000000 must be <= 100000"),  # 23 GB, then the kernel's OOM killer
    ("Q", {"n_grid": np.int64(200)}, r"the timing ran"),  # a numpy integer refused as "not an integer"
    ("Q", {"ngrid": 200}, r"unknown .*ngrid.*n_grid"),  # "option 'ngrid' is a GA option"
    ("Q", {"method": "ga", "generations": 10 ** 8}, r"allow_large"),  # a GA of months, unpriced
])
def test_retime_path_arguments_one_line(ur5, monkeypatch, path, kw, needle):
    from qmt_drake.retime import retime_path
    _no_timing(monkeypatch)
    with pytest.raises((QmtInputError, AssertionError), match=needle) as info:
        retime_path(ur5, ur5.q_path_rad if isinstance(path, str) else path, **kw)
    assert info.type is QmtInputError or "the timing ran" in needle


@pytest.mark.parametrize("scenario", ["ur5-suction-bins", "ch4"])
def test_retime_path_scenario_argument(ch4, ur5, monkeypatch, scenario):
    # a name (the API's other functions load it) or a planar scenario: AttributeError 'joint_names'
    from qmt_drake.retime import retime_path
    _no_timing(monkeypatch)
    sc = ch4 if scenario == "ch4" else scenario
    with pytest.raises((QmtInputError, AssertionError), match=r"retime_path|the timing ran") as info:
        retime_path(sc, ur5.q_path_rad)  # the IK path clears the bins (its two ends joined straight collide)
    assert info.type is QmtInputError or scenario != "ch4"


def test_avoid_with_a_task_pose_inside_an_obstacle_names_the_fix(tmp_path, capsys):
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-suction-bins.yaml").read_text())
    raw["world"]["obstacles"].append({"name": "block", "kind": "box", "size_m": [0.1, 0.1, 0.1],
                                      "pose": {"xyz_m": [0.45, -0.30, 0.05]}})  # around the pick pose's box
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw))
    line = _refused(capsys, "plan", path, "--method", "toppra", "--avoid", within_s=30)
    assert "task pose 0" in line and "block" in line and "give a margin below" not in line


# --- plan files edited by hand -----------------------------------------------------------------------------------

@pytest.mark.parametrize("key, value", [("method", 5), ("method", ""), ("scenario", ["ur5-suction-bins"])])
def test_plan_file_with_a_method_or_scenario_that_is_no_name(ur5, ur5_plan, tmp_path, key, value):
    # method 5 loaded and ran: "ur5-suction-bins 5 x1: carried, ..."
    import json

    from qmt_drake import load_plan
    f = tmp_path / "p.json"
    ur5_plan.write_json(f)
    d = json.loads(f.read_text())
    d[key] = value
    f.write_text(json.dumps(d))
    with pytest.raises(QmtInputError, match=rf"plan file .*p.json: its {key} .* is not a name \(edited by hand\?\)"):
        load_plan(f, ur5)


def test_overrides_take_numpy_arrays_and_scalars():
    # load_scenario(overrides={"payload": {"com_m": np.array([...])}}) was refused: "must be a list of numbers"
    from qmt_drake.config.fields import merge_overrides
    base = {"payload": {"mass_kg": 2.0, "com_m": [0.0, 0.0, 0.08]}}
    out = merge_overrides(base, {"payload": {"com_m": np.array([0.0, 0.01, 0.08]), "mass_kg": np.float32(1.5)}})
    assert out["payload"] == {"mass_kg": 1.5, "com_m": [0.0, 0.01, 0.08]}
    assert type(out["payload"]["com_m"]) is list and type(out["payload"]["mass_kg"]) is float
    from qmt_drake.spatial_data import parse_spatial_data
    d = parse_spatial_data("ur5-suction-bins", {"payload": {"com_m": np.array([0.0, 0.0, 0.07])}})
    assert d.payload.com_m.tolist() == [0.0, 0.0, 0.07]
    with pytest.raises(QmtInputError, match=r"payload.mass_kg must be positive, got nan"):  # still checked
        parse_spatial_data("ur5-suction-bins", {"payload": {"mass_kg": np.float64("nan")}})


def test_success_with_motor_parameters_and_no_motor_section_refused_before_building(tmp_path, capsys, monkeypatch):
    # the uncertainty section draws motor constants the scenario does not have: refused only once the arm was built
    path = _spatial_yaml(tmp_path, actuators__motor=None)
    _no_build(monkeypatch)
    line = _refused(capsys, "plan", path, "--method", "toppra", "--success", "0.9")
    assert "uncertainty.parameters.gear_efficiency scales its DC motors" in line  # (the file's keys sorted)
    assert "add actuators.motor or drop that parameter" in line


def test_export_plan_python_arguments_one_line(ur5, ur5_plan, ch4, tmp_path):
    # each reached a traceback (AttributeError, TypeError, a numpy broadcast ValueError), or was taken: rate True as
    # 1 Hz, hold "yes"; a numpy integer rate was refused as not a number
    from qmt_drake import plan_with
    from qmt_drake.export import export_plan
    out = tmp_path / "s.csv"
    planar = plan_with("thesis", ch4)
    for args, kw, needle in [
        (("thesis-ch4", planar, "csv", 125, out), {}, r"scenario 'thesis-ch4' is a name; pass load_scenario"),
        ((ch4, "p.json", "csv", 125, out), {}, r"plan 'p.json' is not a Plan"),
        ((ch4, ur5_plan, "csv", 125, out), {}, r"a spatial \(3-D\) plan for scenario ur5-suction-bins, not for a planar"),
        ((ch4, planar, "csv", 125, 5), {}, r"export_plan: out: got 5"),
        ((ch4, planar, "csv", True, out), {}, r"--rate True must be a number"),
        ((ch4, planar, "csv", 125, out), {"hold": "yes"}, r"hold 'yes' must be True or False"),
    ]:
        with pytest.raises(QmtInputError, match=needle):
            export_plan(*args, **kw)
    assert not out.exists()
    assert export_plan(ch4, planar, "csv", np.int64(125), out)["rate_hz"] == 125.0


def test_vector_message_says_numbers_once():
    # "actuators.torque_limit_Nm must be a list of numbers (numbers), got 150.0"
    from qmt_drake.spatial_data import parse_spatial_data
    with pytest.raises(QmtInputError) as info:
        parse_spatial_data("ur5-suction-bins", {"actuators": {"torque_limit_Nm": 150.0}})
    assert str(info.value).endswith("actuators.torque_limit_Nm must be a list of numbers, got 150.0")


@pytest.mark.parametrize("key, value", [("resistance_ohm", [1.0, -1.0]), ("resistance_ohm", [1.0, 0.0]),
                                        ("torque_constant_Nm_per_A", [0.05, float("nan")]),
                                        ("gear_ratio", [100.0, float("inf")]), ("voltage_limit_V", [24.0, 0.0])])
def test_dc_motor_params_refuse_non_physical_values(key, value):
    # a user composing DcMotorWithGear in their own diagram: a zero or negative resistance gave inf/NaN torques
    from qmt_drake.systems.dc_motor import DcMotorParams
    kw = {"torque_constant_Nm_per_A": [0.05, 0.05], "resistance_ohm": [1.0, 1.0], "gear_ratio": [100.0, 100.0],
          "voltage_limit_V": [24.0, 24.0], "current_limit_A": [5.0, np.inf], "efficiency": [0.8, 0.8]}
    DcMotorParams(**kw)  # the nominal one (an unlimited current) builds
    with pytest.raises(QmtInputError, match=rf"DcMotorParams.{key} .* must be .*positive for every joint"):
        DcMotorParams(**{**kw, key: value})


def test_spatial_sweep_plan_file_checked_before_the_cases_run(ur5_plan, tmp_path):
    # an edited plan file in a spatial sweep failed in every worker (exit 4), named by the worker's temporary copy
    import json

    from qmt_drake.sweep.spatial_cases import build_spatial_cases
    from qmt_drake.sweep.spec import load_spec
    f = tmp_path / "edited.json"
    ur5_plan.write_json(f)
    d = json.loads(f.read_text())
    d["rebuild"]["k"] = 2 * d["rebuild"]["k"]  # the stored samples no longer match
    f.write_text(json.dumps(d))
    spec = load_spec({"name": "s", "scenario": "ur5-suction-bins", "plans": [{"file": str(f)}],
                      "parameters": {"friction": [0.4]}}, name="s")
    with pytest.raises(QmtInputError, match=rf"plan file {f}: its rebuilt trajectory differs"):
        build_spatial_cases(spec)


def test_planar_sweep_plan_file_checked_before_the_cases_run(ur5_plan, tmp_path):
    # a spatial plan file in a thesis-ch4 sweep: every case failed in the workers (exit 4), named by a temporary copy
    from qmt_drake.sweep.cases import build_cases
    from qmt_drake.sweep.spec import load_spec
    f = tmp_path / "ur5.json"
    ur5_plan.write_json(f)
    spec = load_spec({"name": "s", "scenario": "thesis-ch4", "plans": [{"file": str(f)}],
                      "parameters": {"friction": [0.3]}}, name="s")
    with pytest.raises(QmtInputError, match=rf"plan file {f} is a spatial \(3-D\) plan for scenario ur5-suction-bins"):
        build_cases(spec)
