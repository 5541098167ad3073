"""A saved plan re-checks as it did (issue 27 item 3): a planar plan without a closed form is stored as 1 kHz
samples (a quintic between them, ~1e-8 rad/s^2 off), so a plan at 0.999999999 of its limit could come back at
1.0000000009, infeasible. The planar Ruckig, trajopt, TOPP-RA, Drake Toppra and collocation plans also store
what rebuilds them exactly (plan_files.rebuild_spec: Ruckig's inputs, the B-spline, the path and TOPP-RA's
profile, Drake's q(s) and s(t) and collocation's PiecewisePolynomial by their coefficients, the slow-down, the
segments) and load from it: the same trajectory bit for bit, the same re-check."""

import json

import numpy as np
import pytest

from qmt_drake import load_plan, load_scenario, plan_with
from qmt_drake.errors import QmtInputError
from qmt_drake.sampling import piecewise_grid


def _round_trip(tmp_path, scenario, method, **options):
    plan = plan_with(method, load_scenario(scenario), **options)
    path = tmp_path / f"{scenario}-{method}.json"
    plan.write_json(path)
    return plan, load_plan(path), path


def _same_values(a, b):
    grid = piecewise_grid(a.trajectory.breakpoints_s[None, :], 10_000.0)
    for x, y in zip(a.trajectory.evaluate(grid.t_s, grid.t_piece_s), b.trajectory.evaluate(grid.t_s, grid.t_piece_s)):
        assert np.array_equal(x, y)


@pytest.mark.parametrize("scenario, options", [("thesis-ch4", {}), ("thesis-ch2", {"mode": "joint"})])
def test_a_saved_ruckig_plan_rechecks_as_it_did(tmp_path, scenario, options):
    plan, loaded, _ = _round_trip(tmp_path, scenario, "ruckig", **options)
    assert plan.feasible and loaded.feasible
    assert loaded.check.worst_ratio == plan.check.worst_ratio
    assert loaded.motion_time_s == plan.motion_time_s
    _same_values(plan, loaded)
    if scenario == "thesis-ch4":  # the case of the issue: at the limit to 1e-9
        assert abs(plan.check.worst_ratio - 1.0) < 1e-6


def test_a_saved_trajopt_plan_rechecks_as_it_did(tmp_path):
    plan, loaded, _ = _round_trip(tmp_path, "thesis-ch3", "trajopt", num_control_points=10)
    assert loaded.check.worst_ratio == plan.check.worst_ratio and loaded.feasible == plan.feasible
    _same_values(plan, loaded)


def test_a_rebuild_that_disagrees_with_its_samples_is_refused(tmp_path):
    _, _, path = _round_trip(tmp_path, "thesis-ch2", "ruckig")
    d = json.loads(path.read_text())
    d["rebuild"]["ruckig_inputs"]["max_jerk"] = [2 * x for x in d["rebuild"]["ruckig_inputs"]["max_jerk"]]
    path.write_text(json.dumps(d))
    with pytest.raises(QmtInputError, match="'rebuild' disagrees with its samples"):
        load_plan(path)
    # a malformed one is one line too (Ruckig refusing the inputs, a rebuild that is not a mapping)
    d["rebuild"]["ruckig_inputs"]["max_acceleration"] = [-1.0] * len(d["rebuild"]["ruckig_inputs"]["max_jerk"])
    path.write_text(json.dumps(d))
    with pytest.raises(QmtInputError, match="cannot rebuild its trajectory .ruckig failed"):
        load_plan(path)
    d["rebuild"] = [1, 2]
    path.write_text(json.dumps(d))
    with pytest.raises(QmtInputError, match="'rebuild' must be a mapping"):
        load_plan(path)


def test_a_saved_toppra_plan_rechecks_as_it_did(tmp_path):
    """via5-ch4's TOPP-RA plan (five segments on the traced spline path, slowed by the exact factor): at
    0.999999998 of its limit; from its samples it came back at 1.00026, infeasible."""
    plan, loaded, _ = _round_trip(tmp_path, "via5-ch4", "toppra")
    assert plan.feasible and loaded.feasible and abs(plan.check.worst_ratio - 1.0) < 1e-6
    assert loaded.check.worst_ratio == plan.check.worst_ratio
    _same_values(plan, loaded)


def test_a_saved_drake_toppra_plan_rechecks_as_it_did(tmp_path):
    """Drake Toppra's plan (q(s) and s(t) stored by their coefficients): from its samples thesis-ch2's came
    back at 0.70749 instead of 0.70712 of its limit."""
    plan, loaded, _ = _round_trip(tmp_path, "thesis-ch2", "toppra-drake")
    assert loaded.check.worst_ratio == plan.check.worst_ratio and loaded.feasible == plan.feasible
    _same_values(plan, loaded)


def test_a_saved_collocation_plan_rechecks_as_it_did(tmp_path):
    """A planar collocation plan (a Drake PiecewisePolynomial, stored by its coefficients)."""
    plan, loaded, _ = _round_trip(tmp_path, "thesis-ch4", "collocation")
    assert loaded.check.worst_ratio == plan.check.worst_ratio and loaded.feasible == plan.feasible
    _same_values(plan, loaded)
