"""The scenario as plain typed data (qmt_drake/scenario_data.py): one loader for every kind gives a frozen
dataclass with no Drake object and no built model in it; a bad value is refused in one line naming the
file and the key path; the data builds the same scenario as the kind's own loader."""

import dataclasses
import pickle

import numpy as np
import pytest
import yaml

from qmt_drake.apps.cli import main
from qmt_drake.config.resolve import SCENARIO_DIR, TASK_DIR
from qmt_drake.config.sections import Scenario
from qmt_drake.design.tasks import Task, load_task
from qmt_drake.energy.experiments import EnergyScenarioData
from qmt_drake.energy.scenario import get_experiment
from qmt_drake.errors import QmtInputError
from qmt_drake.scenario_data import build_scenario, load_scenario_data, scenario_data_kind
from qmt_drake.spatial_data import SpatialScenarioData
from qmt_drake.spatial_task import SpatialScenario, load_spatial_scenario

KINDS = {"thesis-ch4": Scenario, "crane-tray": Scenario, "ur5-suction-bins": SpatialScenarioData,
         "ur5-magnet-part": SpatialScenarioData, "panda-tray-cup": SpatialScenarioData,
         "ohsaka-fig3": EnergyScenarioData, "peg_in_hole": Task}
# built objects that must never sit inside the data (they are what the builders make)
BUILT = {"SpatialChain", "SpatialIK", "GripModel", "ArmModel", "PlanarChain", "LimitSet", "VerticalArm",
         "MultibodyPlant", "BottleSpec"}


def _foreign(x, path="data", seen=None) -> list[str]:
    """Paths inside x (dataclass fields and instance attributes, mappings, sequences, object arrays) that
    hold a pydrake object or a built model."""
    seen = set() if seen is None else seen
    if id(x) in seen or x is None or isinstance(x, (str, bytes, int, float, bool, complex)):
        return []
    seen.add(id(x))
    t = type(x)
    if t.__module__.startswith("pydrake") or t.__name__ in BUILT:
        return [f"{path}: {t.__module__}.{t.__name__}"]
    out = []
    if isinstance(x, dict):
        for k, v in x.items():
            out += _foreign(k, f"{path}[{k!r}] key", seen) + _foreign(v, f"{path}[{k!r}]", seen)
    elif isinstance(x, (list, tuple, set, frozenset)):
        for i, v in enumerate(x):
            out += _foreign(v, f"{path}[{i}]", seen)
    elif isinstance(x, np.ndarray):
        if x.dtype == object:
            for i, v in enumerate(x.ravel()):
                out += _foreign(v, f"{path}.flat[{i}]", seen)
    elif hasattr(x, "__dict__") and not isinstance(x, type):
        for k, v in vars(x).items():
            out += _foreign(v, f"{path}.{k}", seen)
    return out


def test_the_walk_finds_a_drake_object_and_a_built_model():
    """The check below can fail: a plant or a chain hidden two levels down is found."""
    sc = load_spatial_scenario("ur5-magnet-part")
    assert any("MultibodyPlant" in p for p in _foreign({"a": [sc]}))
    assert any("SpatialChain" in p for p in _foreign((1, {"chain": sc.chain})))


@pytest.mark.parametrize("name", sorted(KINDS))
def test_every_kind_loads_as_plain_frozen_data(name):
    data = load_scenario_data(name)
    assert type(data) is KINDS[name]
    assert dataclasses.is_dataclass(data) and data.__dataclass_params__.frozen
    assert _foreign(data) == []
    assert _foreign(pickle.loads(pickle.dumps(data))) == []  # plain data pickles


def test_kinds_are_told_apart_by_the_file():
    assert scenario_data_kind("thesis-ch2") == "transfer"
    assert scenario_data_kind(SCENARIO_DIR / "panda-tray-cup.yaml") == "spatial_transfer"
    assert scenario_data_kind("ohsaka-fig2") == "energy_time"
    assert scenario_data_kind(TASK_DIR / "task1_welding_plate.yaml") == "design_task"


