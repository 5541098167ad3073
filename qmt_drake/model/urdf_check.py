"""Reading a spatial arm's URDF for planning: check it is a serial revolute chain, build Drake's plant.

`load_arm_plant(urdf, hand_frame, ...)` turns a URDF (path or XML text) into a finalized continuous
MultibodyPlant of the arm alone: visual and collision geometry dropped (planning needs none, and
`package://` meshes would need a package map), the joints named in `lock_joints` turned into fixed
joints at their zero position (e.g. a gripper's fingers), the root link welded to the world when the
URDF does not do it (URDF's convention for a fixed base), and the carried body, if given, welded to
the hand frame.

`check_urdf(root, hand_frame, ...)` refuses, in one line naming the problem and the fix
(QmtInputError), every URDF that is not a serial chain of revolute (or continuous) joints from a
fixed base to the hand frame: floating/planar joints, prismatic joints, a link with two parents
(closed chain), a movable joint that is not on the path to the hand (branching), links on the chain
without an inertial element (or with a mass < 0 or an inertia no body has: Drake only warns and
substitutes), and joints without effort or velocity limits when no actuator section supplies them.

`drive_parameters(urdf, joints, ...)` reads gear ratios and rotor inertias from the URDF's actuators
or takes them from the scenario's actuator section, refusing a joint left without them.
"""

from __future__ import annotations

import importlib.metadata
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RotationalInertia, SpatialInertia

from qmt_drake.errors import QmtInputError
from qmt_drake.model.actuator_order import actuator_joint_names, actuator_specs, add_actuators_in_order

DRAKE_NS = "http://drake.mit.edu"
ET.register_namespace("drake", DRAKE_NS)

MOVABLE_OK = ("revolute", "continuous")

# Arms of the `example-robot-data` package (a test extra): name -> (URDF path under robots/, hand
# frame, joints to lock).
EXAMPLE_ARMS = {
    "ur3": ("ur_description/urdf/ur3_robot.urdf", "tool0", ()),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "tool0", ()),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", "tool0", ()),
    "panda": ("panda_description/urdf/panda.urdf", "panda_hand_tcp",
              ("panda_finger_joint1", "panda_finger_joint2")),
    "kinova": ("kinova_description/robots/kinova.urdf", "j2s6s200_end_effector", ()),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "link_eef", ()),
    "z1": ("z1_description/urdf/z1.urdf", "gripperStator", ("jointGripper",)),
}


def example_robot_urdf(name: str) -> tuple[Path, str, tuple]:
    """(URDF path, hand frame, joints to lock) of an arm shipped by `example-robot-data`; QmtInputError
    when the package is not installed."""
    if name not in EXAMPLE_ARMS:
        raise QmtInputError(f"unknown example arm {name!r}; choose one of {sorted(EXAMPLE_ARMS)}")
    try:
        files = importlib.metadata.files("example-robot-data") or []
    except importlib.metadata.PackageNotFoundError:
        raise QmtInputError("the example arms need the 'example-robot-data' package; "
                            "pip install example-robot-data") from None
    rel, hand, lock = EXAMPLE_ARMS[name]
    for f in files:
        if str(f).endswith("example-robot-data/robots/" + rel):
            return Path(f.locate()).resolve(), hand, lock
    raise QmtInputError(f"example-robot-data does not ship robots/{rel}; upgrade example-robot-data")


def _read_root(urdf: str | Path, source: str) -> ET.Element:
    text = str(urdf)
    if not text.lstrip().startswith("<"):
        path = Path(urdf)
        if not path.is_file():
            raise QmtInputError(f"{source}: no such URDF file; give the path of an existing .urdf")
        text = path.read_text()
    if "drake:" in text and "xmlns:drake" not in text:  # Drake's parser accepts the undeclared prefix
        text = re.sub(r"<robot\b", f'<robot xmlns:drake="{DRAKE_NS}"', text, count=1)
    try:
        return ET.fromstring(text)
    except ET.ParseError as exc:
        raise QmtInputError(f"{source}: not well-formed XML ({exc}); fix the URDF's XML") from None


