"""`retime` with obstacles (issue 28): the user's path is checked for clearance before any timing. A hand-written
UR5 path clears the shipped totes (its smallest clearance reported, equal to the timed plan's and to a dense
independent sampling); in the cell with 4 cm deeper totes (docs/examples/ur5-deep-totes.yaml) the same path is
refused in one line saying where it collides, the two shapes and the depth (or, asked to report, timed with the
plan infeasible); a waypoint pushed into the tote's floor is named as colliding itself."""

import re

import numpy as np
import pytest

from qmt_drake.apps.cli import main
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.clearance import collision_model
from qmt_drake.planners.spatial_toppra import joint_path
from qmt_drake.retime import path_clearance, retime_path
from tests.spatial_fixtures import load_or_skip
from tests.test_obstacles import DEEP_TOTES, SCENARIOS
from tests.test_retime import HAND_PATH, NAMES, write_csv


@pytest.fixture(scope="module")
def ur5():
    return load_or_skip(str(SCENARIOS / "ur5-suction-bins.yaml"))


@pytest.fixture(scope="module")
def deep():
    return load_or_skip(str(DEEP_TOTES))


def _dense_min(sc, Q, s_from, s_to, n=1500):
    """Smallest signed distance (m) on n points of the path's spline over [s_from, s_to] (rad), one Drake
    query per point: independent of limits/clearance's sampling and refinement."""
    pp = joint_path(Q)
    cm = collision_model(sc)
    return min(cm.distance(q)[0] for q in pp.vector_values(np.linspace(s_from, s_to, n)).T)


def test_a_path_that_clears_reports_its_clearance(ur5, tmp_path, capsys):
    path = write_csv(tmp_path / "p.csv", NAMES, HAND_PATH)
    assert main(["retime", str(SCENARIOS / "ur5-suction-bins.yaml"), "--path", path]) == 0  # one line, no traceback
    line = capsys.readouterr().out.strip()
    assert "\n" not in line and "re-check max ratio" in line and "(suction)" in line
    plan = retime_path(ur5, path)
    assert f"; clearance {plan.info['path_clearance']['clearance_m']:.4f} m (carried/part vs obstacle/" in line
    c = plan.info["path_clearance"]
    assert 0.0 < c["clearance_m"] < 0.1 and c["clearance_pair"][1].startswith("obstacle/")
    assert plan.clearance["clearance_m"] == pytest.approx(c["clearance_m"], abs=2e-4)  # the timed plan's own
    assert plan.feasible
    L = float(np.asarray(joint_path(HAND_PATH).get_segment_times())[-1])
    assert _dense_min(ur5, HAND_PATH, 0.0, L, 3000) >= c["clearance_m"] - 1e-6


def test_a_path_through_the_deeper_totes_is_refused_with_where_and_how_deep(deep, tmp_path, capsys):
    with pytest.raises(QmtInputError) as exc:
        retime_path(deep, HAND_PATH)
    msg = str(exc.value)
    assert "\n" not in msg and "collides between waypoints" in msg and "overlaps obstacle/" in msg
    assert "every waypoint itself clears" in msg and "retime keeps your path's geometry" in msg
    k, depth_mm = re.search(r"between waypoints (\d+) and \d+ .* by ([\d.]+) mm", msg).groups()
    s = np.asarray(joint_path(HAND_PATH).get_segment_times())
    k = int(k)
    assert -_dense_min(deep, HAND_PATH, s[k], s[k + 1]) * 1e3 == pytest.approx(float(depth_mm), abs=0.2)
    # reported instead of refused (the API's collisions="report"): timed anyway, the plan infeasible
    rep = retime_path(deep, HAND_PATH, collisions="report")
    c = rep.info["path_clearance"]
    assert c["refusal"] == msg and c["clearance_m"] == pytest.approx(-float(depth_mm) / 1e3, abs=1e-4)
    assert rep.clearance["clearance_m"] == pytest.approx(c["clearance_m"], abs=2e-4) and not rep.feasible
    with pytest.raises(QmtInputError, match="collisions 'ignore'"):
        retime_path(deep, HAND_PATH, collisions="ignore")
    # the CLI: exit 2, the same one line
    path = write_csv(tmp_path / "p.csv", NAMES, HAND_PATH)
    assert main(["retime", str(DEEP_TOTES), "--path", path]) == 2
    # --collisions report: timed, the line says COLLIDES with the depth, exit 3 (not 0: the plan is infeasible)
    capsys.readouterr()
    assert main(["retime", str(DEEP_TOTES), "--path", path, "--collisions", "report"]) == 3
    line = capsys.readouterr().out.strip()
    assert "\n" not in line and f"clearance {c['clearance_m']:.4f} m (" in line and "; COLLIDES)" in line


def test_a_waypoint_inside_the_tote_floor_is_named(ur5):
    Q = HAND_PATH.copy()
    Q[0, 1] += 0.25  # the shoulder lowers the pick pose into tote A's floor
    inside = collision_model(ur5).distance(Q[0])[0]
    assert inside < 0.0
    with pytest.raises(QmtInputError, match=rf"waypoint 0 \({-inside * 1e3:.1f} mm\) collides itself"):
        path_clearance(ur5, Q, "path P")
