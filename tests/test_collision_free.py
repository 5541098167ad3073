"""The collision-free path (planners/collision_free.py) and the clearance bounded between samples
(limits/clearance.certified_clearance), on a two-link planar arm whose straight joint-space move sweeps its
tip through a post: RRT-Connect must fold the elbow around it. Checked against closed forms (the point-speed
radii of the links, the smallest distance of a sphere on a turning link from a wall) and against an
independent dense sampling of Drake's signed distance along the certified spline."""

import json
from types import SimpleNamespace

import numpy as np
import pytest
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.apps.cli import main
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.clearance import CollisionModel, certified_clearance, collision_model
from qmt_drake.model.obstacles import Obstacle
from qmt_drake.model.spatial_ik import SpatialIK
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.planners.collision_free import collision_free_path
from qmt_drake.planners.spatial_plan_io import load_spatial_plan
from qmt_drake.planners.spatial_trajectory import PolyTrajectory
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.trajectory import PolynomialTrajectory
from tests.test_obstacles import one_link

_INERTIA = '<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
# two revolute joints about z (shoulder at the origin, elbow at x = 0.5 on link a); a sphere of radius 0.04 m at
# the tip of link b (x = 0.5 on b), the hand there too
TWO_LINK_URDF = f"""<robot name="two">
  <link name="base">{_INERTIA}</link>
  <link name="a">{_INERTIA}</link>
  <link name="b">{_INERTIA}<collision><origin xyz="0.5 0 0"/><geometry><sphere radius="0.04"/></geometry></collision></link>
  <link name="hand"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="10" velocity="2"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2.8" upper="2.8" effort="10" velocity="2"/></joint>
  <joint name="hand_fix" type="fixed"><parent link="b"/><child link="hand"/><origin xyz="0.5 0 0"/></joint>
</robot>
"""
SIDE_M = 0.06  # the carried cube's side


def two_link(tmp_path, obstacles):
    """A stand-in spatial scenario: TWO_LINK_URDF carrying a cube at its hand, face axis z (never tilts)."""
    urdf = tmp_path / "two.urdf"
    urdf.write_text(TWO_LINK_URDF)
    plant, H, names = load_arm_plant(urdf, "hand")
    body = SimpleNamespace(mass_kg=1.0, com_m=np.zeros(3), inertia_kgm2=np.eye(3) * SIDE_M ** 2 / 6)
    q0, q1 = np.array([-1.0, 0.0]), np.array([1.0, 0.0])
    return SimpleNamespace(name="two", urdf=urdf, hand_frame="hand", lock_joints={}, torque_limit_Nm=np.full(2, 10.0),
                           velocity_limit_rad_s=np.full(2, 2.0), hand_kind="suction", body=body,
                           obstacles=tuple(obstacles), plant=plant, joint_names=names,
                           ik=SpatialIK(plant, H, face_axis=(0.0, 0.0, 1.0)), path_normals=np.array([[0.0, 0.0, 1.0]]),
                           q_poses_rad=np.array([q0, q1]), q_path_rad=np.array([q0, q1]), pose_rotations=None)


POST = Obstacle("post", "box", (1.0, 0.0, 0.0), size_m=(0.1, 0.1, 0.4))  # on the tip's circle at q = (0, 0)


def test_speed_radii_are_the_closed_form(tmp_path):
    # one link: the sphere's far side 0.55 m, the carried cube's corner 1 + sqrt(3) 0.05 m from the joint
    assert collision_model(one_link(tmp_path, [])).speed_radii_m == pytest.approx([1.0 + np.sqrt(3) * 0.05])
    # two links: j1 reaches the cube's corner at 0.5 + 0.5 + sqrt(3) 0.03; j2 the same less link a's 0.5
    rho = CollisionModel(two_link(tmp_path, [POST])).speed_radii_m
    assert rho == pytest.approx([1.0 + np.sqrt(3) * SIDE_M / 2, 0.5 + np.sqrt(3) * SIDE_M / 2])


def test_certified_clearance_brackets_the_closed_form(tmp_path):
    """One link turning 0 -> 1.2 -> 0 rad in 0.3 s (a fast cubic): the cube's far corner passes a wall; the exact
    smallest distance comes from the sampled closed form. The certified interval holds it, within tol."""
    wall = Obstacle("wall", "box", (0.0, 1.5, 0.0), size_m=(4.0, 1.0, 1.0))  # its face at y = 1.0
    sc = one_link(tmp_path, [wall])
    pp = PiecewisePolynomial.CubicWithContinuousSecondDerivatives([0.0, 0.15, 0.3], [[0.0, 1.2, 0.0]], [0.0], [0.0])
    traj = PolyTrajectory(pp)
    tol = 5e-4
    c = certified_clearance(sc, traj, 37.0, tol_m=tol)  # a coarse 37 Hz, off the turning point: the bound works
    # closed form: the cube (side 0.1, axes along the link) at x = 1 on a link at angle q; its highest corner
    # is at y = sin q + 0.05 (cos q + sin q) (rising up to q = atan 21); the sphere is lower. The wall's face y = 1.
    q = pp.vector_values(np.linspace(0.0, 0.3, 300001)).ravel()
    exact = np.min(1.0 - (np.sin(q) + 0.05 * (np.cos(q) + np.sin(q))))
    assert 0.0 < exact < 0.01
    assert c["certified"] and c["clearance_lower_bound_m"] <= exact + 1e-9 <= c["clearance_m"] + 1e-9
    assert c["clearance_m"] - c["clearance_lower_bound_m"] <= tol


