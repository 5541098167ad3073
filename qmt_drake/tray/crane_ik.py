"""Seed 002's analytic inverse kinematics of the CRANE-X7 used as a planar 3-DOF arm.

The seed (section 2, eq. 1-12) solves a planar 3R arm in its own frame: X0 horizontal, Y0 up,
angles counter-clockwise, q1 from X0; the wrist point W = p - L3 (cos phi, sin phi);
C_alpha = (L1^2 + L2^2 - |W|^2) / (2 L1 L2), q2 = +-(pi - alpha),
q1 = atan2(W_y, W_x) - atan2(L2 sin q2, L1 + L2 cos q2), q3 = phi - q1 - q2.
(The printed eq. 12 has p_x in both atan2 arguments; W_y is meant.)

The robot (section 3, Fig. 4) measures its angles from the vertical and the other way round:
theta1 = pi/2 - q1 (the seed's formula), theta2 = -q2, theta3 = -q3, so that the level tray
(phi = 90 deg in the seed's frame) is theta1 + theta2 + theta3 = 0. The seed's branch choice
"q2 = -(pi - alpha)" is written in the robot's sign: it is the branch with theta2 in
[-161, 2] deg (eq. 13), i.e. q2 = +(pi - alpha) in the counter-clockwise frame. The seed also
lifts the target by the base: the IK runs on (x, y - L0).

Robot angles theta are the joint positions of models/crane_x7_planar.urdf (shoulder_pitch, elbow,
wrist_pitch), whose x is the seed's X0 and z its Y0 (z = 0 on the base plate).

Why the seed's printed joints differ from this IK (see `seed_joint_residual` and the study): the
seed's start/goal joints put the wrist-pitch axis 0.2749 / 0.2731 m above the shoulder, whereas
Table 1 (L0 + L3 = 0.148 m below y = 0.4) puts it at 0.252 m (our IK differs from the printed
joints by up to 0.20 rad). A tool offset h = L0 + L3 of 0.1232 m reproduces them to 12 mrad
(`fit_tool_offset`), close to the maker's frame 0.019 m beyond the wrist-pitch axis (joint 7,
the gripper base: 0.105 + 0.019 = 0.124 m), the usual MoveIt end link of the CRANE-X7: the run
apparently placed that frame, not the tray, at y = 0.4 m. The seed's start joints also sum to -0.0168 rad (not 0): they
are measured, not computed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from qmt_drake.config.scenario import MODELS_DIR
from qmt_drake.errors import QmtInputError

URDF_PATH = MODELS_DIR / "crane_x7_planar.urdf"  # the planar CRANE-X7 the tray co-simulation models


@dataclass(frozen=True)
class CraneGeometry:
    """Seed 002 Table 1 [m] and joint ranges eq. 13 [rad] (robot angles)."""

    L0: float = 0.105
    L1: float = 0.250
    L2: float = 0.250
    L3: float = 0.043
    theta_min: tuple = (math.radians(-90), math.radians(-161), math.radians(-90))
    theta_max: tuple = (math.radians(90), math.radians(2), math.radians(90))


TABLE1 = CraneGeometry()
SEED_START_XY_M = (0.04, 0.4)
SEED_GOAL_XY_M = (0.4, 0.4)
SEED_START_THETA_RAD = (1.1183, -1.9650, 0.8299)  # seed 002 section 7
SEED_GOAL_THETA_RAD = (1.2057, -0.4617, -0.7440)


def seed_frame_ik(px: float, py: float, phi: float, geom: CraneGeometry = TABLE1) -> np.ndarray:
    """Eq. 11-12 in the seed's counter-clockwise frame, relative to the shoulder: (q1, q2, q3) [rad]
    on the branch q2 = +(pi - alpha). Raises QmtInputError when the wrist point is out of reach."""
    wx, wy = px - geom.L3 * math.cos(phi), py - geom.L3 * math.sin(phi)
    c_alpha = (geom.L1**2 + geom.L2**2 - (wx * wx + wy * wy)) / (2 * geom.L1 * geom.L2)
    if not -1.0 <= c_alpha <= 1.0:
        raise QmtInputError(f"tray point ({px:.4g}, {py:.4g}) m above the shoulder is out of the arm's reach "
                            f"(|W| = {math.hypot(wx, wy):.4g} m, L1 + L2 = {geom.L1 + geom.L2:.4g} m); move it closer")
    alpha = math.atan2(math.sqrt(1.0 - c_alpha**2), c_alpha)
    q2 = math.pi - alpha
    q1 = math.atan2(wy, wx) - math.atan2(geom.L2 * math.sin(q2), geom.L1 + geom.L2 * math.cos(q2))
    return np.array([q1, q2, phi - q1 - q2])


def robot_from_seed(q) -> np.ndarray:
    """theta = (pi/2 - q1, -q2, -q3): the robot's angles (from the vertical, clockwise in Fig. 2)."""
    q = np.asarray(q, float)
    return np.array([math.pi / 2 - q[0], -q[1], -q[2]])


