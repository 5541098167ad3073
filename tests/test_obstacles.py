"""world.obstacles (model/obstacles.py), the clearance re-check (limits/clearance.py) and the
co-simulation's `collided` outcome (sim/spatial_cosim.collision_check)."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.clearance import (
    HORIZON_M,
    CollisionModel,
    carried_shapes,
    clearance,
    clearance_of_states,
)
from qmt_drake.model.obstacles import Obstacle, parse_obstacles, read_mesh_points
from qmt_drake.outcome import OUTCOMES, with_collision
from qmt_drake.planners.spatial_plan_io import make_spatial_plan
from qmt_drake.planners.spatial_trajectory import PolyTrajectory
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from tests.spatial_fixtures import edited_copy, load_or_skip, shipped_toppra

SCENARIOS = Path(__file__).resolve().parents[1] / "models" / "scenarios"
DEEP_TOTES = Path(__file__).resolve().parents[1] / "docs" / "examples" / "ur5-deep-totes.yaml"

# one revolute joint about world z; link "arm" carries a sphere of radius 0.05 m at x = 0.5 m
ONE_LINK_URDF = """<robot name="one">
  <link name="base"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="arm"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.5 0 0"/><geometry><sphere radius="0.05"/></geometry></collision></link>
  <link name="hand"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <joint name="hand_fix" type="fixed"><parent link="arm"/><child link="hand"/><origin xyz="1.0 0 0"/></joint>
