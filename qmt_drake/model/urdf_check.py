"""Reading a spatial arm's URDF for planning: check it is a serial revolute chain, build Drake's plant.

`load_arm_plant(urdf, hand_frame, ...)` turns a URDF (path or XML text) into a finalized continuous
MultibodyPlant of the arm alone: visual and collision geometry dropped (planning needs none, and
`package://` meshes would need a package map), the joints in `lock_joints` (a list: each at 0; or a
mapping joint -> value, rad or m, e.g. a torso height) turned into fixed joints at that value (e.g. a
gripper's fingers), the root link welded to the world when the URDF does not do it (URDF's convention
for a fixed base), one actuator per chain joint in chain order (model/actuator_order.py), and the
carried body, if given, welded to the hand frame. `off_chain_locks` adds every movable joint off the
base-to-hand chain to the locks (`lock: off_chain` in a scenario).

`check_urdf(root, hand_frame, ...)` refuses, in one line naming the problem and the fix
(QmtInputError), every URDF that is not a serial chain of revolute (or continuous) joints from a
fixed base to the hand frame: floating/planar joints, prismatic joints, a link with two parents
(closed chain), a movable joint that is not on the path to the hand (branching), links on the chain
without an inertial element, a link moved by the chain with a mass < 0 or an inertia no body has
(Drake only warns and substitutes; for a link that does not move with the arm, such as an antenna
welded to a mobile base, a warning naming the link), and joints without effort or velocity limits
when no actuator section supplies them. `urdf_joint_limits` reads those limits (the scenario's defaults).

`drive_parameters(urdf, joints, ...)` reads gear ratios and rotor inertias from the URDF's actuators
or takes them from the scenario's actuator section; without either, an ideal joint-torque source
(N = 1, J_r = 0, marked not given: the DC-motor drive refuses it)."""

from __future__ import annotations

import logging
import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RotationalInertia, SpatialInertia

from qmt_drake.errors import QmtInputError
from qmt_drake.model.actuator_order import actuator_joint_names, actuator_specs, add_actuators_in_order
from qmt_drake.model.arm import add_urdf
from qmt_drake.model.urdf_fields import check_joint_fields
from qmt_drake.model.urdf_package import EXAMPLE_ARMS, example_robot_urdf  # noqa: F401 (re-exported)

DRAKE_NS = "http://drake.mit.edu"
ET.register_namespace("drake", DRAKE_NS)

MOVABLE_OK = ("revolute", "continuous")

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
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise QmtInputError(f"{source}: not well-formed XML ({exc}); fix the URDF's XML") from None
    check_joint_fields(root, source)  # names and numbers, before any reader or Drake's parser sees them
    return root


def lock_values(lock_joints) -> dict:
    """{joint name: value [rad or m]}: a list of names (each locked at 0) or a mapping name -> value."""
    if isinstance(lock_joints, dict):
        return {str(k): float(v) for k, v in lock_joints.items()}
    return {str(n): 0.0 for n in lock_joints}


def _strip_and_lock(root: ET.Element, lock_joints, source: str) -> None:
    lock = lock_values(lock_joints)
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
    unknown = [n for n in lock if n not in names]
    if unknown:
        raise QmtInputError(f"{source}: lock_joints names {unknown}, which are not joints of the URDF; "
                            f"use joint names from {sorted(n for n in names if n)}")
    for j in root.findall("joint"):
        if j.get("name") in lock:
            _fix_joint_at(j, lock[j.get("name")], source)
    for tr in root.findall("transmission"):
        missing = [j.get("name") for j in tr.findall("joint") if j.get("name") not in names]
        if missing:  # Drake refuses the whole file for it (Pinocchio loads it); planning reads no transmission
            warnings.warn(f"{source}: transmission {tr.get('name')!r} names joints {missing} that the URDF does "
                          "not have (ignored)", stacklevel=3)
        if missing or any(j.get("name") in lock for j in tr.findall("joint")):
            root.remove(tr)


