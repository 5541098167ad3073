"""`retime`: a joint path written by hand (CSV, and a ROS 2 JointTrajectory YAML with the joints in
another order) timed by the spatial TOPP-RA with the hand's rows, re-checked; bad paths refused in one line."""

import numpy as np
import pytest
import yaml

from qmt_drake import load_plan
from qmt_drake.apps.cli import main
from qmt_drake.errors import QmtInputError
from qmt_drake.planners.spatial_methods import plan_toppra_spatial
from qmt_drake.planners.spatial_toppra import joint_path, plan_drake_toppra
from qmt_drake.planners.spatial_trajectory import TimeScaled, check
from qmt_drake.retime import load_plan_file, retime_path
from tests.spatial_fixtures import load_or_skip

NAMES = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
# Written by hand (rad): cup down (lift + elbow + wrist_1 = -pi/2, wrist_2 = -pi/2) from bin A, up, over, down in bin B.
HAND_PATH = np.array([[-0.791, -1.145, 1.993, -2.418, -1.571, 0.0],
                      [-0.791, -1.451, 1.653, -1.773, -1.571, 0.0],
                      [0.0, -1.55, 1.75, -1.77, -1.571, 0.0],
                      [0.780, -1.451, 1.653, -1.773, -1.571, 0.0],
                      [0.780, -1.145, 1.993, -2.418, -1.571, 0.0]])
ORDER = [3, 0, 5, 2, 4, 1]  # the YAML's joint order


def write_csv(path, names, rows) -> str:
    path.write_text("\n".join([",".join(names)] + [",".join(str(v) for v in r) for r in rows]) + "\n")
    return str(path)


def joint_trajectory(names, rows, times=None) -> dict:
    """A trajectory_msgs/JointTrajectory as MoveIt writes it (ROS 2 field names)."""
    times = np.arange(len(rows)) * 0.7 if times is None else times
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "base_link"}, "joint_names": list(names),
            "points": [{"positions": [float(v) for v in r], "velocities": [], "accelerations": [], "effort": [],
                        "time_from_start": {"sec": int(t), "nanosec": int(round((t % 1) * 1e9))}}
                       for r, t in zip(rows, times)]}


@pytest.fixture(scope="module")
def sc():
    return load_or_skip("ur5-suction-bins")


@pytest.fixture(scope="module")
def csv_plan(sc, tmp_path_factory):
    return retime_path(sc, write_csv(tmp_path_factory.mktemp("rt") / "path.csv", NAMES, HAND_PATH))


def test_csv_and_shuffled_joint_trajectory_give_identical_timing(sc, csv_plan, tmp_path):
    p = tmp_path / "path.yaml"
    p.write_text(yaml.safe_dump(joint_trajectory([NAMES[j] for j in ORDER], HAND_PATH[:, ORDER])))
    yml = retime_path(sc, str(p))
    assert yml.duration_s == csv_plan.duration_s and yml.raw_duration_s == csv_plan.raw_duration_s
    t = np.linspace(0.0, csv_plan.duration_s, 301)
    for a, b in zip(yml.sample(t), csv_plan.sample(t)):
        np.testing.assert_array_equal(a, b)
    # the path's waypoints are the CSV's, in the arm's order, start and end on them
    np.testing.assert_array_equal(yml.info["path_q_rad"], HAND_PATH)
    np.testing.assert_allclose(csv_plan.sample([0.0, csv_plan.duration_s])[0], HAND_PATH[[0, -1]], atol=1e-12)


def test_toppra_retime_holds_its_limits_and_no_uniformly_faster_timing_does(sc, csv_plan):
    traj = csv_plan.trajectory
    assert csv_plan.recheck["max"] <= 1.0 and csv_plan.feasible
    rate = sc.recheck_rate_hz
    assert check(sc, TimeScaled(traj, 1.25), rate)["max"] <= 1.0  # slower: also feasible
    assert check(sc, TimeScaled(traj, 0.97), rate)["max"] > 1.0  # 3 % faster breaks a limit: it rides one
    # Drake's own Toppra with the joint speed/acceleration limits only (fewer limits) is not slower
    drake = plan_drake_toppra(joint_path(HAND_PATH), sc.plant, velocity_limit=sc.velocity_limit_rad_s,
                              acceleration_limit=sc.acceleration_limit_rad_s2)
    assert drake["duration_s"] <= csv_plan.raw_duration_s * 1.005
    # the hand's pose at the ends is reported, not refused (the path is the task): rounding to 1 mrad costs < 1 mm
    assert csv_plan.pose_error.shape == (2, 2) and 0 < csv_plan.pose_error[:, 0].max() < 1e-3


