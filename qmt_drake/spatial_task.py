"""Spatial transfer scenarios (`kind: spatial_transfer`): a URDF arm, its actuators, a carried part, a
suction hand and a 3-D pick-and-place task, validated into planning objects with one-line errors.

    sc = load_spatial_scenario("ur5-suction-bins")     # or a path to a YAML file

Sections (SI units; models/scenarios/ur5-suction-bins.yaml is the example):
- arm: `package: <robot-description package>/<arm or URDF file>` (model/urdf_package.py: an arm of
  EXAMPLE_ARMS such as example-robot-data/ur5, or any URDF file the installed package ships, then with
  `hand_frame`; refused in one line when the package is not installed) or `urdf: <path>` (relative to
  the file) with `hand_frame`; `face_axis` the hand-frame axis the cup faces along (default z);
  `lock_joints` a list of joints fixed at 0 or a mapping joint -> value (rad or m: {torso_lift_joint:
  0.25}); `lock: off_chain` also fixes every movable joint off the base-to-hand chain (at its
  lock_joints value, else 0). docs/arms.md is the user's guide.
- actuators: velocity_limit_rad_s, acceleration_limit_rad_s2, jerk_limit_rad_s3, torque_limit_Nm
  (joint side), gear_ratio, rotor_inertia_kgm2 (motor side; the reflected inertia N^2 J_r enters the
  joint torques), one value per chain joint; velocity_limit_rad_s and torque_limit_Nm default to the
  URDF's <limit velocity effort>, gear_ratio and rotor_inertia_kgm2 to the URDF's drake:gear_ratio /
  drake:rotor_inertia, else (no `motor`) to an ideal joint-torque source, N = 1 and J_r = 0; optional
  `motor` (spatial_motor.py: k_t, R, voltage limit) for the DC-motor co-simulation, which needs them.
- payload: mass_kg, com_m (hand frame, from the cup's centre), inertia_kgm2 (principal central moments
  in the hand axes).
- hand: kind suction: cup_radius_m, vacuum_force_N, friction, rim_points, pyramid_edges; or kind
  magnet: moment_limit_Nm (the thesis's payload-moment limit, in 3-D the face-plane moment of the
  part's contact wrench, gravity included: limits/contact_wrench.MagnetMomentTerm); `physics` (suction,
  magnet): how the co-simulation holds the part, weld (default: welded, detached the first step its
  wrench leaves the limit) or contact (a free body held by contact and the pull,
  sim/spatial_contact_hand.py, docs/spatial_hands.md); or kind tray:
  friction, cup {radius_m, height_m, mass_kg, com_height_m (default height / 2)}, margin (0, 1],
  pyramid_edges, tray_size_m: an unfixed cup standing on a tray in the face plane
  (limits/tray_contact.py; no payload section: the cup is the carried body; the tray is massless).
- task: seed_rad (optional, the IK branch; without it the IK tries 12 starts and keeps the path with
  the least joint motion, model/spatial_ik.SpatialIK.solve_path), poses_m (K >= 2 hand positions), and the hand's orientation at them,
  one of: face_normal (world; the same at every pose; the spin about it is free), face_normals (one
  per pose: e.g. a part picked from a tilted bin), hand_rpy_rad (a full rotation per pose: roll,
  pitch, yaw of the hand frame in the world, Drake's RollPitchYaw); transfer_points (inner points of
  the geometric path between poses 1 and K-2, on the straight line between them, the orientation
  interpolated along it by slerp); free_spin_about_normal (default false; true lets the hand spin
  freely about its face normal at every pose: a suction cup or a magnet does not care, and a 5-joint
  arm can then reach a face-down pose its hand_rpy_rad would over-constrain; with face_normal(s) the
  spin is always free).
- limits (optional): check_rate_hz (the planners' sampling, default 200 Hz; the re-check samples at 10x).
- world (optional): obstacles, a list of boxes, cylinders, meshes and bins welded to the world
  (model/obstacles.py; the re-check's clearance, limits/clearance.py; docs/obstacles.md).

Every task pose is solved by SpatialIK on the seed's branch and checked by Drake's forward kinematics
to 1e-6 m / 1e-6 rad; an unreachable pose is refused naming it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from qmt_drake import spatial_poses
from qmt_drake.config import fields as F
from qmt_drake.config.resolve import SCENARIO_DIR, SPATIAL, resolve_scenario  # noqa: F401 (SCENARIO_DIR: re-exported)
from qmt_drake.config.simulation import NO_SIMULATION, Simulation
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.contact_wrench import CarriedBody, MagnetMomentTerm
from qmt_drake.limits.motor_torque import MotorTorqueTerm
from qmt_drake.limits.suction import GripModel, SuctionTerm
from qmt_drake.limits.tray_contact import TrayContactTerm, TrayCup
from qmt_drake.model.arm_model import ArmData, build_arm_model
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.model.spatial_ik import SpatialIK
from qmt_drake.model.urdf_check import urdf_joint_limits
from qmt_drake.spatial_data import SpatialScenarioData, parse_spatial_data
from qmt_drake.spatial_motor import SpatialMotors, parse_motor_section

SPATIAL_KIND = SPATIAL
RECHECK_FACTOR = 10


@dataclass
class SpatialScenario:
    name: str
    path: Path
    urdf: Path
    hand_frame: str
    lock_joints: dict  # joint -> locked value (rad or m): arm.lock_joints, lock: off_chain
    joint_names: list
    plant: object  # continuous MultibodyPlant of the arm alone (IK, Drake FK)
    ik: SpatialIK
    chain: SpatialChain  # with the carried part and the reflected rotor inertia
    body: CarriedBody
    grip: GripModel | None  # suction hand
    velocity_limit_rad_s: np.ndarray
    acceleration_limit_rad_s2: np.ndarray
    jerk_limit_rad_s3: np.ndarray
    torque_limit_Nm: np.ndarray
    drive: dict
    face_normal: np.ndarray  # the first pose's face normal (world)
    poses_m: np.ndarray  # (K, 3) task poses
    q_poses_rad: np.ndarray  # (K, n) their IK solutions
    path_points_m: np.ndarray  # (P, 3) the geometric path's points (poses + transfer points)
    q_path_rad: np.ndarray  # (P, n)
    path_pose_index: np.ndarray  # index of each task pose in path_points_m
    check_rate_hz: float
    hand_kind: str = "suction"
    hand_physics: str = "weld"  # hand.physics: weld (threshold on a welded part) or contact (sim/spatial_contact_hand)
    moment_limit_Nm: float | None = None  # magnet hand
    face_axis: np.ndarray | None = None
    cup: TrayCup | None = None  # tray hand: the unfixed cup standing on the tray
    motor: SpatialMotors | None = None  # actuators.motor (DC-motor co-simulation); None: not given
    pose_normals: np.ndarray | None = None  # (K, 3) the face normal at each task pose (world, unit)
    path_normals: np.ndarray | None = None  # (P, 3) the face normal at each path point
    pose_rotations: np.ndarray | None = None  # (K, 3, 3) R_WH at each task pose (task.hand_rpy_rad); None: normals
    path_rotations: np.ndarray | None = None  # (P, 3, 3)
    obstacles: tuple = ()  # world.obstacles (model/obstacles.Obstacle), welded to the world
    uncertainty: dict | None = None  # `uncertainty` (sweep/parameters.check_spatial_uncertainty); {}: none
    simulation: Simulation = NO_SIMULATION  # `simulation` (config/simulation.py): its co-simulation's Drake settings

    @property
    def n_dof(self) -> int:
        return self.chain.n_dof

    @property
    def gravity_m_s2(self) -> np.ndarray:
        return self.plant.gravity_field().gravity_vector()

    def pose_target(self, k: int) -> dict:
        """Task pose k's orientation as SpatialIK's keyword: {'rotation': R_WH} or {'normal': n}."""
        if self.pose_rotations is not None:
            return {"rotation": self.pose_rotations[k]}
        return {"normal": self.pose_normals[k]}

    @property
    def recheck_rate_hz(self) -> float:
        return RECHECK_FACTOR * self.check_rate_hz

    def hand_term(self, grip: GripModel | None = None):
        """The hand's limit term: the suction grip (`grip` overrides the scenario's polyhedron) or the
        magnet's face-plane moment (limits/contact_wrench.MagnetMomentTerm)."""
        if self.hand_kind == "tray":
            return TrayContactTerm(self.cup, self.gravity_m_s2, face_axis=self.face_axis)
        if self.hand_kind == "magnet":
            return MagnetMomentTerm(self.body, self.moment_limit_Nm, self.gravity_m_s2, face_normal=self.face_axis)
        return SuctionTerm(grip or self.grip, self.body, self.gravity_m_s2)

    def terms(self, grip: GripModel | None = None) -> list:
        """The limit terms beyond joint speed/acceleration: joint torques and the hand's term."""
        arm = SimpleNamespace(gear_ratio=self.drive["gear_ratio"], joint_names=self.joint_names,
                              gravity_does_no_work=False)
        return [MotorTorqueTerm(arm, self.torque_limit_Nm / self.drive["gear_ratio"]), self.hand_term(grip)]


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    """The YAML file of a built-in name or a path (config/resolve.py); one line if neither or of another kind."""
    return resolve_scenario(name_or_path, SPATIAL_KIND)


