"""IK that does not lie (issue 28 item 3): the polish after Drake's InverseKinematics is damped, stays
inside the joint limits and never makes the solver's pose worse; a refusal names the pose, the residual
and the reason; `task.free_spin_about_normal` lets a 5-joint arm reach face-down poses.

The arm: a 5-joint URDF written here (pan, three pitch, roll: the roll axis is the cup's axis, so
with the cup facing down it is parallel to the pan axis, a singular orientation). Every pose error is
measured by Drake's forward kinematics (SpatialIK.errors), not by the chain the polish uses.
"""

import numpy as np
import pytest
from pydrake.math import RollPitchYaw

from qmt_drake.errors import QmtInputError
from qmt_drake.model.spatial_ik import ANGLE_TOL_RAD, POSITION_TOL_M, SpatialIK
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.spatial_task import load_spatial_scenario

DOWN = np.array([0.0, 0.0, -1.0])


def _link(name, m, L):
    i = m * L * L / 12 + 1e-4
    return (f'<link name="{name}"><inertial><origin xyz="0 0 {L / 2}"/><mass value="{m}"/>'
            f'<inertia ixx="{i}" iyy="{i}" izz="1e-4" ixy="0" ixz="0" iyz="0"/></inertial></link>')


def _joint(name, parent, child, axis, z):
    return (f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="0 0 {z}"/><axis xyz="{axis}"/>'
            '<limit lower="-2.9" upper="2.9" effort="50" velocity="3"/></joint>')


ARM5 = ('<?xml version="1.0"?><robot name="arm5">'
        + _link("base", 2.0, 0.1) + _link("turret", 0.8, 0.1) + _link("upper", 1.0, 0.3)
        + _link("fore", 0.8, 0.25) + _link("wrist", 0.3, 0.06) + _link("hand", 0.2, 0.04)
        + _joint("pan", "base", "turret", "0 0 1", 0.1) + _joint("lift", "turret", "upper", "0 1 0", 0.1)
        + _joint("elbow", "upper", "fore", "0 1 0", 0.3) + _joint("flex", "fore", "wrist", "0 1 0", 0.25)
        + _joint("roll", "wrist", "hand", "0 0 1", 0.06) + "</robot>")


@pytest.fixture(scope="module")
def ik():
    plant, hand, _ = load_arm_plant(ARM5, "hand")
    return SpatialIK(plant, hand, name="arm5")


def _face_down_targets(ik, count, seed_noise, rng):
    """(q_true, p, seed): reachable face-down targets (pitch sum pi) from configurations in the limits."""
    out = []
    for _ in range(count):
        lift, elbow = rng.uniform(0.3, 1.2), rng.uniform(0.8, 2.0)
        q = np.array([rng.uniform(-2, 2), lift, elbow, np.pi - lift - elbow, rng.uniform(-2, 2)])
        out.append((q, ik.pose(q)[0], q + seed_noise * rng.standard_normal(5)))
    return out


def _cost(ik, q, p, n=None, R=None):
    return float(np.sum(ik._linearised(q, p, n, R)[1] ** 2))


def test_face_down_poses_of_a_5_joint_arm_are_reached_inside_the_limits(ik):
    for _, p, seed in _face_down_targets(ik, 12, 0.3, np.random.default_rng(0)):
        q = ik.solve(p, normal=DOWN, seed=seed)
        ep, ea = ik.errors(q, p, normal=DOWN)  # Drake's forward kinematics
        assert ep <= POSITION_TOL_M and ea <= ANGLE_TOL_RAD
        assert np.all(q >= ik.lower) and np.all(q <= ik.upper)


def test_polish_stays_in_the_limits_and_never_worsens_the_solvers_pose(ik):
    """From far seeds Drake's solver stops at a local minimum with joints on their limits; plain
    Gauss-Newton (the old polish) then walks out of the limits, the damped polish does not, and its
    pose error is never larger than the solver's."""
    rng = np.random.default_rng(0)
    old_left = 0
    for _, p, seed in _face_down_targets(ik, 30, 1.0, rng):
        q0 = ik._drake_ik(p, DOWN, None, seed)
        q = ik._polish(q0, p, DOWN, None)
        assert np.all(q >= ik.lower) and np.all(q <= ik.upper)
        assert _cost(ik, q, p, DOWN) <= _cost(ik, np.clip(q0, ik.lower, ik.upper), p, DOWN)
        gn = np.array(q0)
        for _ in range(8):  # the old polish: undamped minimum-norm steps, no limits
            rows, err = ik._linearised(gn, p, DOWN, None)
            gn = gn + np.linalg.lstsq(rows, err, rcond=1e-10)[0]
        old_left += not (np.all(gn >= ik.lower - 1e-9) and np.all(gn <= ik.upper + 1e-9))
    assert old_left >= 1  # the case exists in this sample: the test can fail


