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
- task: seed_rad (the IK branch), poses_m (K >= 2 hand positions), and the hand's orientation at them,
  one of: face_normal (world; the same at every pose; the spin about it is free), face_normals (one
  per pose: e.g. a part picked from a tilted bin), hand_rpy_rad (a full rotation per pose: roll,
  pitch, yaw of the hand frame in the world, Drake's RollPitchYaw); transfer_points (inner points of
  the geometric path between poses 1 and K-2, on the straight line between them, the orientation
  interpolated along it by slerp); free_spin_about_normal (default false; true lets the hand spin
  freely about its face normal at every pose: a suction cup or a magnet does not care, and a 5-joint
  arm can then reach a face-down pose its hand_rpy_rad would over-constrain; with face_normal(s) the
  spin is always free).
- limits: check_rate_hz (the planners' sampling; the re-check samples at 10x).
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
from qmt_drake.budgets import SPATIAL_MAX_GRIP_COUNT, check_spatial_sizes
from qmt_drake.config import fields as F
from qmt_drake.config.resolve import SCENARIO_DIR, SPATIAL, resolve_scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.contact_wrench import CarriedBody, MagnetMomentTerm
from qmt_drake.limits.motor_torque import MotorTorqueTerm
from qmt_drake.limits.suction import GripModel, SuctionTerm
from qmt_drake.limits.tray_contact import TrayContactTerm, TrayCup
from qmt_drake.model.obstacles import parse_obstacles
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.model.spatial_ik import SpatialIK
from qmt_drake.model.urdf_check import drive_parameters, load_arm_plant, off_chain_locks, urdf_joint_limits
from qmt_drake.model.urdf_package import EXAMPLE_ARMS, package_urdf
from qmt_drake.spatial_motor import SpatialMotors, parse_motor_section
from qmt_drake.sweep.parameters import check_spatial_uncertainty

SPATIAL_KIND = SPATIAL
RECHECK_FACTOR = 10
HAND_PHYSICS = ("weld", "contact")  # hand.physics: how the co-simulation holds a suction or magnet part
OPTIONAL_ACTUATOR_KEYS = ("velocity_limit_rad_s", "torque_limit_Nm", "gear_ratio", "rotor_inertia_kgm2")
TOP_KEYS = {"kind", "name", "description", "arm", "actuators", "payload", "hand", "task", "limits", "world",
            "uncertainty"}


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


def _arm(raw: dict, where: str, base: Path):
    F.check_keys(raw, {"package", "urdf", "hand_frame", "face_axis", "lock_joints", "lock"}, where)
    if ("package" in raw) == ("urdf" in raw):
        raise QmtInputError(f"{where}: give exactly one of 'package' (<robot-description package>/<arm or URDF "
                            "file>, e.g. example-robot-data/ur5) or 'urdf' (the path of a URDF file of your own)")
    if "package" in raw:
        urdf, hand, lock = package_urdf(F.string(raw, "package", where), f"{where}.package")
        if hand is None and "hand_frame" not in raw:
            raise QmtInputError(f"{where}: {raw['package']!r} is not one of the known arms {sorted(EXAMPLE_ARMS)}; "
                                "give hand_frame, the link the hand is fixed to")
        hand = F.string(raw, "hand_frame", where, default=hand)
    else:
        urdf = F.xml_file((base / F.string(raw, "urdf", where)).resolve(), "robot", f"{where}.urdf", "URDF")
        hand, lock = F.string(raw, "hand_frame", where), ()
    lock = _lock_joints(raw.get("lock_joints", lock), f"{where}.lock_joints")
    if "lock" in raw:
        F.string(raw, "lock", where, choices=("off_chain",))
        lock = off_chain_locks(urdf, hand, lock, source=str(urdf))
    face = F.direction(raw, "face_axis", where) if "face_axis" in raw else np.array([0.0, 0.0, 1.0])
    return urdf, hand, lock, face


def _lock_joints(raw, where: str) -> dict:
    """arm.lock_joints: a list of joint names (each locked at 0) or a mapping joint -> value (rad or m)."""
    if isinstance(raw, dict):
        return {str(k): F.num(raw, k, where) for k in raw}
    if isinstance(raw, (list, tuple)) and all(isinstance(k, str) for k in raw):
        return {k: 0.0 for k in raw}
    raise QmtInputError(f"{where} must be a list of joint names (locked at 0) or a mapping joint: value "
                        f"(rad or m, e.g. {{torso_lift_joint: 0.25}}); got {F.show(raw)}")


def load_spatial_scenario(name_or_path: str | Path) -> SpatialScenario:
    """The validated scenario (module docstring); QmtInputError (one line) for any bad input."""
    path = resolve_scenario_path(name_or_path)
    raw = F.read_yaml_mapping(path, "spatial scenario", SCENARIO_DIR / "ur5-suction-bins.yaml")
    where = path.name
    F.check_keys(raw, TOP_KEYS, where)
    if raw.get("kind") != SPATIAL_KIND:
        raise QmtInputError(f"{where}: kind must be '{SPATIAL_KIND}' for a spatial scenario, got {raw.get('kind')!r}")
    world = F.mapping(raw, "world", where, default={})
    F.check_keys(world, {"obstacles"}, f"{where}: world")
    obstacles = parse_obstacles(world.get("obstacles"), f"{where}: world.obstacles", path.parent)
    urdf, hand, lock, face_axis = _arm(F.mapping(raw, "arm", where), f"{where}: arm", path.parent)

    w = f"{where}: actuators"
    act = F.mapping(raw, "actuators", where)
    keys = ("velocity_limit_rad_s", "acceleration_limit_rad_s2", "jerk_limit_rad_s3", "torque_limit_Nm",
            "gear_ratio", "rotor_inertia_kgm2")
    F.check_keys(act, set(keys) | {"motor"}, w)
    # the URDF's velocity and effort limits, the gear ratio and rotor inertia are defaults (module docstring)
    vals = {k: F.vector(act, k, w, positive=True) for k in keys if k in act or k not in OPTIONAL_ACTUATOR_KEYS}
    plant, H, names = load_arm_plant(urdf, hand, lock_joints=lock, effort_limit_Nm=vals.get("torque_limit_Nm"),
                                     velocity_limit_rad_s=vals.get("velocity_limit_rad_s"))
    n = len(names)
    for k, v in vals.items():
        if v.shape != (n,):
            raise QmtInputError(f"{w}.{k} has {v.size} entries; give {n}, one per joint {names}")
    vals = _urdf_limit_defaults(vals, urdf, names)
    drive = drive_parameters(urdf, names, gear_ratio=vals.get("gear_ratio"),
                             rotor_inertia_kgm2=vals.get("rotor_inertia_kgm2"), source=str(urdf),
                             required=act.get("motor") is not None)
    motor = parse_motor_section(act.get("motor"), names, vals["torque_limit_Nm"], drive["gear_ratio"], f"{w}.motor")

    w = f"{where}: hand"
    hd = F.mapping(raw, "hand", where)
    kind = F.string(hd, "kind", w, choices=("suction", "magnet", "tray"))
    grip, moment_limit, cup = None, None, None
    if kind == "tray":
        cup = _tray_cup(hd, w)
    elif kind == "suction":
        F.check_keys(hd, {"kind", "cup_radius_m", "vacuum_force_N", "friction", "rim_points", "pyramid_edges",
                          "physics"}, w)
        rim, edges = (F.integer(hd, k, w, minimum=3, maximum=SPATIAL_MAX_GRIP_COUNT, default=d)
                      for k, d in (("rim_points", 8), ("pyramid_edges", 4)))
        check_spatial_sizes(w, rim_points=rim, pyramid_edges=edges)
        grip = GripModel(F.num(hd, "cup_radius_m", w, positive=True), F.num(hd, "vacuum_force_N", w, positive=True),
                         F.num(hd, "friction", w, positive=True), face_normal=face_axis,
                         rim_points=rim, pyramid_edges=edges)
    else:
        F.check_keys(hd, {"kind", "moment_limit_Nm", "physics"}, w)
        moment_limit = F.num(hd, "moment_limit_Nm", w, positive=True)
    physics = F.string(hd, "physics", w, choices=HAND_PHYSICS, default="weld")
    body = _payload(raw, where) if cup is None else _no_payload(raw, where, cup.body(face_axis))

    w = f"{where}: task"
    tk = F.mapping(raw, "task", where)
    F.check_keys(tk, {"seed_rad", "face_normal", "face_normals", "hand_rpy_rad", "poses_m", "transfer_points",
                      "free_spin_about_normal"}, w)
    seed = F.radians(tk, "seed_rad", w, length=n, what="one joint angle per joint")
    poses = tk.get("poses_m")
    if not isinstance(poses, list) or len(poses) < 2:
        raise QmtInputError(f"{w}.poses_m must be a list of >= 2 positions [x, y, z] (m)")
    check_spatial_sizes(w, task_poses=len(poses))
    P = np.array([F.vector({"p": p}, "p", f"{w}.poses_m[{k}]", length=3) for k, p in enumerate(poses)])
    pose_rotations = spatial_poses.pose_rotations(tk, len(P), w)
    pose_normals = (spatial_poses.pose_normals(tk, len(P), w) if pose_rotations is None
                    else np.einsum("kij,j->ki", pose_rotations, face_axis))
    if F.boolean(tk, "free_spin_about_normal", w, default=False):
        pose_rotations = None  # only the face normal of each hand_rpy_rad is kept
    elif "hand_rpy_rad" not in tk and "free_spin_about_normal" in tk:
        raise QmtInputError(f"{w}.free_spin_about_normal: false needs hand_rpy_rad (a face normal leaves the "
                            "spin free); give hand_rpy_rad to fix the spin, or drop the key")
    spatial_poses.refuse_repeated_poses(P, pose_normals, pose_rotations, w)
    n_tr = F.integer(tk, "transfer_points", w, minimum=0, default=0)
    lim = F.mapping(raw, "limits", where)
    F.check_keys(lim, {"check_rate_hz"}, f"{where}: limits")
    rate = F.num(lim, "check_rate_hz", f"{where}: limits", positive=True)
    check_spatial_sizes(where, transfer_points=n_tr, check_rate_hz=rate)
    uncertainty = check_spatial_uncertainty(raw.get("uncertainty"), kind, f"{where}: uncertainty")

    ik = SpatialIK(plant, H, face_axis=face_axis, name=str(raw.get("name", path.stem)))
    chain = SpatialChain(plant, H, reflected_inertia_kgm2=drive["reflected_inertia_kgm2"], carried=body.as_dict())
    pts, idx, normals, rotations = spatial_poses.path_points(P, n_tr, pose_normals, pose_rotations, face_axis)
    q_path = ik.solve_path(pts, normals=None if rotations is not None else normals, rotations=rotations, seed=seed,
                           max_joint_step_rad=1.0, what=f"{where}: task path point")
    if cup is not None:
        _check_cup_rests(TrayContactTerm(cup, plant.gravity_field().gravity_vector(), face_axis=face_axis), chain,
                         q_path, f"{where}: task")
    sc = SpatialScenario(name=str(raw.get("name", path.stem)), path=path, urdf=Path(urdf), hand_frame=hand,
                           lock_joints=lock, joint_names=list(names), plant=plant, ik=ik, chain=chain, body=body,
                           grip=grip, velocity_limit_rad_s=vals["velocity_limit_rad_s"],
                           acceleration_limit_rad_s2=vals["acceleration_limit_rad_s2"],
                           jerk_limit_rad_s3=vals["jerk_limit_rad_s3"], torque_limit_Nm=vals["torque_limit_Nm"],
                           drive=drive, face_normal=normals[0], poses_m=P, q_poses_rad=q_path[idx],
                           path_points_m=pts, q_path_rad=q_path, path_pose_index=idx, check_rate_hz=rate,
                           hand_kind=kind, hand_physics=physics, moment_limit_Nm=moment_limit, face_axis=face_axis, cup=cup,
                           motor=motor, pose_normals=pose_normals, path_normals=normals,
                           pose_rotations=pose_rotations, path_rotations=rotations, obstacles=obstacles,
                           uncertainty=uncertainty)
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


def _payload(raw: dict, where: str) -> CarriedBody:
    w = f"{where}: payload"
    pay = F.mapping(raw, "payload", where)
    F.check_keys(pay, {"mass_kg", "com_m", "inertia_kgm2"}, w)
    return CarriedBody(F.num(pay, "mass_kg", w, positive=True), F.vector(pay, "com_m", w, length=3),
                       np.diag(F.principal_inertia(pay, "inertia_kgm2", w)))


def _no_payload(raw: dict, where: str, body: CarriedBody) -> CarriedBody:
    if "payload" in raw:
        raise QmtInputError(f"{where}: payload: a tray hand carries its cup (hand.cup); drop the payload section")
    return body


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


def _tray_cup(hd: dict, w: str) -> TrayCup:
    """The tray hand's section: friction, cup {radius_m, height_m, mass_kg, com_height_m}, margin,
    pyramid_edges, tray_size_m (limits/tray_contact.TrayCup)."""
    F.check_keys(hd, {"kind", "friction", "cup", "margin", "pyramid_edges", "tray_size_m"}, w)
    c = F.mapping(hd, "cup", w)
    wc = f"{w}.cup"
    F.check_keys(c, {"radius_m", "height_m", "mass_kg", "com_height_m"}, wc)
    height = F.num(c, "height_m", wc, positive=True)
    com = F.num(c, "com_height_m", wc, positive=True, default=None)
    if com is not None and com >= height:
        raise QmtInputError(f"{wc}.com_height_m {com} must lie inside the cup, below height_m {height}")
    radius = F.num(c, "radius_m", wc, positive=True)
    size = (F.vector(hd, "tray_size_m", w, positive=True, length=3, what="tray length, width, thickness")
            if "tray_size_m" in hd else np.array(TrayCup.tray_size_m))
    if 2 * radius > min(size[:2]):
        raise QmtInputError(f"{wc}.radius_m {radius} is too large for the tray {size[:2].tolist()} m; give a "
                            "smaller cup or a larger tray_size_m")
    return TrayCup(radius, height, F.num(c, "mass_kg", wc, positive=True), F.num(hd, "friction", w, positive=True),
                   com_height_m=com, margin=F.num(hd, "margin", w, positive=True, maximum=1.0, default=1.0),
                   pyramid_edges=F.integer(hd, "pyramid_edges", w, minimum=3, maximum=SPATIAL_MAX_GRIP_COUNT, default=8),
                   tray_size_m=tuple(float(x) for x in size))