def _fix_joint_at(j: ET.Element, value: float, source: str) -> None:
    """Turn joint j into a fixed joint at `value` (rad about its axis, or m along it): its origin
    becomes the joint's pose at that value (URDF: origin, then the motion along/about the axis)."""
    kind, name = j.get("type"), j.get("name")
    lim = j.find("limit")
    if kind in ("revolute", "prismatic") and lim is not None and value != 0.0:
        lo, hi = float(lim.get("lower", "-inf")), float(lim.get("upper", "inf"))
        if not lo <= value <= hi:
            raise QmtInputError(f"{source}: lock_joints {name}: {value:g} is outside the joint's range "
                                f"[{lo:g}, {hi:g}]; give a value inside it")
    if value != 0.0:
        if kind not in ("revolute", "continuous", "prismatic"):
            raise QmtInputError(f"{source}: lock_joints {name}: a {kind} joint locks at 0 only; give 0 or "
                                "drop the value")
        origin = j.find("origin")
        xyz = np.array([float(x) for x in (origin.get("xyz", "0 0 0") if origin is not None else "0 0 0").split()])
        rpy = np.array([float(x) for x in (origin.get("rpy", "0 0 0") if origin is not None else "0 0 0").split()])
        axis_el = j.find("axis")
        axis = np.array([float(x) for x in (axis_el.get("xyz", "1 0 0") if axis_el is not None else "1 0 0").split()])
        axis = axis / np.linalg.norm(axis)
        X = RigidTransform(RollPitchYaw(rpy), xyz)
        motion = (RigidTransform(axis * value) if kind == "prismatic"
                  else RigidTransform(RotationMatrix(AngleAxis(value, axis)), np.zeros(3)))
        X = X @ motion
        if origin is None:
            origin = ET.SubElement(j, "origin")
        origin.set("xyz", " ".join(repr(float(v)) for v in X.translation()))
        origin.set("rpy", " ".join(repr(float(v)) for v in RollPitchYaw(X.rotation()).vector()))
    j.set("type", "fixed")
    for tag in ("axis", "limit", "dynamics", "mimic", "calibration"):
        for el in j.findall(tag):
            j.remove(el)


def off_chain_locks(urdf: str | Path, hand_frame: str, lock_joints=(), source: str | None = None) -> dict:
    """`lock: off_chain`: lock_values(lock_joints) plus every movable joint not on the chain from the
    root link to `hand_frame`, at 0 (a joint named in lock_joints keeps its value)."""
    source = source or (str(urdf) if not str(urdf).lstrip().startswith("<") else "URDF text")
    root = _read_root(urdf, source)
    lock = lock_values(lock_joints)
    on_chain = {j.get("name") for j in chain_joints(root, hand_frame, source)}
    for j in root.findall("joint"):
        if j.get("type") != "fixed" and j.get("name") not in on_chain:
            lock.setdefault(j.get("name"), 0.0)
    return lock


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
        shown = str(off) if len(off) <= 8 else f"{off[:6]} and {len(off) - 6} more"
        raise QmtInputError(f"{source}: movable joints {shown} are not on the chain from the base to "
                            f"{hand_frame!r} (a branch); lock them (lock_joints, or lock: off_chain for every one) "
                            "or name a hand frame after them")
    movable = [j for j in path if j.get("type") in MOVABLE_OK]
    mimic = [j for j in movable if j.find("mimic") is not None]
    if mimic:  # the planners move every chain joint on its own; a mimic joint follows another's angle
        j = mimic[0]
        raise QmtInputError(f"{source}: chain joint {j.get('name')!r} mimics {j.find('mimic').get('joint')!r} "
                            "(<mimic>), and the planners move each chain joint on its own; lock it (lock_joints) "
                            "or drop its <mimic>")
    if not movable:
        raise QmtInputError(f"{source}: no revolute joint between the base and {hand_frame!r}; "
                            "name a hand link at the end of the arm")
    inertials = {lk.get("name"): lk.find("inertial") for lk in root.findall("link")}
    for j in movable:
        child = j.find("child").get("link")
        if inertials.get(child) is None:
            raise QmtInputError(f"{source}: link {child!r} (moved by joint {j.get('name')!r}) has no "
                                "<inertial>; give it mass, origin and inertia")
    moving = _links_below(root, movable[0].find("child").get("link"))
    for name, el in inertials.items():
        if el is None:
            continue
        try:
            _check_inertial(name, el, source)
        except QmtInputError as exc:
            if name in moving:
                raise
            # a link that does not move with the arm (welded to the base: an antenna, a sensor) plays no
            # part in the arm's dynamics; Drake substitutes a valid inertia and warns too
            warnings.warn(f"{exc} (ignored: the link does not move with the arm)", stacklevel=3)
    for j in movable:
        lim = j.find("limit")
        lo, hi = (None, None) if lim is None else (lim.get("lower"), lim.get("upper"))
        if j.get("type") == "revolute" and lo is not None and hi is not None and float(lo) == float(hi):
            # (exporters write lower = upper = 0 for "no range given"); the planners would hold it there, and
            # IK would blame the task ("too few joints", "out of reach")
            raise QmtInputError(f"{source}: chain joint {j.get('name')!r} has the range [{lo}, {hi}] (<limit lower="
                                f"\"{lo}\" upper=\"{hi}\">): it cannot move; give its range in a copy of the URDF "
                                "(arm.urdf) or lock it (lock_joints)")
        for attr, supplied, what in (("effort", effort_limit_Nm, "effort"),
                                     ("velocity", velocity_limit_rad_s, "velocity")):
            value = None if lim is None else lim.get(attr)
            if (value is None or float(value) <= 0) and supplied is None:
                raise QmtInputError(f"{source}: joint {j.get('name')!r} has no {what} limit; add "
                                    f"<limit {attr}=\"...\"/> or give the actuator section's {what} limits")
    return [j.get("name") for j in movable]