def _strip_and_lock(root: ET.Element, lock_joints, source: str) -> None:
    for link in root.findall("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
    for j in root.findall("joint"):  # not used by planning; Drake warns about it
        for el in j.findall("safety_controller"):
            j.remove(el)
        for dyn in j.findall("dynamics"):  # Drake ignores joint friction and warns per joint
            dyn.attrib.pop("friction", None)
    for el in root.iter("mechanicalReduction"):  # Drake ignores it too (drive_parameters explains) and warns
        el.text = "1"
    names = {j.get("name") for j in root.findall("joint")}
    unknown = [n for n in lock_joints if n not in names]
    if unknown:
        raise QmtInputError(f"{source}: lock_joints names {unknown}, which are not joints of the URDF; "
                            f"use joint names from {sorted(n for n in names if n)}")
    for j in root.findall("joint"):
        if j.get("name") in lock_joints:
            j.set("type", "fixed")
            for tag in ("axis", "limit", "dynamics", "mimic", "calibration"):
                for el in j.findall(tag):
                    j.remove(el)
    for tr in root.findall("transmission"):
        if any(j.get("name") in lock_joints for j in tr.findall("joint")):
            root.remove(tr)


def chain_joints(root: ET.Element, hand_frame: str, source: str = "URDF") -> list[ET.Element]:
    """The joints from the root link to the link carrying `hand_frame`, base first (structure only)."""
    joints = root.findall("joint")
    links = {lk.get("name") for lk in root.findall("link")}
    parents: dict[str, ET.Element] = {}
    for j in joints:
        child = j.find("child").get("link")
        if child in parents:
            raise QmtInputError(f"{source}: link {child!r} has two parent joints "
                                f"({parents[child].get('name')!r}, {j.get('name')!r}): a closed chain; "
                                "keep one and model the loop outside the URDF")
        parents[child] = j
    if hand_frame not in links:
        raise QmtInputError(f"{source}: no link named {hand_frame!r} for the hand frame; "
                            f"name one of {sorted(links)}")
    path, link = [], hand_frame
    while link in parents:
        path.append(parents[link])
        link = parents[link].find("parent").get("link")
        if len(path) > len(joints):
            raise QmtInputError(f"{source}: the joints form a loop above {hand_frame!r}; make the URDF a tree")
    return path[::-1]


def check_urdf(root: ET.Element, hand_frame: str, *, source: str = "URDF",
               effort_limit_Nm=None, velocity_limit_rad_s=None) -> list[str]:
    """Refuse (QmtInputError, one line) a URDF that is not a serial revolute chain from a fixed base
    to `hand_frame`; returns the chain's movable joint names, base first. `effort_limit_Nm` /
    `velocity_limit_rad_s` (per joint) stand for an actuator section supplying the limits."""
    for j in root.findall("joint"):
        t = j.get("type")
        if t in ("floating", "planar"):
            raise QmtInputError(f"{source}: joint {j.get('name')!r} is {t}: a floating base; weld the arm's "
                                "base to the world with a fixed joint")
        if t == "prismatic":
            raise QmtInputError(f"{source}: joint {j.get('name')!r} is prismatic; spatial arms take revolute "
                                "joints only: lock it (lock_joints) or make it fixed")
        if t not in MOVABLE_OK + ("fixed",):
            raise QmtInputError(f"{source}: joint {j.get('name')!r} has type {t!r}; use revolute, continuous "
                                "or fixed")
    path = chain_joints(root, hand_frame, source)
    on_path = {j.get("name") for j in path}
    off = [j.get("name") for j in root.findall("joint") if j.get("type") in MOVABLE_OK and j.get("name") not in on_path]
    if off:
        raise QmtInputError(f"{source}: movable joints {off} are not on the chain from the base to "
                            f"{hand_frame!r} (a branch); lock them (lock_joints) or name a hand frame after them")
    movable = [j for j in path if j.get("type") in MOVABLE_OK]
    if not movable:
        raise QmtInputError(f"{source}: no revolute joint between the base and {hand_frame!r}; "
                            "name a hand link at the end of the arm")
    inertials = {lk.get("name"): lk.find("inertial") for lk in root.findall("link")}
    for j in movable:
        child = j.find("child").get("link")
        if inertials.get(child) is None:
            raise QmtInputError(f"{source}: link {child!r} (moved by joint {j.get('name')!r}) has no "
                                "<inertial>; give it mass, origin and inertia")
    for name, el in inertials.items():
        if el is not None:
            _check_inertial(name, el, source)
    for j in movable:
        lim = j.find("limit")
        for attr, supplied, what in (("effort", effort_limit_Nm, "effort"),
                                     ("velocity", velocity_limit_rad_s, "velocity")):
            value = None if lim is None else lim.get(attr)
            if (value is None or float(value) <= 0) and supplied is None:
                raise QmtInputError(f"{source}: joint {j.get('name')!r} has no {what} limit; add "
                                    f"<limit {attr}=\"...\"/> or give the actuator section's {what} limits")
    return [j.get("name") for j in movable]


def _check_inertial(link: str, el: ET.Element, source: str) -> None:
    """Mass >= 0 and a physically valid rotational inertia (Drake only warns and substitutes)."""
    try:
        m = float(el.find("mass").get("value"))
        i = el.find("inertia")
        v = {k: float(i.get(k, 0.0)) for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")}
    except (AttributeError, TypeError, ValueError):
        raise QmtInputError(f"{source}: link {link!r} has an <inertial> without a numeric <mass value> and "
                            "<inertia>; give both") from None
    inertia = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]],
                        [v["ixz"], v["iyz"], v["izz"]]])
    if not np.isfinite(m) or m < 0 or not np.all(np.isfinite(inertia)):
        raise QmtInputError(f"{source}: link {link!r} has mass {m} kg; give a finite mass >= 0")
    ev = np.linalg.eigvalsh(inertia)
    tol = 1e-12 * max(1.0, float(np.abs(ev).max()))
    if ev[0] < -tol or ev[0] + ev[1] < ev[2] - tol:
        raise QmtInputError(f"{source}: link {link!r} has a rotational inertia that no body has (principal "
                            f"moments {ev.round(9).tolist()} kg m^2 must be >= 0 and satisfy the triangle "
                            "inequality); fix its <inertia>")


