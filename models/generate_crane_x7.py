"""Write models/crane_x7_planar.urdf: the CRANE-X7 used as a planar 3-DOF arm (seed 002).

Run `python models/generate_crane_x7.py` after changing a number here; the URDF is committed.

Sources (numbers only; the URDF is our own):
- rt-net/crane_x7_description, urdf/crane_x7_arm.xacro (commit 491cb63): link masses, centres of
  mass, inertias, joint offsets, joint limits; urdf/crane_x7_wide_two_finger_gripper.xacro: the
  gripper base and fingers; urdf/crane_x7.urdf.xacro: joints_vlimit = 4.81710873 rad/s.
    joint 2 (shoulder pitch) 0.036 + 0.064 m above the base link, joint 4 (elbow) 0.065 + 0.185 m
    above joint 2, joint 6 (wrist pitch) 0.121 + 0.129 m above joint 4, joint 7 0.019 m above
    joint 6; axes of joints 2, 4, 6: (0, -1, 0).
    limits: joint 2 +-pi/2 (M_PI = 3.14159 there), joint 4 [-2.80718, 0.04141], joint 6 +-pi/2;
    effort 10 N m (joint 2), 4 N m (joints 4, 6).
- seed 002 Table 1: L1 = L2 = 0.250 m, L3 = 0.043 m (wrist-pitch axis to the tray), L0 = 0.105 m
  (shoulder axis above the base plate; the maker's 0.100 m plus the mounting plate); eq. 13.
- seed 002 section 6: tray plus attachment 0.208 kg.

Conventions
- The arm moves in the vertical x-z plane of the world (z up, gravity -z); x is the seed's X0,
  z its Y0. Every used joint turns about +y, so a positive angle tilts the next link from +z
  towards +x; the maker's axes are -y, i.e. our x is the maker's -x (the maker's arm reaches its
  -x side for positive angles). Centres of mass and inertias are mirrored accordingly (x -> -x).
- Joint angles are the robot's theta (zero: the arm straight up), so theta1 = pi/2 - q1 of the
  seed's IK frame (crane_ik.py).
- The held joints (1 shoulder pan, 3 upper-arm twist, 5 lower-arm twist, 7 wrist roll, gripper
  fingers) are welded at zero; their links are merged into the moving link they ride on.
- `tray` is welded L3 = 0.043 m beyond the wrist-pitch axis; its frame origin is the centre of the
  tray's upper surface, z normal to it. The tray's collision geometry is added in Python
  (qmt_drake/systems/tray_object.py) so all contact parameters live in one place.
- Rotor inertia and gear ratio sit in <transmission><actuator> (drake:rotor_inertia is the
  motor-side value; Drake adds N^2 J_rotor to the joint). The datasheets give no rotor inertia:
  the values below are an ASSUMPTION for coreless motors of this size (see ROTOR_INERTIA_KGM2).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
M_PI_MAKER = 3.14159  # the maker's xacro writes pi so

L0_M = 0.105
L1_M = 0.250
L2_M = 0.250
L3_M = 0.043
TRAY_AND_ATTACHMENT_KG = 0.208
# Tray geometry is not given in the seed: a plastic serving tray about 0.24 x 0.16 m, 5 mm thick;
# the attachment (Fig. 7) wraps the gripper, so the pair's centre of mass is put 12 mm below the
# tray surface (assumption).
TRAY_SIZE_M = (0.24, 0.16, 0.005)
TRAY_COM_BELOW_SURFACE_M = 0.012

# Gear ratios: ROBOTIS e-Manual, XM540-W270 272.5:1, XM430-W350 353.5:1.
GEAR_RATIO = {"shoulder_pitch": 272.5, "elbow": 353.5, "wrist_pitch": 353.5}
# ASSUMPTION (no datasheet value): motor-side rotor inertia of the coreless motors.
ROTOR_INERTIA_KGM2 = {"shoulder_pitch": 2.5e-7, "elbow": 0.8e-7, "wrist_pitch": 0.8e-7}
EFFORT_NM = {"shoulder_pitch": 10.0, "elbow": 4.0, "wrist_pitch": 4.0}
VELOCITY_RAD_S = 4.81710873
LIMITS_RAD = {"shoulder_pitch": (-M_PI_MAKER / 2, M_PI_MAKER / 2), "elbow": (-2.80718, 0.04141),
              "wrist_pitch": (-M_PI_MAKER / 2, M_PI_MAKER / 2)}


def _rpy(r, p, y) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _part(mass, com, rpy, ixx, ixy, ixz, iyy, iyz, izz, z_offset=0.0):
    """One maker inertial block, expressed in the moving link's frame (frame shift z_offset along
    the link, then mirrored x -> -x). Returns (m, com (3,), I about com (3,3))."""
    inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    r = _rpy(*rpy)
    inertia = r @ inertia @ r.T
    c = np.asarray(com, float) + np.array([0.0, 0.0, z_offset])
    mirror = np.diag([-1.0, 1.0, 1.0])
    return mass, mirror @ c, mirror @ inertia @ mirror


def _combine(parts):
    m = sum(p[0] for p in parts)
    com = sum(p[0] * p[1] for p in parts) / m
    inertia = np.zeros((3, 3))
    for mi, ci, ii in parts:
        d = ci - com
        inertia += ii + mi * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return m, com, inertia


R90 = (M_PI_MAKER / 2, 0.0, 0.0)
# Link groups, each in the frame of the pitch joint that drives it (numbers from the maker's xacro).
UPPER_ARM = [  # link 2 (upper arm fixed part) + link 3 (upper arm revolute part, joint 3 at z 0.065)
    _part(0.136, (3.10e-05, 1.90e-05, 3.42e-02), R90, 1.68e-04, 2.05e-08, -4.00e-07, 9.62e-05, 6.24e-08, 1.34e-04),
    _part(0.321, (-1.37e-02, -8.10e-05, 9.52e-02), (0, 0, 0), 1.82e-03, 7.54e-07, -3.73e-05, 1.88e-03, 4.15e-06,
          1.59e-04, z_offset=0.065),
]
LOWER_ARM = [  # link 4 (lower arm fixed part) + link 5 (lower arm revolute part, joint 5 at z 0.121)
    _part(0.222, (-9.39e-03, 6.40e-05, 8.04e-02), R90, 4.89e-04, -3.90e-06, 8.29e-08, 1.14e-04, 2.82e-06, 5.03e-04),
    _part(0.207, (-8.40e-05, 4.62e-04, 6.37e-02), (0, 0, 0), 2.90e-04, 1.00e-07, -4.77e-07, 2.57e-04, -1.69e-05,
          8.75e-05, z_offset=0.121),
]
WRIST = [  # link 6 (wrist) + gripper base (joint 7 at z 0.019) + both fingers (closed, at z 0.019 + 0.024)
    _part(0.14, (6.10e-03, 8.26e-04, -3.55e-03), R90, 4.01e-05, -2.91e-06, 6.39e-07, 6.13e-05, -4.90e-07, 7.35e-05),
    _part(0.121, (1.08e-04, -1.03e-03, 2.08e-02), (0, 0, 0), 3.20e-05, -9.45e-08, 2.61e-07, 4.14e-05, 3.88e-07,
          4.29e-05, z_offset=0.019),
    _part(0.0158, (-0.012 - 2.65e-03, 3.54e-03, 2.69e-02), R90, 1.01e-05, 0, 0, 1.01e-05, 0, 1.01e-05,
          z_offset=0.019 + 0.024),
    _part(0.0139, (0.012 + 3.01e-03, 2.85e-03, 3.09e-02), R90, 7.48e-06, 0, 0, 7.48e-06, 0, 7.48e-06,
          z_offset=0.019 + 0.024),
]


def _tray_inertial():
    a, b, c = TRAY_SIZE_M[0], TRAY_SIZE_M[1], 0.03  # the attachment makes the pair ~3 cm deep
    m = TRAY_AND_ATTACHMENT_KG
    ixx, iyy, izz = m * (b * b + c * c) / 12, m * (a * a + c * c) / 12, m * (a * a + b * b) / 12
    return m, np.array([0.0, 0.0, -TRAY_COM_BELOW_SURFACE_M]), np.diag([ixx, iyy, izz])


def _inertial_xml(m, com, inertia) -> str:
    i = inertia
    return (f'    <inertial>\n      <origin xyz="{com[0]:.6g} {com[1]:.6g} {com[2]:.6g}"/>\n'
            f'      <mass value="{m:.6g}"/>\n'
            f'      <inertia ixx="{i[0, 0]:.6g}" ixy="{i[0, 1]:.6g}" ixz="{i[0, 2]:.6g}" iyy="{i[1, 1]:.6g}"'
            f' iyz="{i[1, 2]:.6g}" izz="{i[2, 2]:.6g}"/>\n    </inertial>\n')


def _bar_visual(length: float, color: str) -> str:
    return (f'    <visual>\n      <origin xyz="0 0 {length / 2:.6g}"/>\n'
            f'      <geometry><box size="0.05 0.04 {length:.6g}"/></geometry>\n'
            f'      <material name="{color}"/>\n    </visual>\n'
            '    <visual>\n      <origin rpy="1.5707963 0 0"/>\n'
            '      <geometry><cylinder radius="0.028" length="0.06"/></geometry>\n'
            '      <material name="servo_black"/>\n    </visual>\n')


def make_urdf() -> str:
    links = {"upper_arm": _combine(UPPER_ARM), "lower_arm": _combine(LOWER_ARM), "wrist": _combine(WRIST)}
    p = ['<?xml version="1.0"?>\n',
         "<!-- Generated by models/generate_crane_x7.py from the numbers of rt-net/crane_x7_description "
         "(urdf/crane_x7_arm.xacro) and seed 002 Table 1. Do not edit by hand. -->\n",
         '<robot name="crane_x7_planar" xmlns:drake="http://drake.mit.edu">\n',
         '  <material name="arm_white"><color rgba="0.92 0.92 0.92 1"/></material>\n',
         '  <material name="servo_black"><color rgba="0.15 0.15 0.15 1"/></material>\n',
         '  <material name="tray_brown"><color rgba="0.55 0.35 0.2 1"/></material>\n',
         '  <link name="world"/>\n',
         # base: maker's base link (0.388 kg) + shoulder-pan link (0.253 kg), both welded: no dynamics.
         '  <link name="base">\n'
         f'    <visual>\n      <origin xyz="0 0 {L0_M / 2:.6g}"/>\n'
         f'      <geometry><cylinder radius="0.04" length="{L0_M:.6g}"/></geometry>\n'
         '      <material name="servo_black"/>\n    </visual>\n  </link>\n',
         '  <joint name="base_weld" type="fixed">\n    <parent link="world"/>\n    <child link="base"/>\n'
         '  </joint>\n']
    for name, (m, com, inertia) in links.items():
        length = {"upper_arm": L1_M, "lower_arm": L2_M, "wrist": 0.019 + 0.024}[name]
        p.append(f'  <link name="{name}">\n' + _inertial_xml(m, com, inertia) + _bar_visual(length, "arm_white")
                 + "  </link>\n")
    m, com, inertia = _tray_inertial()
    a, b, c = TRAY_SIZE_M
    p.append('  <link name="tray">\n' + _inertial_xml(m, com, inertia)
             + f'    <visual>\n      <origin xyz="0 0 {-c / 2:.6g}"/>\n'
             f'      <geometry><box size="{a:.6g} {b:.6g} {c:.6g}"/></geometry>\n'
             '      <material name="tray_brown"/>\n    </visual>\n  </link>\n')
    joints = [("shoulder_pitch", "base", "upper_arm", L0_M), ("elbow", "upper_arm", "lower_arm", L1_M),
              ("wrist_pitch", "lower_arm", "wrist", L2_M)]
    for name, parent, child, z in joints:
        lo, hi = LIMITS_RAD[name]
        p.append(f'  <joint name="{name}" type="revolute">\n    <parent link="{parent}"/>\n'
                 f'    <child link="{child}"/>\n    <origin xyz="0 0 {z:.6g}"/>\n    <axis xyz="0 1 0"/>\n'
                 f'    <limit lower="{lo:.6g}" upper="{hi:.6g}" effort="{EFFORT_NM[name]:.6g}"'
                 f' velocity="{VELOCITY_RAD_S:.9g}"/>\n  </joint>\n')
    p.append(f'  <joint name="tray_weld" type="fixed">\n    <parent link="wrist"/>\n    <child link="tray"/>\n'
             f'    <origin xyz="0 0 {L3_M:.6g}"/>\n  </joint>\n')
    for name, *_ in joints:
        p.append(f'  <transmission name="{name}_transmission">\n'
                 '    <type>transmission_interface/SimpleTransmission</type>\n'
                 f'    <joint name="{name}">\n      <hardwareInterface>EffortJointInterface</hardwareInterface>\n'
                 f'    </joint>\n    <actuator name="{name}_servo">\n'
                 f'      <drake:rotor_inertia value="{ROTOR_INERTIA_KGM2[name]:.6g}"/>\n'
                 f'      <drake:gear_ratio value="{GEAR_RATIO[name]:.6g}"/>\n'
                 '    </actuator>\n  </transmission>\n')
    p.append("</robot>\n")
    return "".join(p)


def main() -> None:
    path = HERE / "crane_x7_planar.urdf"
    path.write_text(make_urdf())
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