def tray_ik(x: float, y: float, geom: CraneGeometry = TABLE1, *, tool_offset_m: float | None = None,
            check_limits: bool = True) -> np.ndarray:
    """Robot joint angles theta [rad] that put the level tray's centre at (x, y) [m] (seed frame:
    y above the base plate). tool_offset_m replaces L0 + L3 (the vertical distance from the tray
    to the wrist axis's height above the shoulder) when given. Raises QmtInputError (one line) when
    the point is unreachable or the joints leave eq. 13's ranges."""
    if not (np.isfinite(x) and np.isfinite(y)):
        raise QmtInputError(f"tray point ({x}, {y}) must be finite numbers in metres")
    y_shoulder = y - geom.L0 if tool_offset_m is None else y - tool_offset_m + geom.L3
    try:
        q = seed_frame_ik(x, y_shoulder, math.pi / 2, geom)
    except QmtInputError:
        raise QmtInputError(f"tray point ({x:.4g}, {y:.4g}) m is out of the arm's reach (wrist axis "
                            f"{math.hypot(x, y_shoulder - geom.L3):.3g} m from the shoulder, L1 + L2 = "
                            f"{geom.L1 + geom.L2:.3g} m); move it closer") from None
    theta = robot_from_seed(q)
    theta = (theta + math.pi) % (2 * math.pi) - math.pi
    if check_limits:
        lo, hi = np.array(geom.theta_min), np.array(geom.theta_max)
        bad = np.flatnonzero((theta < lo - 1e-9) | (theta > hi + 1e-9))
        if bad.size:
            k = int(bad[0])
            raise QmtInputError(
                f"tray point ({x:.4g}, {y:.4g}) m needs joint {k + 1} at {math.degrees(theta[k]):.1f} deg, outside "
                f"eq. 13's [{math.degrees(lo[k]):.0f}, {math.degrees(hi[k]):.0f}] deg; pick a point inside the "
                "workspace")
    return theta


def tray_fk(theta, geom: CraneGeometry = TABLE1) -> np.ndarray:
    """(x, y, phi) of the tray centre [m, m, rad] in the seed frame; phi is the robot's tool angle
    theta1 + theta2 + theta3 (0 = level)."""
    t = np.asarray(theta, float)
    a1, a12, a123 = t[0], t[0] + t[1], t[0] + t[1] + t[2]
    x = geom.L1 * math.sin(a1) + geom.L2 * math.sin(a12) + geom.L3 * math.sin(a123)
    y = geom.L0 + geom.L1 * math.cos(a1) + geom.L2 * math.cos(a12) + geom.L3 * math.cos(a123)
    return np.array([x, y, a123])


def seed_joint_residual(tool_offset_m: float | None = None, geom: CraneGeometry = TABLE1) -> np.ndarray:
    """(2, 3) our IK minus the seed's printed start/goal joints [rad]."""
    ours = [tray_ik(*xy, geom, tool_offset_m=tool_offset_m, check_limits=False)
            for xy in (SEED_START_XY_M, SEED_GOAL_XY_M)]
    return np.array(ours) - np.array([SEED_START_THETA_RAD, SEED_GOAL_THETA_RAD])


def fit_tool_offset(geom: CraneGeometry = TABLE1) -> tuple[float, float]:
    """The tool offset h [m] (tray target height minus the wrist axis's height above the shoulder,
    L0 + L3 in Table 1) that best reproduces the seed's printed joints, and the max residual [rad]."""
    res = minimize_scalar(lambda h: float(np.sum(seed_joint_residual(h, geom) ** 2)), bounds=(0.05, 0.2),
                          method="bounded", options={"xatol": 1e-7})
    return float(res.x), float(np.max(np.abs(seed_joint_residual(res.x, geom))))