def load_spatial_scenario(name_or_path: str | Path, overrides: dict | None = None) -> SpatialScenario:
    """The validated scenario (module docstring); QmtInputError (one line) for any bad input. The file's
    plain data (spatial_data.parse_spatial_data, `overrides` merged into its YAML first), built by
    build_spatial_scenario."""
    return build_spatial_scenario(parse_spatial_data(name_or_path, overrides))


def build_spatial_scenario(data: SpatialScenarioData) -> SpatialScenario:
    """The one builder of a spatial scenario's planning objects from its plain data: the arm's plant, its
    chain with the carried part, the IK and the task's joint poses; the checks that need the arm (one value
    per joint, the URDF's defaults, the poses reachable, the part held at rest) raise one line here."""
    where, arm, hd, tk = data.path.name, data.arm, data.hand, data.task
    urdf, hand, lock, face_axis = arm.urdf, arm.hand_frame, arm.lock_joints, arm.face_axis
    w = f"{where}: actuators"
    vals = dict(data.actuators.given)
    motor_raw = data.actuators.motor
    built = build_arm_model(ArmData(urdf, hand, lock, vals.get("torque_limit_Nm"), vals.get("velocity_limit_rad_s")),
                            data.payload, gear_ratio=vals.get("gear_ratio"),
                            rotor_inertia_kgm2=vals.get("rotor_inertia_kgm2"), drive_required=motor_raw is not None,
                            where=w)
    plant, H, names, drive, chain = built.plant, built.hand, built.joint_names, built.drive, built.chain
    n = len(names)
    for k, v in vals.items():
        if v.shape != (n,):
            raise QmtInputError(f"{w}.{k} has {v.size} entries; give {n}, one per joint {names}")
    vals = _urdf_limit_defaults(vals, urdf, names)
    motor = parse_motor_section(motor_raw, names, vals["torque_limit_Nm"], drive["gear_ratio"], f"{w}.motor")
    grip = None
    if hd.kind == "suction":
        grip = GripModel(hd.cup_radius_m, hd.vacuum_force_N, hd.friction, face_normal=face_axis,
                         rim_points=hd.rim_points, pyramid_edges=hd.pyramid_edges)
    body, cup = data.payload, hd.cup

    w = f"{where}: task"
    seed = (None if tk.seed_rad is None else
            F.radians({"seed_rad": list(tk.seed_rad)}, "seed_rad", w, length=n, what="one joint angle per joint"))
    ik = SpatialIK(plant, H, face_axis=face_axis, name=data.name)
    pts, idx, normals, rotations = spatial_poses.path_points(tk.poses_m, tk.transfer_points, tk.pose_normals,
                                                             tk.pose_rotations, face_axis)
    q_path = ik.solve_path(pts, normals=None if rotations is not None else normals, rotations=rotations, seed=seed,
                           max_joint_step_rad=1.0, what=f"{where}: task path point")
    if cup is not None:
        _check_cup_rests(TrayContactTerm(cup, plant.gravity_field().gravity_vector(), face_axis=face_axis), chain,
                         q_path, f"{where}: task")
    sc = SpatialScenario(name=data.name, path=data.path, urdf=Path(urdf), hand_frame=hand,
                         lock_joints=dict(lock), joint_names=list(names), plant=plant, ik=ik, chain=chain, body=body,
                         grip=grip, velocity_limit_rad_s=vals["velocity_limit_rad_s"],
                         acceleration_limit_rad_s2=vals["acceleration_limit_rad_s2"],
                         jerk_limit_rad_s3=vals["jerk_limit_rad_s3"], torque_limit_Nm=vals["torque_limit_Nm"],
                         drive=drive, face_normal=normals[0], poses_m=tk.poses_m, q_poses_rad=q_path[idx],
                         path_points_m=pts, q_path_rad=q_path, path_pose_index=idx, check_rate_hz=data.check_rate_hz,
                         hand_kind=hd.kind, hand_physics=hd.physics, moment_limit_Nm=hd.moment_limit_Nm,
                         face_axis=face_axis, cup=cup, motor=motor, pose_normals=tk.pose_normals, path_normals=normals,
                         pose_rotations=tk.pose_rotations, path_rotations=rotations, obstacles=data.obstacles,
                         uncertainty=data.uncertainty, simulation=data.simulation)
    if cup is None:
        _check_holds_at_rest(sc, f"{where}: payload")
    return sc