def test_full_rotation_on_5_joints_refused_naming_pose_residual_and_reason():
    """A cup mounted across the roll axis (face along the hand's x): facing down, its spin about the
    normal is fixed by the pan joint, so a rotation with another spin is out of reach of 5 joints."""
    plant, hand, _ = load_arm_plant(ARM5, "hand")
    ik = SpatialIK(plant, hand, face_axis=(1.0, 0.0, 0.0), name="arm5")
    q_true = np.array([0.4, 0.6, 1.2, np.pi / 2 - 1.8, 0.0])
    p, R_true = ik.pose(q_true)
    assert np.allclose(R_true @ ik.face_axis, DOWN)
    R = RollPitchYaw(0.0, np.pi / 2, 0.4 + 0.7).ToRotationMatrix().matrix()  # face down, spin off by 0.7 rad
    with pytest.raises(QmtInputError) as exc:
        ik.solve(p, rotation=R, seed=q_true, what="task pose 2")
    msg = str(exc.value)
    assert msg.startswith("task pose 2 at ") and "residual" in msg and "too few joints: 5 joints" in msg
    assert "free_spin_about_normal" in msg and "\n" not in msg
    q0 = ik._drake_ik(p, None, R, q_true)
    q = ik._polish(q0, p, None, R)
    assert _cost(ik, q, p, R=R) <= _cost(ik, np.clip(q0, ik.lower, ik.upper), p, R=R)
    assert np.all(q >= ik.lower) and np.all(q <= ik.upper)
    q = ik.solve(p, normal=DOWN, seed=q_true)  # the spin left free: reached
    assert max(ik.errors(q, p, normal=DOWN)) <= POSITION_TOL_M


def _scenario(tmp_path, task_orientation: str) -> str:
    """A pick-and-place of the cup mounted across the roll axis (face_axis x), every pose face down."""
    (tmp_path / "arm5.urdf").write_text(ARM5)
    ik_ = SpatialIK(*load_arm_plant(ARM5, "hand")[:2])
    pts = [ik_.pose(np.array([pan, 0.6, 1.2, np.pi / 2 - 1.8, 0.0]))[0] for pan in (-0.3, 0.3)]
    poses = [pts[0], pts[0] + [0, 0, 0.05], pts[1] + [0, 0, 0.05], pts[1]]
    five = "[1, 1, 1, 1, 1]"
    text = f"""kind: spatial_transfer
name: arm5-cup
arm: {{urdf: arm5.urdf, hand_frame: hand, face_axis: [1, 0, 0]}}
actuators:
  velocity_limit_rad_s: [3, 3, 3, 3, 3]
  torque_limit_Nm: [50, 50, 50, 20, 20]
  acceleration_limit_rad_s2: [10, 10, 10, 10, 10]
  jerk_limit_rad_s3: [100, 100, 100, 100, 100]
  gear_ratio: {five}
  rotor_inertia_kgm2: [1.0e-6, 1.0e-6, 1.0e-6, 1.0e-6, 1.0e-6]
payload: {{mass_kg: 0.2, com_m: [0, 0, 0.03], inertia_kgm2: [1.0e-4, 1.0e-4, 1.0e-4]}}
hand: {{kind: suction, cup_radius_m: 0.015, vacuum_force_N: 40.0, friction: 0.5}}
task:
  seed_rad: [-0.3, 0.6, 1.2, -0.23, 0.0]
  poses_m: {[np.round(x, 6).tolist() for x in poses]}
{task_orientation}
limits: {{check_rate_hz: 200}}
"""
    path = tmp_path / "arm5-cup.yaml"
    path.write_text(text)
    return str(path)


def test_free_spin_about_normal_lets_a_5_joint_arm_take_face_down_poses(tmp_path):
    spins = "  hand_rpy_rad: [[0, 1.5707963267948966, 0.3], [0, 1.5707963267948966, 0.3], " \
            "[0, 1.5707963267948966, -0.4], [0, 1.5707963267948966, -0.4]]"  # face down, spins the pan cannot give
    with pytest.raises(QmtInputError, match="too few joints: 5 joints for a 6-DOF target"):
        load_spatial_scenario(_scenario(tmp_path, spins))
    sc = load_spatial_scenario(_scenario(tmp_path, spins + "\n  free_spin_about_normal: true"))
    assert sc.pose_rotations is None
    for k, q in enumerate(sc.q_poses_rad):
        ep, ea = sc.ik.errors(q, sc.poses_m[k], normal=DOWN)
        assert ep <= POSITION_TOL_M and ea <= ANGLE_TOL_RAD
    with pytest.raises(QmtInputError, match="free_spin_about_normal: false needs hand_rpy_rad"):
        load_spatial_scenario(_scenario(tmp_path, "  face_normal: [0, 0, -1]\n  free_spin_about_normal: false"))
