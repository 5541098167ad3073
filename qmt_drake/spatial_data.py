"""A spatial scenario as plain typed data: what its YAML file says, validated key by key, and nothing built.

    data = parse_spatial_data(path)           # SpatialScenarioData: no plant, no IK, no chain
    sc = spatial_task.build_spatial_scenario(data)   # the one builder of the planning objects

The schema is spatial_task.py's module docstring. Every check that needs only the file is made here,
through config/fields.py's checkers (one number rule, errors naming `file: section.key`); the checks that
need the arm (one value per joint, the URDF's defaults, the poses reachable) are the builder's. The data
holds numbers, strings, paths, numpy arrays and small frozen records (CarriedBody, TrayCup, Obstacle):
no Drake object, so it pickles, compares and prints as what the user wrote.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from qmt_drake import spatial_poses
from qmt_drake.budgets import SPATIAL_MAX_GRIP_COUNT, check_spatial_sizes
from qmt_drake.config import fields as F
from qmt_drake.config.resolve import SCENARIO_DIR, SPATIAL, resolve_scenario
from qmt_drake.config.simulation import NO_SIMULATION, Simulation, parse_simulation
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.contact_wrench import CarriedBody
from qmt_drake.limits.tray_contact import TrayCup
from qmt_drake.model.obstacles import Obstacle, parse_obstacles
from qmt_drake.model.urdf_check import off_chain_locks
from qmt_drake.model.urdf_package import EXAMPLE_ARMS, example_face_axis, package_urdf
from qmt_drake.sweep.parameters import check_spatial_uncertainty

HAND_PHYSICS = ("weld", "contact")  # hand.physics: how the co-simulation holds a suction or magnet part
ACTUATOR_KEYS = ("velocity_limit_rad_s", "acceleration_limit_rad_s2", "jerk_limit_rad_s3", "torque_limit_Nm",
                 "gear_ratio", "rotor_inertia_kgm2")
OPTIONAL_ACTUATOR_KEYS = ("velocity_limit_rad_s", "torque_limit_Nm", "gear_ratio", "rotor_inertia_kgm2")
DEFAULT_CHECK_RATE_HZ = 200.0  # limits.check_rate_hz when the section is left out (the shipped scenarios state 200)
TOP_KEYS = {"kind", "name", "description", "arm", "actuators", "payload", "hand", "task", "limits", "world",
            "uncertainty", "simulation"}
# why a spatial scenario's plant is discrete (simulation.plant.time_step 0 refused) and a weld hand refuses TAMSI
DISCRETE_ONLY = ("the hand (a weld constraint, a contact seat or the tray's cup) is stepped by the discrete plant's "
                 "contact solver and the hold is checked at every plant step")
WELD_NO_TAMSI = ("the hand holds its part by a weld constraint (hand.physics weld), which Drake's TAMSI solver does "
                 "not model")
TASK_KEYS = {"seed_rad", "face_normal", "face_normals", "hand_rpy_rad", "poses_m", "transfer_points",
             "free_spin_about_normal"}


@dataclass(frozen=True)
class SpatialArmData:
    """`arm`: the URDF (a file of an installed package or the user's own), the link the hand is fixed to,
    the hand-frame axis the hand faces along, and the joints fixed (joint -> value, rad or m)."""

    urdf: Path
    hand_frame: str
    face_axis: np.ndarray  # unit, hand frame
    lock_joints: dict = field(default_factory=dict)


@dataclass(frozen=True)
class SpatialActuatorData:
    """`actuators`: the per-joint vectors as given (key -> (n,) array; a key left out takes the URDF's value
    when the builder knows the joints) and the raw `motor` mapping (spatial_motor.parse_motor_section
    checks it against the joints)."""

    given: dict  # subset of ACTUATOR_KEYS -> np.ndarray
    motor: dict | None = None


@dataclass(frozen=True)
class SpatialHandData:
    """`hand`: kind suction | magnet | tray, with the values of that kind (the others None)."""

    kind: str
    physics: str = "weld"
    cup_radius_m: float | None = None  # suction
    vacuum_force_N: float | None = None
    friction: float | None = None
    rim_points: int | None = None
    pyramid_edges: int | None = None
    moment_limit_Nm: float | None = None  # magnet
    cup: TrayCup | None = None  # tray


@dataclass(frozen=True)
class SpatialTaskData:
    """`task`: the IK seed, the task poses and their orientations (normals always, rotations when
    hand_rpy_rad fixes the spin), and the transfer points of the carry."""

    seed_rad: np.ndarray | None  # None: the IK tries several starts and keeps the least joint motion
    poses_m: np.ndarray  # (K, 3)
    pose_normals: np.ndarray  # (K, 3) unit, world
    pose_rotations: np.ndarray | None  # (K, 3, 3) R_WH, None: the spin about the normal is free
    transfer_points: int = 0


@dataclass(frozen=True)
class SpatialScenarioData:
    """A spatial scenario file, validated, as plain data (module docstring)."""

    name: str
    path: Path
    arm: SpatialArmData
    actuators: SpatialActuatorData
    hand: SpatialHandData
    payload: CarriedBody  # the carried body (tray: the cup standing on the tray)
    task: SpatialTaskData
    check_rate_hz: float
    obstacles: tuple[Obstacle, ...] = ()
    uncertainty: dict = field(default_factory=dict)
    simulation: Simulation = NO_SIMULATION  # `simulation`: the co-simulation's plant and simulator settings

    @property
    def lock_joints(self) -> dict:
        return self.arm.lock_joints


def parse_spatial_data(name_or_path: str | Path, overrides: dict | None = None) -> SpatialScenarioData:
    """The plain data of a spatial scenario (a built-in name or a YAML path), `overrides` merged into its
    YAML mapping first (config/fields.merge_overrides); QmtInputError (one line naming `file:
    section.key`) for any bad value the file alone shows."""
    path = resolve_scenario(name_or_path, SPATIAL)
    raw = F.read_yaml_mapping(path, "spatial scenario", SCENARIO_DIR / "ur5-suction-bins.yaml")
    if overrides:
        raw = F.merge_overrides(raw, overrides)
    where = path.name
    F.check_keys(raw, TOP_KEYS, where)
    if raw.get("kind") != SPATIAL:
        raise QmtInputError(f"{where}: kind must be '{SPATIAL}' for a spatial scenario, got {raw.get('kind')!r}")
    world = F.mapping(raw, "world", where, default={})
    F.check_keys(world, {"obstacles"}, f"{where}: world")
    obstacles = parse_obstacles(world.get("obstacles"), f"{where}: world.obstacles", path.parent)
    arm = _arm(F.mapping(raw, "arm", where), f"{where}: arm", path.parent)

    w = f"{where}: actuators"
    act = F.mapping(raw, "actuators", where)
    F.check_keys(act, set(ACTUATOR_KEYS) | {"motor"}, w)
    given = {k: F.vector(act, k, w, positive=True) for k in ACTUATOR_KEYS
             if k in act or k not in OPTIONAL_ACTUATOR_KEYS}
    actuators = SpatialActuatorData(given, act.get("motor"))

    hand = _hand(F.mapping(raw, "hand", where), f"{where}: hand", arm.face_axis)
    if hand.cup is None:
        payload = _payload(raw, where)
    elif "payload" in raw:
        raise QmtInputError(f"{where}: payload: a tray hand carries its cup (hand.cup); drop the payload section")
    else:
        payload = hand.cup.body(arm.face_axis)

    task = _task(F.mapping(raw, "task", where), f"{where}: task", arm.face_axis)
    lim = F.mapping(raw, "limits", where) if "limits" in raw else {}
    F.check_keys(lim, {"check_rate_hz"}, f"{where}: limits")
    rate = F.num(lim, "check_rate_hz", f"{where}: limits", positive=True, default=DEFAULT_CHECK_RATE_HZ)
    check_spatial_sizes(where, transfer_points=task.transfer_points, check_rate_hz=rate)
    uncertainty = check_spatial_uncertainty(raw.get("uncertainty"), hand.kind, f"{where}: uncertainty")
    simulation = parse_simulation(raw.get("simulation"), where, continuous=DISCRETE_ONLY,
                                  no_tamsi=WELD_NO_TAMSI if hand.kind != "tray" and hand.physics == "weld" else None)
    return SpatialScenarioData(name=F.string(raw, "name", where, default=path.stem), path=path, arm=arm, actuators=actuators,
                               hand=hand, payload=payload, task=task, check_rate_hz=rate, obstacles=obstacles,
                               uncertainty=uncertainty, simulation=simulation)


def _arm(raw: dict, where: str, base: Path) -> SpatialArmData:
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
    known = example_face_axis(F.string(raw, "package", where)) if "package" in raw else None
    face = (F.direction(raw, "face_axis", where) if "face_axis" in raw
            else np.array(known if known is not None else (0.0, 0.0, 1.0)))
    return SpatialArmData(Path(urdf), hand, face, lock)


def _lock_joints(raw, where: str) -> dict:
    """arm.lock_joints: a list of joint names (each locked at 0) or a mapping joint -> value (rad or m)."""
    if isinstance(raw, dict):
        return {str(k): F.num(raw, k, where) for k in raw}
    if isinstance(raw, (list, tuple)) and all(isinstance(k, str) for k in raw):
        twice = sorted({k for k in raw if raw.count(k) > 1})
        if twice:  # a joint listed twice is a copy-paste slip (the other joint meant is then left free)
            raise QmtInputError(f"{where} names {twice} more than once; list each joint once")
        return {k: 0.0 for k in raw}
    raise QmtInputError(f"{where} must be a list of joint names (locked at 0) or a mapping joint: value "
                        f"(rad or m, e.g. {{torso_lift_joint: 0.25}}); got {F.show(raw)}")


def _hand(hd: dict, w: str, face_axis: np.ndarray) -> SpatialHandData:
    kind = F.string(hd, "kind", w, choices=("suction", "magnet", "tray"))
    if kind == "tray":
        return SpatialHandData(kind, cup=_tray_cup(hd, w))
    if kind == "suction":
        F.check_keys(hd, {"kind", "cup_radius_m", "vacuum_force_N", "friction", "rim_points", "pyramid_edges",
                          "physics"}, w)
        rim, edges = (F.integer(hd, k, w, minimum=3, maximum=SPATIAL_MAX_GRIP_COUNT, default=d)
                      for k, d in (("rim_points", 8), ("pyramid_edges", 4)))
        check_spatial_sizes(w, rim_points=rim, pyramid_edges=edges)
        radius, pull, mu = (F.num(hd, k, w, positive=True) for k in ("cup_radius_m", "vacuum_force_N", "friction"))
        return SpatialHandData(kind, F.string(hd, "physics", w, choices=HAND_PHYSICS, default="weld"),
                               cup_radius_m=radius, vacuum_force_N=pull, friction=mu, rim_points=rim,
                               pyramid_edges=edges)
    F.check_keys(hd, {"kind", "moment_limit_Nm", "physics"}, w)
    moment = F.num(hd, "moment_limit_Nm", w, positive=True)
    return SpatialHandData(kind, F.string(hd, "physics", w, choices=HAND_PHYSICS, default="weld"),
                           moment_limit_Nm=moment)


def _payload(raw: dict, where: str) -> CarriedBody:
    w = f"{where}: payload"
    pay = F.mapping(raw, "payload", where)
    F.check_keys(pay, {"mass_kg", "com_m", "inertia_kgm2"}, w)
    return CarriedBody(F.num(pay, "mass_kg", w, positive=True), F.vector(pay, "com_m", w, length=3),
                       np.diag(F.principal_inertia(pay, "inertia_kgm2", w)))


def _task(tk: dict, w: str, face_axis: np.ndarray) -> SpatialTaskData:
    F.check_keys(tk, TASK_KEYS, w)
    # its length: the builder (joints); without it the IK tries several starts (SpatialIK.solve_path)
    seed = F.radians(tk, "seed_rad", w, what="one joint angle per joint") if "seed_rad" in tk else None
    poses = F.sequence(tk, "poses_m", w, min_length=2, what="positions [x, y, z] (m)")
    check_spatial_sizes(w, task_poses=len(poses))
    P = np.array([F.vector({"p": p}, "p", f"{w}.poses_m[{k}]", length=3) for k, p in enumerate(poses)])
    rotations = spatial_poses.pose_rotations(tk, len(P), w)
    normals = (spatial_poses.pose_normals(tk, len(P), w) if rotations is None
               else np.einsum("kij,j->ki", rotations, face_axis))
    if F.boolean(tk, "free_spin_about_normal", w, default=False):
        rotations = None  # only the face normal of each hand_rpy_rad is kept
    elif "hand_rpy_rad" not in tk and "free_spin_about_normal" in tk:
        raise QmtInputError(f"{w}.free_spin_about_normal: false needs hand_rpy_rad (a face normal leaves the "
                            "spin free); give hand_rpy_rad to fix the spin, or drop the key")
    spatial_poses.refuse_repeated_poses(P, normals, rotations, w)
    n_transfer = F.integer(tk, "transfer_points", w, minimum=0, default=0)
    if n_transfer and len(P) < 4:  # spatial_poses.path_points fills the carry between poses 1 and K-2 only
        raise QmtInputError(f"{w}.transfer_points {n_transfer}: the points go on the carry between the lift and the "
                            f"lower (poses 1 and K-2 of pick, lift, ..., lower, place), and this task has {len(P)} "
                            "poses; add the points you want to poses_m instead")
    return SpatialTaskData(seed, P, normals, rotations, n_transfer)


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