def test_rrt_connect_finds_a_certified_path_round_the_post(tmp_path):
    sc = two_link(tmp_path, [POST])
    cm = collision_model(sc)
    straight = np.linspace(sc.q_poses_rad[0], sc.q_poses_rad[1], 201)
    assert min(cm.distance(q)[0] for q in straight) < 0  # the straight move hits the post
    r = collision_free_path(sc, margin_m=0.01, seed=3, box_pad_rad=2.0)  # the elbow folds by > 0.9 rad
    c = r["certificate"]
    assert c["certified"] and c["clearance_lower_bound_m"] >= 0.005  # margin / 2, certified between samples
    assert np.array_equal(r["Q"][0], sc.q_poses_rad[0]) and np.array_equal(r["Q"][-1], sc.q_poses_rad[1])
    # independent: Drake's signed distance at 4000 points of the spline the planners time
    path = r["path"]
    dense = min(cm.distance(q)[0] for q in path.sample(np.linspace(0.0, path.duration_s, 4000))[0])
    assert dense >= c["clearance_lower_bound_m"] - 1e-12 and dense >= 0.005
    again = collision_free_path(sc, margin_m=0.01, seed=3, box_pad_rad=2.0)
    assert np.array_equal(again["Q"], r["Q"])  # deterministic given the seed
    assert isinstance(path, PolynomialTrajectory) and path.holds_end_value  # sampled in s, clipped into [0, L]


def test_through_every_task_pose(tmp_path):
    """through="poses" (the default): one leg per pair of task poses, each pose a vertex of the path; "ends":
    the inner pose is not visited."""
    sc = two_link(tmp_path, [POST])
    mid = np.array([0.0, 1.4])  # the elbow folded: the tip 0.65 m from the shoulder, well inside the post at 1 m
    sc.q_poses_rad = np.array([sc.q_poses_rad[0], mid, sc.q_poses_rad[1]])
    sc.q_path_rad = sc.q_poses_rad
    r = collision_free_path(sc, margin_m=0.01, seed=0, box_pad_rad=2.0)
    assert any(np.array_equal(v, mid) for v in r["Q"][r["vertex_index"]])
    assert r["certificate"]["clearance_lower_bound_m"] >= 0.005
    with pytest.raises(QmtInputError, match="through 'middle'"):
        collision_free_path(sc, through="middle")


def test_refusals(tmp_path):
    with pytest.raises(QmtInputError, match="no world.obstacles"):
        collision_free_path(two_link(tmp_path, []))
    with pytest.raises(QmtInputError, match="margin"):
        collision_free_path(two_link(tmp_path, [POST]), margin_m=-1.0)
    inside = Obstacle("near", "box", (0.54, -0.84, 0.0), size_m=(0.1, 0.1, 0.4))  # around the start pose's part
    with pytest.raises(QmtInputError, match=r"task pose 0 collides with obstacle/near by 90.0 mm .*move the obstacle"):
        collision_free_path(two_link(tmp_path, [inside]), margin_m=0.05)  # no margin can help: not "a margin below"
    near = Obstacle("near", "box", (0.66, -0.84, 0.0), size_m=(0.1, 0.1, 0.4))  # 28 mm from the start pose's part
    with pytest.raises(QmtInputError, match=r"task pose 0 is itself within the margin or tilted \(28.2 mm"):
        collision_free_path(two_link(tmp_path, [near]), margin_m=0.05)


def test_plan_refuses_avoid_options_without_avoid_and_on_a_planar_arm(capsys):
    assert main(["plan", "ur5-suction-bins", "--method", "toppra", "--avoid-seed", "3"]) == 2
    assert "options of --avoid" in capsys.readouterr().err
    assert main(["plan", "ch2", "--method", "toppra", "--avoid"]) == 2
    assert "--avoid plans a collision-free path among a spatial scenario's world.obstacles" in capsys.readouterr().err


def test_a_plan_made_with_avoid_simulates_against_its_scenario(tmp_path, capsys):
    """`plan SC --avoid --json P` then `simulate SC --plan P`: the file's collision-free facts rebuild the
    path it was planned on (the same seed: the same path), so the plan loads against SC itself."""
    path = tmp_path / "p.json"
    assert main(["plan", "ur5-suction-bins", "--method", "toppra", "--avoid", "--json", str(path), "--quiet"]) in (0, None)
    sc = load_spatial_scenario("ur5-suction-bins")
    plan = load_spatial_plan(path, sc)
    assert plan.duration_s == json.loads(path.read_text())["duration_s"]
    assert plan.extra["collision_free_path"]["seed"] == 0
    broken = path.read_text().replace('"through": "poses"', '"through": "nowhere"')
    (tmp_path / "q.json").write_text(broken)
    with pytest.raises(QmtInputError):
        load_spatial_plan(tmp_path / "q.json", sc)