def _urdf_limit_defaults(vals: dict, urdf, names) -> dict:
    """The actuator section's velocity and torque limits, each defaulting to the URDF's own <limit>
    (load_arm_plant has refused a joint without either when the section does not give them)."""
    own = urdf_joint_limits(urdf, names)
    for key, urdf_key in (("velocity_limit_rad_s", "velocity_limit_rad_s"), ("torque_limit_Nm", "effort_limit_Nm")):
        if key not in vals:
            vals[key] = own[urdf_key]
    return vals


def _check_cup_rests(term: TrayContactTerm, chain: SpatialChain, q_path: np.ndarray, w: str) -> None:
    """Refuse a path on which the cup cannot even stand still on the tray (tray not facing up enough)."""
    zero = np.zeros_like(q_path)
    r = term.columns(chain.evaluate(q_path, zero, zero))
    k, j = np.unravel_index(np.argmax(r), r.shape)
    if r[k, j] > 1.0:
        raise QmtInputError(f"{w}: the cup cannot stand still on the tray at path point {k} (its "
                            f"{TrayContactTerm.column_names[j]} ratio at rest is {r[k, j]:.3g} > 1); point face_normal "
                            "up (e.g. [0, 0, 1]) or raise the friction")


def _check_holds_at_rest(sc: SpatialScenario, w: str) -> None:
    """Refuse a payload the suction cup or the magnet cannot hold even at rest on the path (mass_kg 1e9, a
    centre of mass far out): the planners would only find no motion, without saying why. (Joint torques at
    rest are named when TOPP-RA finds no motion: limits/at_rest.py.)"""
    term = sc.hand_term()
    zero = np.zeros_like(sc.q_path_rad)
    r = term.columns(sc.chain.evaluate(sc.q_path_rad, zero, zero))
    k, j = np.unravel_index(np.argmax(r), r.shape)
    if r[k, j] > 1.0:
        raise QmtInputError(f"{w}: the {sc.hand_kind} hand cannot hold the payload even at rest at path point {k} "
                            f"(its {term.column_names[j]} ratio at rest is {r[k, j]:.3g} > 1); lower mass_kg or move "
                            "com_m nearer the hand, or give a stronger hand")