def _copy(tmp_path, name, section, key, value):
    raw = yaml.safe_load((SCENARIO_DIR / f"{name}.yaml").read_text())
    for k in ("urdf",):  # a relative URDF path still finds its file from the copy
        if k in raw.get("arm", {}) and not raw["arm"][k].startswith("/") and "package" not in raw["arm"]:
            raw["arm"][k] = str((SCENARIO_DIR / raw["arm"][k]).resolve())
    node = raw
    for s in section:
        node = node[s]
    node[key] = value
    p = tmp_path / f"{name}-bad.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


@pytest.mark.parametrize("name,section,key,value,expect", [
    ("ur5-suction-bins", ["hand"], "cup_radius_m", -0.01, "ur5-suction-bins-bad.yaml: hand.cup_radius_m must be positive"),
    ("panda-tray-cup", ["hand", "cup"], "radius_m", "4 cm", "panda-tray-cup-bad.yaml: hand.cup.radius_m must be a number"),
    ("ur5-magnet-part", ["limits"], "check_rate_hz", True, "ur5-magnet-part-bad.yaml: limits.check_rate_hz must be a number"),
    ("ohsaka-fig3", ["family"], "m", 2.5, "ohsaka-fig3-bad.yaml: family.m must be an integer"),
    ("thesis-ch4", ["limits"], "motor_torque_limit_Nm", [0.064, -1], "limits.motor_torque_limit_Nm must be a list of positive"),
])
def test_a_bad_value_names_the_file_and_the_key_path(tmp_path, capsys, name, section, key, value, expect):
    p = _copy(tmp_path, name, section, key, value)
    with pytest.raises(QmtInputError) as err:
        load_scenario_data(p)
    msg = str(err.value)
    assert expect in msg and "\n" not in msg
    assert main(["plan", str(p), "--method", "toppra" if name != "ohsaka-fig3" else "snopt"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and expect in lines[0]


def test_a_design_task_names_the_unit_by_its_key_path(tmp_path):
    raw = yaml.safe_load((TASK_DIR / "peg_in_hole.yaml").read_text())
    raw["units"][0]["position_m"] = [0.5, 0.0]
    p = tmp_path / "peg.yaml"
    p.write_text(yaml.safe_dump(raw))
    with pytest.raises(QmtInputError, match=r"peg\.yaml: units\[0\]\.position_m has 2 entries; give 3"):
        load_scenario_data(p)


@pytest.mark.parametrize("name", ["ur5-suction-bins", "panda-tray-cup"])
def test_spatial_data_builds_the_same_scenario(name):
    data = load_scenario_data(name)
    built = build_scenario(pickle.loads(pickle.dumps(data)))
    ref = load_spatial_scenario(name)
    assert isinstance(built, SpatialScenario)
    assert built.joint_names == ref.joint_names and built.hand_kind == ref.hand_kind
    for key in ("q_path_rad", "q_poses_rad", "path_points_m", "velocity_limit_rad_s", "acceleration_limit_rad_s2",
                "jerk_limit_rad_s3", "torque_limit_Nm"):
        assert np.array_equal(getattr(built, key), getattr(ref, key)), key
    assert np.array_equal(built.drive["reflected_inertia_kgm2"], ref.drive["reflected_inertia_kgm2"])
    q, qd = ref.q_path_rad, np.full_like(ref.q_path_rad, 0.3)  # the chains: same kinematics, carried part, rotors
    a, b = built.chain.evaluate(q, qd, -qd), ref.chain.evaluate(q, qd, -qd)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


def test_energy_data_builds_the_same_experiment():
    data = load_scenario_data("ohsaka-fig4")
    built, ref = build_scenario(data), get_experiment("ohsaka-fig4")
    for f in dataclasses.fields(ref):
        if f.name != "arm":
            assert getattr(built, f.name) == getattr(ref, f.name), f.name
    assert np.array_equal(built.arm.length_m, ref.arm.length_m) and built.arm.tip_mass_kg == ref.arm.tip_mass_kg


def test_transfer_and_design_data_are_their_own_scenario():
    data = load_scenario_data("crane-tray")
    assert type(data) is Scenario and not hasattr(data, "arm")  # plain data: the loader's arm is not carried
    assert build_scenario(data).fingerprint() == data.fingerprint()
    assert build_scenario(data).arm.n_dof == len(data.limits.motor_torque_limit_Nm)
    task = load_scenario_data("peg_in_hole")
    assert all(np.array_equal(a, b) for a, b in zip(task.arrays(), load_task("peg_in_hole").arrays()))
