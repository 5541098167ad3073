"""Where a scenario's URDF comes from: `arm.package` names a file of an installed robot-description
package (a Python distribution, e.g. `example-robot-data`), `arm.urdf` a file of one's own.

    package: example-robot-data/ur5                                   # an arm of EXAMPLE_ARMS (hand frame known)
    package: example-robot-data/tiago                                 # any URDF of the package by its name
    package: example-robot-data/tiago_description/robots/tiago.urdf   # or by its path in the package

`package_urdf(ref)` resolves these (a unique file name or path ending among the distribution's .urdf
files), refusing in one line, with the package's URDFs and `urdf:` for a file of one's own.
"""

from __future__ import annotations

import functools
import importlib.metadata
from pathlib import Path

from qmt_drake.errors import QmtInputError

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
# The hand-frame axis a known arm's tool points along, where it is not z: the Z1's wrist rolls about
# gripperStator's x axis, and the Kinova's j2s6s200_end_effector frame has its x axis along the wrist's
# roll axis, 0.16 m out from the wrist. tests/test_known_arm_setup.py checks each known arm's face axis
# against its last joint's axis and the wrist-to-hand offset by Drake's kinematics.
EXAMPLE_FACE_AXES = {"z1": (1.0, 0.0, 0.0), "kinova": (1.0, 0.0, 0.0)}


def example_face_axis(ref: str) -> tuple | None:
    """The known arm's face axis for `arm.package` ref 'example-robot-data/<arm>' (z unless listed in
    EXAMPLE_FACE_AXES); None for any other ref."""
    dist, _, rest = ref.partition("/")
    if dist != "example-robot-data" or rest not in EXAMPLE_ARMS:
        return None
    return EXAMPLE_FACE_AXES.get(rest, (0.0, 0.0, 1.0))


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


def _package_urdfs(dist: str, where: str) -> list:
    try:
        files = importlib.metadata.files(dist) or []
    except importlib.metadata.PackageNotFoundError:
        raise QmtInputError(f"{where}: package {dist!r} is not installed (pip install {dist}); for a URDF file of "
                            "your own give urdf: <path> instead") from None
    return [f for f in files if str(f).endswith(".urdf")]


def package_urdf(ref: str, where: str = "arm.package") -> tuple[Path, str | None, tuple]:
    """(URDF path, hand frame or None, joints to lock) of `ref` = '<distribution>/<arm, file name or path>'
    (module docstring); QmtInputError (one line) when the package is missing or has no such URDF."""
    dist, _, rest = ref.partition("/")
    if dist == "example-robot-data" and rest in EXAMPLE_ARMS:
        return example_robot_urdf(rest)
    urdfs = _package_urdfs(dist, where)
    name = rest.removesuffix(".urdf")
    hits = [f for f in urdfs if str(f).endswith("/" + name + ".urdf") or str(f) == name + ".urdf"] if rest else []
    if len(hits) == 1:
        return Path(hits[0].locate()).resolve(), None, ()
    names = sorted({Path(str(f)).stem for f in urdfs})
    shown = ", ".join(names[:12]) + (", ..." if len(names) > 12 else "")
    what = f"is ambiguous in {dist} ({len(hits)} files; give more of the path)" if hits else \
        f"names no URDF file of the installed package {dist}"
    arms = f"{dist}/<arm> with <arm> one of {sorted(EXAMPLE_ARMS)}, or " if dist == "example-robot-data" else ""
    raise QmtInputError(f"{where} {ref!r} {what}; give {arms}{dist}/<file> with <file> one of {shown or 'none'} "
                        "(or its path in the package), or urdf: <path> for a URDF file of your own")


@functools.lru_cache(maxsize=32)  # a distribution's file list is read once
def installed_package_dirs(name: str) -> tuple[Path, ...]:
    """The folders named `name` inside the installed Python distribution of that name (example-robot-data
    installs its robots under share/example-robot-data/); [] when it is not installed."""
    try:
        files = importlib.metadata.files(name) or []
    except importlib.metadata.PackageNotFoundError:
        return ()
    found: list[Path] = []
    for f in files:
        parts = Path(str(f)).parts
        if name in parts[:-1]:
            d = Path(f.locate()).resolve().parents[len(parts) - 2 - parts.index(name)]
            if d not in found:
                found.append(d)
    return tuple(found)


def mesh_file(uri: str, urdf: Path) -> Path | None:
    """A URDF mesh filename as an existing file, or None: package://NAME/rest is looked up in the folders
    above the URDF (a folder NAME there, or one holding NAME), then in the installed distribution NAME
    (a URDF copied out of example-robot-data still finds its meshes); file:// and relative names
    against the URDF's folder. The one resolver of the collision (limits/clearance.py) and visual
    (sim/spatial_recording.py) meshes."""
    urdf = Path(urdf)
    if uri.startswith("package://"):
        name, _, rest = uri[len("package://"):].partition("/")
        for d in [urdf.parent, *urdf.parent.parents, *installed_package_dirs(name)]:
            for root in (d, d / name):
                if root.name == name and (root / rest).is_file():
                    return root / rest
        return None
    p = Path(uri.removeprefix("file://"))
    p = p if p.is_absolute() else urdf.parent / p
    return p if p.is_file() else None