def test_the_scenarios_own_ik_path_retimes_to_the_spatial_toppra_bit_for_bit(sc):
    own = plan_toppra_spatial(sc, n_grid=300)
    again = retime_path(sc, sc.q_path_rad, n_grid=300)
    assert again.raw_duration_s == own.raw_duration_s
    assert np.max(again.pose_error) < 1e-6  # its ends are the task's IK solutions


def test_ga_follows_the_path_through_its_waypoints(sc):
    p = retime_path(sc, HAND_PATH, "ga", generations=3, population=10, seed=1)
    assert p.recheck["max"] <= 1.0
    times = np.r_[0.0, np.cumsum(p.info["segment_times_s"])]
    np.testing.assert_allclose(p.sample(times)[0], HAND_PATH, atol=1e-9)


def _refused(sc, source, *words):
    with pytest.raises(QmtInputError) as e:
        retime_path(sc, source)
    msg = str(e.value)
    assert "\n" not in msg and all(w in msg for w in words), msg


def test_bad_paths_are_refused_in_one_line(sc, tmp_path):
    _refused(sc, write_csv(tmp_path / "a.csv", NAMES[:5] + ["gripper_joint"], HAND_PATH), "gripper_joint",
             "not a moving joint")
    _refused(sc, write_csv(tmp_path / "b.csv", NAMES[:5], HAND_PATH[:, :5]), "no column", "wrist_3_joint")
    _refused(sc, write_csv(tmp_path / "c.csv", NAMES, [list(HAND_PATH[0]), list(HAND_PATH[1][:5])]),
             "waypoint 1 has 5 values")
    nan = HAND_PATH.copy()
    nan[2, 1] = np.nan
    _refused(sc, write_csv(tmp_path / "d.csv", NAMES, nan), "waypoint 2", "shoulder_lift_joint", "finite")
    _refused(sc, write_csv(tmp_path / "e.csv", NAMES, HAND_PATH[:1]), "1 waypoint", "at least 2")
    _refused(sc, write_csv(tmp_path / "f.csv", NAMES, HAND_PATH[[0, 1, 1, 2]]), "waypoints 1 and 2", "duplicate")
    _refused(sc, joint_trajectory(NAMES, HAND_PATH, times=[0.0, 1.0, 0.5, 2.0, 3.0]), "time_from_start",
             "point 2")
    wide = HAND_PATH.copy()
    wide[1, 2] = 3.3
    _refused(sc, wide, "elbow_joint", "outside its range")
    _refused(sc, {"points": []}, "JointTrajectory")
    (tmp_path / "g.txt").write_text("x")
    _refused(sc, str(tmp_path / "g.txt"), "unknown file type")


def test_cli_refuses_an_unknown_joint_in_one_line(tmp_path, capsys):
    path = write_csv(tmp_path / "a.csv", ["base_joint"] + NAMES[1:], HAND_PATH)
    assert main(["retime", "ur5-suction-bins", "--path", path]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "base_joint" in err
    assert main(["retime", "thesis-ch2", "--path", path]) == 2  # a planar arm retimes too; not the UR5's joints
    assert "'base_joint' is not a moving joint of the arm; its joints are joint1" in capsys.readouterr().err


def test_a_retimed_plan_file_loads_back_for_export(sc, csv_plan, tmp_path):
    csv_plan.write_json(tmp_path / "r.json")
    back = load_plan_file(tmp_path / "r.json", sc)
    assert back.method == "retime_toppra" and back.duration_s == csv_plan.duration_s
    numbers = {k: v for k, v in csv_plan.recheck.items() if not isinstance(v, str)}
    assert {k: back.recheck[k] for k in numbers} == pytest.approx(numbers, rel=1e-9)  # rebuilt to rounding
    assert {k: v for k, v in back.recheck.items() if isinstance(v, str)} == \
        {k: v for k, v in csv_plan.recheck.items() if isinstance(v, str)}  # the binding column's name
    np.testing.assert_allclose(back.pose_error, csv_plan.pose_error, rtol=1e-9)
    with pytest.raises(QmtInputError, match="retimes a path of scenario ur5-suction-bins"):
        load_plan_file(tmp_path / "r.json", load_or_skip("ur5-magnet-part"))


def test_a_retimed_plan_file_is_simulated_by_the_cli_and_named_to_the_generic_loader(sc, csv_plan, tmp_path, capsys):
    """`retime ... --json r.json` then `simulate SC --plan r.json` (was refused: '2 task-pose times; the scenario
    has 4 task poses'); qmt_drake.load_plan points to retime.load_plan_file in one line."""
    csv_plan.write_json(tmp_path / "r.json")
    assert main(["simulate", "ur5-suction-bins", "--plan", str(tmp_path / "r.json"), "--json", str(tmp_path / "s.json")]) \
        in (0, None)
    assert "retime_toppra x1:" in capsys.readouterr().out
    with pytest.raises(QmtInputError, match=r"retime.load_plan_file\(path, scenario\)"):
        load_plan(tmp_path / "r.json", sc)