def _links_below(root: ET.Element, link: str) -> set[str]:
    """`link` and every link whose chain of parents reaches it (all move when it does)."""
    children: dict[str, list[str]] = {}
    for j in root.findall("joint"):
        children.setdefault(j.find("parent").get("link"), []).append(j.find("child").get("link"))
    out, todo = set(), [link]
    while todo:
        k = todo.pop()
        if k not in out:
            out.add(k)
            todo.extend(children.get(k, ()))
    return out


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
    _strip_and_lock(root, lock_joints, source)
    names = check_urdf(root, hand_frame, source=source, effort_limit_Nm=effort_limit_Nm,
                       velocity_limit_rad_s=velocity_limit_rad_s)
    plant, model = _parse(root, time_step_s, source)
    if actuator_joint_names(plant, model) != names:
        # Drake's actuators follow the <transmission> order and skip the ones it does not support: parse
        # again without them and add one actuator per chain joint in chain order (model/actuator_order.py)
        specs = actuator_specs(plant, model, names, source)
        for tr in root.findall("transmission"):
            root.remove(tr)
        drake_log = logging.getLogger("drake")
        level = drake_log.level
        drake_log.setLevel(logging.ERROR)  # its warnings about this URDF were given by the first parse
        try:
            plant, model = _parse(root, time_step_s, source)
        finally:
            drake_log.setLevel(level)
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
    return plant, add_urdf(plant, ET.tostring(root, encoding="unicode"), source=source)


def drive_parameters(urdf: str | Path, joint_names, *, gear_ratio=None, rotor_inertia_kgm2=None,
                     source: str | None = None, required: bool = True) -> dict:
    """Gear ratios N and motor-side rotor inertias J_r of the chain's joints (for a DC-motor model and
    the reflected inertia N^2 J_r): from each joint's `<transmission><actuator>` `drake:gear_ratio` /
    `drake:rotor_inertia`, replaced by `gear_ratio` / `rotor_inertia_kgm2` (per joint, the scenario's
    actuator section) when given. A joint left without either is refused in one line when `required`
    (a `<mechanicalReduction>` is not read: Drake ignores it too), else it gets N = 1, J_r = 0 (an ideal
    joint-torque source). Returns gear_ratio, rotor_inertia_kgm2, reflected_inertia_kgm2 (n,) arrays
    and `given` (False when a default was used)."""
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
    out, given = {}, {"gear_ratio": True, "rotor_inertia": True}
    for tag, value, unit in (("gear_ratio", gear_ratio, ""), ("rotor_inertia", rotor_inertia_kgm2, " kg m^2")):
        if value is not None:
            vals = np.asarray(value, float).reshape(-1)
            if vals.shape != (len(names),) or not np.all(np.isfinite(vals)) or np.any(vals < 0):
                raise QmtInputError(f"{source}: the actuator section's {tag} has {vals.size} values; give "
                                    f"{len(names)} finite values >= 0{unit}, one per joint {names}")
            out[tag] = vals
            continue
        missing = [j for j in names if j not in found[tag]]
        if missing and not required:  # an ideal joint-torque source: no gear, no rotor
            given[tag] = False
            out[tag] = np.array([found[tag].get(j, 1.0 if tag == "gear_ratio" else 0.0) for j in names])
            continue
        if missing:
            raise QmtInputError(f"{source}: joints {missing} declare no drake:{tag} in their <transmission><actuator> "
                                f"(<mechanicalReduction> is not read); add it there or give the actuator "
                                f"section's {tag} per joint")
        out[tag] = np.array([found[tag][j] for j in names])
    return {"gear_ratio": out["gear_ratio"], "rotor_inertia_kgm2": out["rotor_inertia"],
            "reflected_inertia_kgm2": out["gear_ratio"] ** 2 * out["rotor_inertia"],
            "given": given["gear_ratio"] and given["rotor_inertia"]}


def urdf_joint_limits(urdf: str | Path, joint_names, source: str | None = None) -> dict:
    """The URDF's own <limit velocity effort> of each joint [rad/s, N*m]: {"velocity_limit_rad_s",
    "effort_limit_Nm"} (n,) arrays, NaN where the URDF gives none (or a value <= 0)."""
    source = source or (str(urdf) if not str(urdf).lstrip().startswith("<") else "URDF text")
    joints = {j.get("name"): j for j in _read_root(urdf, source).findall("joint")}
    out = {}
    for attr, key in (("velocity", "velocity_limit_rad_s"), ("effort", "effort_limit_Nm")):
        vals = []
        for name in joint_names:
            lim = joints[name].find("limit")
            v = float(lim.get(attr, "nan")) if lim is not None else float("nan")
            vals.append(v if v > 0 else float("nan"))
        out[key] = np.array(vals)
    return out


def chain_root_link(root: ET.Element, hand_frame: str) -> str:
    path = chain_joints(root, hand_frame)
    return path[0].find("parent").get("link") if path else hand_frame


def _inertia_args(m: np.ndarray):
    return m[0, 0], m[1, 1], m[2, 2], m[0, 1], m[0, 2], m[1, 2]