</robot>
"""


def one_link(tmp_path, obstacles, side_m=0.1):
    """A stand-in scenario: ONE_LINK_URDF with a carried cube of side side_m at the hand (x = 1 m at q = 0;
    a cube's principal moments are m s^2 / 6)."""
    urdf = tmp_path / "one.urdf"
    urdf.write_text(ONE_LINK_URDF)
    body = SimpleNamespace(mass_kg=1.0, com_m=np.zeros(3), inertia_kgm2=np.eye(3) * side_m ** 2 / 6)
    return SimpleNamespace(urdf=urdf, hand_frame="hand", lock_joints={}, torque_limit_Nm=np.array([10.0]),
                           velocity_limit_rad_s=np.array([2.0]), hand_kind="suction", body=body,
                           obstacles=tuple(obstacles))


def test_refusals_name_every_bad_entry():
    raw = [{"kind": "box", "size_m": [0.1, -0.1, 0.1], "pose": {"xyz_m": [0, 0, 0]}},
           {"kind": "sphere", "pose": {"xyz_m": [0, 0, 0]}},
           {"kind": "cylinder", "radius_m": 0.1, "length_m": 0.2, "pose": {"xyz_m": [0, 0]}},
           {"kind": "box", "size_m": [0.1, 0.1, 0.1], "pose": {"xyz_m": [0, 0, 0]}, "colour": "red"},
           {"kind": "mesh", "file": "nowhere.obj", "pose": {"xyz_m": [0, 0, 0]}},
           {"kind": "bin", "size_m": [0.3, 0.3, 0.2], "wall_m": 0.2, "pose": {"xyz_m": [0, 0, 0]}},
           {"kind": "box", "size_m": [0.1, 0.1, 0.1], "pose": {"xyz_m": [1, 0, 0]}}]
    with pytest.raises(QmtInputError) as e:
        parse_obstacles(raw, "world.obstacles", Path("."))
    lines = str(e.value).splitlines()
    assert len(lines) == 6
    for i, key in ((0, "size_m"), (1, "kind"), (2, "pose.xyz_m"), (3, "colour"), (4, "file"), (5, "wall_m")):
        assert f"world.obstacles[{i}]" in lines[i] and key in lines[i], lines[i]
    with pytest.raises(QmtInputError, match=r"world.obstacles must be a list"):
        parse_obstacles({"kind": "box"}, "world.obstacles", Path("."))


def test_scenario_refuses_a_bad_world_before_the_arm(tmp_path):
    def edit(raw):
        raw["world"] = {"obstacles": [{"kind": "box", "size_m": [0.1, 0.1], "pose": {"xyz_m": [0, 0, 0]}}]}
    p = edited_copy(SCENARIOS / "ur5-suction-bins.yaml", tmp_path, edit)
    with pytest.raises(QmtInputError, match=r"world.obstacles\[0\].size_m has 2 entries"):
        load_spatial_scenario(p)


def test_bin_is_five_boxes_and_mesh_points(tmp_path):
    obs = parse_obstacles([{"name": "b", "kind": "bin", "size_m": [0.4, 0.3, 0.2], "wall_m": 0.01,
                            "pose": {"xyz_m": [1, 2, 3], "rpy_rad": [0, 0, np.pi / 2]}}], "w", tmp_path)
    assert [o.name for o in obs] == ["b/floor", "b/wall_x-", "b/wall_x+", "b/wall_y-", "b/wall_y+"]
    # turned by 90 degrees about z: the bin's x+ wall is at world y = 2 + (0.4 - 0.01) / 2
    assert np.allclose(obs[2].xyz_m, [1, 2.195, 3.1], atol=1e-12)
    stl = tmp_path / "tet.stl"
    stl.write_text("solid t\n" + "".join(f"facet normal 0 0 1\nouter loop\nvertex {a}\nvertex {b}\nvertex {c}\n"
                                           "endloop\nendfacet\n" for a, b, c in
                                           [("0 0 0", "1 0 0", "0 1 0"), ("0 0 0", "0 0 1", "1 0 0")]) + "endsolid t\n")
    assert read_mesh_points(stl, "w").shape == (4, 3)
    flat = tmp_path / "flat.obj"
    flat.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n")
    with pytest.raises(QmtInputError, match="no volume"):
        parse_obstacles([{"kind": "mesh", "file": "flat.obj", "pose": {"xyz_m": [0, 0, 0]}}], "w", tmp_path)


def test_clearance_against_closed_forms(tmp_path):
    """The sphere (radius 0.05 at x = 0.5 on the link) and the carried cube (side 0.1 at x = 1) against a
    box whose face is at a known distance; the link turned by q about z moves both on circles."""
    wall = Obstacle("wall", "box", (0.0, 0.85, 0.0), size_m=(4.0, 1.0, 1.0))  # faces at y = 0.35 and 1.35
    sc = one_link(tmp_path, [wall])
    cm = CollisionModel(sc)
    d, a, b = cm.distance([0.0])  # sphere centre at y = 0 and the cube's face at y = 0.05: beyond HORIZON_M
    assert (d, a, b) == (HORIZON_M, "", "")
    q = 0.25  # the cube's centre at (cos q, sin q): its nearest corner is what reaches the wall first
    c = np.array([np.cos(q), np.sin(q)])
    corners = c + 0.05 * np.array([[np.cos(q) * sx - np.sin(q) * sy, np.sin(q) * sx + np.cos(q) * sy]
                                   for sx in (-1, 1) for sy in (-1, 1)])
    sphere = 0.5 * np.sin(q) + 0.05
    assert cm.distance([q])[0] == pytest.approx(min(0.35 - corners[:, 1].max(), 0.35 - sphere), abs=1e-6)
    q = 0.4  # the cube's centre at y = 0.389: it overlaps the wall; depth = its top corner's y - 0.35
    top = np.sin(q) + 0.05 * (np.sin(q) + np.cos(q))
    d, a, _ = cm.distance([q])
    assert a == "carried/part" and d == pytest.approx(0.35 - top, abs=1e-6) and d < 0
    assert CollisionModel(one_link(tmp_path, [Obstacle("far", "box", (0.0, 5.0, 0.0), size_m=(1.0, 1.0, 1.0))])) \
        .distance([0.0]) == (HORIZON_M, "", "")  # nothing within HORIZON_M: reported as HORIZON_M, no pair


def test_carried_part_is_the_box_of_its_inertia():
    body = SimpleNamespace(mass_kg=2.0, com_m=np.array([0, 0, 0.08]), inertia_kgm2=np.diag([0.006, 0.006, 0.004]))
    (name, box, X), = carried_shapes(SimpleNamespace(hand_kind="suction", body=body))
    s = np.array([box.width(), box.depth(), box.height()])
    assert np.allclose(2.0 / 12 * (s[1] ** 2 + s[2] ** 2), 0.006) and np.allclose(2.0 / 12 * (s[0] ** 2 + s[1] ** 2), 0.004)


@pytest.fixture(scope="module")
def ur5():
    return load_or_skip(str(SCENARIOS / "ur5-suction-bins.yaml"))


@pytest.fixture(scope="module")
def deep():
    """The same task with totes 4 cm deeper than the lift clears (docs/examples/ur5-deep-totes.yaml)."""
    return load_or_skip(str(DEEP_TOTES))


def _through(sc, points, duration_s):
    """A C2 spline through the scenario's path points `points` (indices), at rest at both ends."""
    q = sc.q_path_rad[points]
    t = np.linspace(0.0, duration_s, len(points))
    pp = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(t, q.T, np.zeros(sc.n_dof), np.zeros(sc.n_dof))
    return PolyTrajectory(pp)


def test_toppra_clears_the_shipped_totes_and_collides_with_deeper_ones(ur5, deep):
    """Today's TOPP-RA plan (the planners do not see obstacles: the same plan in both cells) carries the part
    at the lift height, its bottom 1.25 cm above the shipped totes' walls (clearance positive, at most that;
    the plan feasible) and 2.75 cm below the deeper totes' (negative, the plan infeasible with the pair
    named); the pick pose clears the tote's floor by the closed form (the part's box, side^2 = 6 / m
    (I_xx + I_yy - I_zz), hangs below the cup)."""
    ok = shipped_toppra("ur5-suction-bins", 400)  # the plan of this same shipped file, shared with other tests
    plan = make_spatial_plan(deep, "toppra", ok.trajectory, ok.pose_times_s, planning_s=0.0,
                             raw_duration_s=ok.raw_duration_s, hold_scale=ok.hold_scale, info={})
    assert ok.check.feasible and plan.check.feasible  # only the clearance differs
    assert 0.0 < ok.clearance["clearance_m"] <= 0.0125 + 1e-6 and ok.feasible
    c = plan.clearance
    assert plan.check.feasible and c["clearance_m"] < -0.02 and not plan.feasible
    assert plan.summary()["feasible"] is False
    assert c["clearance_pair"][0] == "carried/part" and c["clearance_pair"][1].startswith("obstacle/bin_")
    side_z = np.sqrt(6 / 2.0 * (0.006 + 0.006 - 0.004))
    part_bottom = ur5.poses_m[0, 2] - 0.08 - side_z / 2
    floor_top = -0.0775 + 0.01
    got = clearance_of_states(ur5, [0.0], ur5.q_poses_rad[:1])
    assert got["clearance_m"] == pytest.approx(part_bottom - floor_top, abs=1e-6)
    assert got["clearance_pair"] == ["carried/part", "obstacle/bin_a/floor"]


def test_a_lift_that_clears_is_reported_positive(ur5):
    traj = _through(ur5, [0, 1], 1.0)  # straight up out of tote A
    c = clearance(ur5, traj, ur5.recheck_rate_hz)
    assert 0.0 < c["clearance_m"] < 0.0101 and c["clearance_samples"] > 2000


def test_cosim_reports_collided_with_the_first_touch(deep):
    """Driven from above tote A straight into its far wall (path points 1 -> 3, the part's bottom 2.7 cm
    below the walls' tops), slowly enough for the cup: the co-simulation ends `collided`."""
    r = simulate_spatial(deep, _through(deep, [1, 3], 1.2))
    assert r["outcome"] == "collided" and "collided" in OUTCOMES and not r["held"]
    assert r["collision_pair"] == ["carried/part", "obstacle/bin_a/wall_y+"]
    assert 0.0 < r["collided_at_s"] < 1.2 and r["clearance_m"] < -0.02


def test_collision_outranks_a_later_loss():
    assert with_collision("detached", 0.5, 0.8) == "collided"
    assert with_collision("detached", 0.9, 0.8) == "detached"
    assert with_collision("carried", None) == "carried"
