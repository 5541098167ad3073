"""One Plan type for all three scenario kinds (issue 27 item 3): a transfer, a spatial and an
energy-time plan are each a plan.Plan (no subclass), round-trip through write_json / load_plan with
equal samples, report only their own kind's summary fields (no NaN placeholder of another kind), and
keep their kind's facts as data. Plan files written by an earlier version (the goldens' plan_json,
tests/golden) still load and reproduce the golden samples."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from qmt_drake import api
from qmt_drake.errors import QmtInputError
from qmt_drake.plan import PLAN_KINDS, Plan, plan_kind
from qmt_drake.plan_files import load_plan

GOLDEN = Path(__file__).resolve().parent / "golden"
# kind -> a golden whose plan_json is a complete plan file of an earlier version (no digested samples)
OLD_FILES = {"transfer": "ch4-thesis", "energy_time": "ohsaka-fig3-snopt"}


def _old_file(case: str, tmp_path: Path) -> tuple[Path, dict]:
    golden = json.loads((GOLDEN / f"{case}.json").read_text())
    path = tmp_path / f"{case}.json"
    path.write_text(json.dumps(golden["plan_json"]))
    return path, golden["plan"]


@pytest.fixture(scope="module")
def plans(tmp_path_factory) -> dict[str, Plan]:
    """One plan of each kind: the transfer and energy-time ones read from old files, the spatial one
    planned (TOPP-RA on a coarse grid, the quickest spatial planner)."""
    tmp = tmp_path_factory.mktemp("old")
    out = {kind: load_plan(_old_file(case, tmp)[0]) for kind, case in OLD_FILES.items()}
    try:
        sc = api.load_scenario("ur5-suction-bins")
    except QmtInputError as exc:  # example-robot-data (a test extra) missing
        if "example-robot-data" not in str(exc):
            raise
        pytest.skip(str(exc))
    out["spatial_transfer"] = api.plan_with("toppra", sc, n_grid=300)
    return out


KINDS = ("transfer", "spatial_transfer", "energy_time")


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_is_the_one_plan_type(plans, kind):
    plan = plans[kind]
    assert type(plan) is Plan and plan.scenario_kind == kind
    assert plan_kind(kind) is PLAN_KINDS[kind]
    # the kind's facts are data on the one type, readable as attributes
    for name, value in plan.facts.items():
        assert getattr(plan, name) is value
    with pytest.raises(AttributeError):
        plan.no_such_fact  # noqa: B018


def test_only_the_spatial_and_energy_plans_carry_facts(plans):
    assert plans["transfer"].facts == {}
    assert {"hold_scale", "pose_times_s", "recheck"} <= set(plans["spatial_transfer"].facts)
    assert {"problem", "cost_z", "optima"} <= set(plans["energy_time"].facts)


@pytest.mark.parametrize("kind", KINDS)
def test_write_json_load_plan_round_trip_with_equal_samples(plans, kind, tmp_path):
    plan = plans[kind]
    path = tmp_path / "plan.json"
    plan.write_json(path)
    back = load_plan(path)
    assert type(back) is Plan and back.scenario_kind == kind and back.method == plan.method
    t = np.linspace(0.0, plan.motion_time_s, 57)
    for a, b in zip(plan.sample(t), back.sample(t)):
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12)
    assert back.feasible == plan.feasible
    assert sorted(back.facts) == sorted(plan.facts)


def _nan_keys(summary: dict) -> list[str]:
    return [k for k, v in summary.items() if isinstance(v, float) and math.isnan(v)]


def test_summary_has_no_field_of_another_kind_and_no_nan_placeholder(plans):
    keys = {kind: set(plans[kind].summary()) for kind in KINDS}
    common = {"scenario", "scenario_kind", "method", "feasible", "motion_time_s", "planner_wall_s"}
    own = {"transfer": {"peak_moment_Nm", "peak_motor_torque_Nm", "payload_mass_kg"},
           "spatial_transfer": {"hold_scale", "recheck_max_ratio", "max_pose_position_error_m"},
           "energy_time": {"cost_z", "energy_integral_N2m2s", "optima"}}
    for kind in KINDS:
        assert common <= keys[kind], kind
        assert own[kind] <= keys[kind], kind
        for other in KINDS:
            if other != kind:
                assert not own[other] & keys[kind], (kind, other)
        assert _nan_keys(plans[kind].summary()) == [], kind


@pytest.mark.parametrize("kind", sorted(OLD_FILES))
def test_a_file_written_by_an_earlier_version_loads_and_reproduces_its_golden_samples(plans, kind, tmp_path):
    path, record = _old_file(OLD_FILES[kind], tmp_path)
    plan = load_plan(path)
    assert type(plan) is Plan and plan.method == record["method"] and plan.feasible == record["feasible"]
    assert plan.motion_time_s == record["motion_time_s"]
    t = np.asarray(record["t_s"], float)
    for got, key in zip(plan.sample(t), ("q_rad", "qd_rad_s", "qdd_rad_s2")):
        np.testing.assert_allclose(got, np.asarray(record[key], float), rtol=0, atol=1e-12)


def test_replace_changes_fields_and_facts_and_refuses_unknown_names(plans):
    plan = plans["spatial_transfer"]
    other = plan.replace(method="x", hold_scale=2.0)
    assert type(other) is Plan and other.method == "x" and other.hold_scale == 2.0
    assert plan.method == "toppra" and other.facts is not plan.facts  # the original is untouched
    with pytest.raises(TypeError):
        plans["transfer"].replace(hold_scale=2.0)  # a transfer plan has no such fact