def load_arm_plant(urdf: str | Path, hand_frame: str, *, lock_joints=(), carried=None,
                   effort_limit_Nm=None, velocity_limit_rad_s=None, source: str | None = None,
                   time_step_s: float = 0.0, finalize: bool = True):
    """(plant, hand Frame, chain joint names): the checked arm as a finalized continuous plant
    (a discrete one with time_step_s > 0; left unfinalized with finalize=False, to add bodies).

    carried: optional dict mass_kg, com_m (3, in the hand frame), inertia_kgm2 (3x3 about the
    centre of mass, hand-frame axes); welded to the hand frame as body "carried"."""
    source = source or (str(urdf) if not str(urdf).lstrip().startswith("<") else "URDF text")
    root = _read_root(urdf, source)
    _strip_and_lock(root, tuple(lock_joints), source)
    names = check_urdf(root, hand_frame, source=source, effort_limit_Nm=effort_limit_Nm,
                       velocity_limit_rad_s=velocity_limit_rad_s)
    plant, model = _parse(root, time_step_s, source)
    if actuator_joint_names(plant, model) != names:
        # Drake's actuators follow the <transmission> order and skip the ones it does not support: parse
        # again without them and add one actuator per chain joint in chain order (model/actuator_order.py)
        specs = actuator_specs(plant, model, names, source)
        for tr in root.findall("transmission"):
            root.remove(tr)
        plant, model = _parse(root, time_step_s, source)
        add_actuators_in_order(plant, model, names, specs)
    root_link = chain_root_link(root, hand_frame)
    if root_link != "world":
        base = plant.GetBodyByName(root_link, model)
        welded = {b.index() for b in plant.GetBodiesWeldedTo(plant.world_body())}
        if base.index() not in welded:
            plant.WeldFrames(plant.world_frame(), base.body_frame(), RigidTransform())
    hand = plant.GetFrameByName(hand_frame, model)
    if carried is not None:
        inertia = RotationalInertia(*_inertia_args(np.asarray(carried["inertia_kgm2"], float)))
        M = SpatialInertia.MakeFromCentralInertia(float(carried["mass_kg"]),
                                                  np.asarray(carried["com_m"], float), inertia)
        body = plant.AddRigidBody("carried", model, M)
        plant.WeldFrames(hand, body.body_frame(), RigidTransform())
    if finalize:
        plant.Finalize()
    return plant, hand, names


def _parse(root: ET.Element, time_step_s: float, source: str):
    plant = MultibodyPlant(time_step_s)
    try:
        model = Parser(plant).AddModelsFromString(ET.tostring(root, encoding="unicode"), "urdf")[0]
    except RuntimeError as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise QmtInputError(f"{source}: Drake cannot parse it ({msg}); fix the URDF") from None
    return plant, model


def drive_parameters(urdf: str | Path, joint_names, *, gear_ratio=None, rotor_inertia_kgm2=None,
                     source: str | None = None) -> dict:
    """Gear ratios N and motor-side rotor inertias J_r of the chain's joints (for a DC-motor model and
    the reflected inertia N^2 J_r): from each joint's `<transmission><actuator>` `drake:gear_ratio` /
    `drake:rotor_inertia`, replaced by `gear_ratio` / `rotor_inertia_kgm2` (per joint, the scenario's
    actuator section) when given. A joint left without either is refused in one line (a
    `<mechanicalReduction>` is not read: Drake ignores it too). Returns gear_ratio, rotor_inertia_kgm2,
    reflected_inertia_kgm2 (n,) arrays."""
    source = source or (str(urdf) if not str(urdf).lstrip().startswith("<") else "URDF text")
    root = _read_root(urdf, source)
    names = list(joint_names)
    found = {"gear_ratio": {}, "rotor_inertia": {}}
    for tr in root.findall("transmission"):
        joints = [j.get("name") for j in tr.findall("joint")]
        for act in tr.findall("actuator"):
            for child in act:
                tag = child.tag.split("}")[-1]
                if tag in found and child.tag.startswith("{" + DRAKE_NS):
                    for j in joints:
                        found[tag][j] = float(child.get("value"))
    out = {}
    for tag, given, unit in (("gear_ratio", gear_ratio, ""), ("rotor_inertia", rotor_inertia_kgm2, " kg m^2")):
        if given is not None:
            vals = np.asarray(given, float).reshape(-1)
            if vals.shape != (len(names),) or not np.all(np.isfinite(vals)) or np.any(vals < 0):
                raise QmtInputError(f"{source}: the actuator section's {tag} has {vals.size} values; give "
                                    f"{len(names)} finite values >= 0{unit}, one per joint {names}")
            out[tag] = vals
            continue
        missing = [j for j in names if j not in found[tag]]
        if missing:
            raise QmtInputError(f"{source}: joints {missing} declare no drake:{tag} in their <transmission><actuator> "
                                f"(<mechanicalReduction> is not read); add it there or give the actuator "
                                f"section's {tag} per joint")
        out[tag] = np.array([found[tag][j] for j in names])
    return {"gear_ratio": out["gear_ratio"], "rotor_inertia_kgm2": out["rotor_inertia"],
            "reflected_inertia_kgm2": out["gear_ratio"] ** 2 * out["rotor_inertia"]}


def chain_root_link(root: ET.Element, hand_frame: str) -> str:
    path = chain_joints(root, hand_frame)
    return path[0].find("parent").get("link") if path else hand_frame


def _inertia_args(m: np.ndarray):
    return m[0, 0], m[1, 1], m[2, 2], m[0, 1], m[0, 2], m[1, 2]
