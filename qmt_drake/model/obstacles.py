"""The cell around a spatial arm: `world.obstacles` of a spatial scenario, as plain data and as Drake
geometry welded to the world.

    world:
      obstacles:
        - {name: table, kind: box, size_m: [1.2, 0.8, 0.04], pose: {xyz_m: [0.5, 0, -0.02]}}
        - {kind: cylinder, radius_m: 0.05, length_m: 0.6, pose: {xyz_m: [0.3, 0.3, 0.3], rpy_rad: [0, 0, 0]}}
        - {kind: mesh, file: meshes/fixture.obj, scale: 0.001, pose: {xyz_m: [0.4, -0.4, 0]}}
        - {name: bin_a, kind: bin, size_m: [0.34, 0.34, 0.30], wall_m: 0.01, pose: {xyz_m: [0.45, -0.3, -0.07]}}

Every entry is one rigid shape (or a bin: a floor and four walls, open at the top) at a pose in the
world frame: `pose.xyz_m` its centre (a bin: the centre of its floor's underside), `pose.rpy_rad`
Drake's RollPitchYaw (default 0). box `size_m` [x, y, z] full lengths; cylinder `radius_m` and
`length_m` along its z; mesh `file` (.obj or .stl, relative to the scenario file) and `scale`
(default 1), taken as its convex hull (Drake's signed distance works on convex shapes); bin `size_m`
outer [x, y, z] and `wall_m` the thickness of its walls and floor. `name` is optional (default
`kind` and index). `parse_obstacles` checks all entries and refuses the bad ones in one line each,
naming `world.obstacles[i].key`; `register_obstacles` adds them to an unfinalized MultibodyPlant as
collision and illustration geometry of the world body. `read_mesh_points` reads the vertices of an
.obj or .stl file (binary or ASCII): the URDF's own collision meshes are .stl, which Drake does not
load, so their hull is built from the points (pydrake.geometry.Convex(points)).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Box, Convex, Cylinder, ProximityProperties
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.plant import CoulombFriction

from qmt_drake.config import fields as F
from qmt_drake.errors import QmtInputError

KINDS = ("box", "cylinder", "mesh", "bin")
KIND_KEYS = {"box": {"size_m"}, "cylinder": {"radius_m", "length_m"}, "mesh": {"file", "scale"},
             "bin": {"size_m", "wall_m"}}
COMMON_KEYS = {"name", "kind", "pose"}
OBSTACLE_COLOR = np.array([0.55, 0.45, 0.35, 0.6])  # a translucent brown: the arm stays visible behind walls
MESH_EXTENSIONS = (".obj", ".stl")


@dataclass(frozen=True)
class Obstacle:
    """One shape welded to the world: kind box | cylinder | mesh; X_WO its pose (xyz m, rpy rad)."""

    name: str
    kind: str
    xyz_m: tuple
    rpy_rad: tuple = (0.0, 0.0, 0.0)
    size_m: tuple | None = None  # box: full lengths along its x, y, z
    radius_m: float | None = None  # cylinder
    length_m: float | None = None  # cylinder, along its z
    file: str | None = None  # mesh (absolute path)
    scale: float = 1.0  # mesh

    def pose(self) -> RigidTransform:
        return RigidTransform(RollPitchYaw(np.asarray(self.rpy_rad, float)), np.asarray(self.xyz_m, float))

    def shape(self):
        if self.kind == "box":
            return Box(*self.size_m)
        if self.kind == "cylinder":
            return Cylinder(self.radius_m, self.length_m)
        return convex_of_file(Path(self.file), self.scale, self.name)


def parse_obstacles(raw, where: str, base: Path) -> tuple[Obstacle, ...]:
    """`world.obstacles` (module docstring) as Obstacles (a bin becomes its five boxes); raw None: none.
    Every bad entry is refused at once, one line each (QmtInputError)."""
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise QmtInputError(f"{where} must be a list of obstacles (box, cylinder, mesh or bin entries), "
                            f"got {F.show(raw)}")
    out, errors, names = [], [], set()
    for i, entry in enumerate(raw):
        w = f"{where}[{i}]"
        try:
            shapes = _one(entry, w, base, i)
            for s in shapes:
                if s.name in names:
                    raise QmtInputError(f"{w}.name {s.name!r} is used by an obstacle before it; give each a new name")
                names.add(s.name)
            out.extend(shapes)
        except QmtInputError as exc:
            errors.append(str(exc))
    if errors:
        raise QmtInputError("\n".join(errors))
    return tuple(out)


def _one(entry, w: str, base: Path, i: int) -> list[Obstacle]:
    if not isinstance(entry, dict):
        raise QmtInputError(f"{w} must be a mapping with kind ({', '.join(KINDS)}), its size and pose; "
                            f"got {F.show(entry)}")
    kind = F.string(entry, "kind", w, choices=KINDS)
    F.check_keys(entry, COMMON_KEYS | KIND_KEYS[kind], w)
    name = F.string(entry, "name", w, default=f"{kind}_{i}")
    pose = F.mapping(entry, "pose", w)
    F.check_keys(pose, {"xyz_m", "rpy_rad"}, f"{w}.pose")
    xyz = tuple(F.vector(pose, "xyz_m", f"{w}.pose", length=3, what="x, y, z in the world"))
    rpy = tuple(F.vector(pose, "rpy_rad", f"{w}.pose", length=3, what="roll, pitch, yaw")) if "rpy_rad" in pose \
        else (0.0, 0.0, 0.0)
    if kind == "box":
        size = tuple(F.vector(entry, "size_m", w, positive=True, length=3, what="x, y, z lengths"))
        return [Obstacle(name, kind, xyz, rpy, size_m=size)]
    if kind == "cylinder":
        return [Obstacle(name, kind, xyz, rpy, radius_m=F.num(entry, "radius_m", w, positive=True),
                         length_m=F.num(entry, "length_m", w, positive=True))]
    if kind == "mesh":
        path = (base / F.string(entry, "file", w)).resolve()
        if path.suffix.lower() not in MESH_EXTENSIONS or not path.is_file():
            raise QmtInputError(f"{w}.file: {path} is not an existing {' or '.join(MESH_EXTENSIONS)} file; give "
                                "the mesh's path relative to the scenario file")
        scale = F.num(entry, "scale", w, positive=True, default=1.0)
        ob = Obstacle(name, kind, xyz, rpy, file=str(path), scale=scale)
        ob.shape()  # a file without three points off a plane is refused here, not in the planner
        return [ob]
    return _bin(name, entry, w, xyz, rpy)


def _bin(name: str, entry: dict, w: str, xyz, rpy) -> list[Obstacle]:
    """A bin open at the top: a floor and four walls of thickness wall_m inside the outer size_m, as boxes
    in the bin's frame (origin at the floor's underside centre) placed by its pose."""
    sx, sy, sz = F.vector(entry, "size_m", w, positive=True, length=3, what="outer x, y, z lengths")
    t = F.num(entry, "wall_m", w, positive=True)
    if 2 * t >= min(sx, sy) or t >= sz:
        raise QmtInputError(f"{w}.wall_m {t} leaves no inside in the bin {[sx, sy, sz]} m; give a thinner wall")
    X = RigidTransform(RollPitchYaw(np.asarray(rpy, float)), np.asarray(xyz, float))
    parts = {"floor": ((sx, sy, t), (0.0, 0.0, t / 2)),
             "wall_x-": ((t, sy, sz), (-(sx - t) / 2, 0.0, sz / 2)), "wall_x+": ((t, sy, sz), ((sx - t) / 2, 0.0, sz / 2)),
             "wall_y-": ((sx - 2 * t, t, sz), (0.0, -(sy - t) / 2, sz / 2)),
             "wall_y+": ((sx - 2 * t, t, sz), (0.0, (sy - t) / 2, sz / 2))}
    out = []
    for part, (size, centre) in parts.items():
        Xp = X @ RigidTransform(np.asarray(centre))
        out.append(Obstacle(f"{name}/{part}", "box", tuple(Xp.translation()),
                            tuple(RollPitchYaw(Xp.rotation()).vector()), size_m=tuple(float(s) for s in size)))
    return out


def read_mesh_points(path: Path, where: str) -> np.ndarray:
    """(N, 3) vertices of an .obj or .stl (binary or ASCII) file, in the file's units."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise QmtInputError(f"{where}: {path} cannot be read ({exc.strerror})") from None
    if path.suffix.lower() == ".obj":
        pts = [line.split()[1:4] for line in data.decode("utf-8", "replace").splitlines() if line.startswith("v ")]
    elif len(data) >= 84 and len(data) == 84 + 50 * struct.unpack("<I", data[80:84])[0]:  # binary STL
        n = struct.unpack("<I", data[80:84])[0]
        tri = np.frombuffer(data[84:], dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]), count=n)
        pts = tri["v"].reshape(-1, 3)
    else:  # ASCII STL
        pts = [line.split()[1:4] for line in data.decode("utf-8", "replace").splitlines()
               if line.strip().startswith("vertex")]
    try:
        out = np.unique(np.asarray(pts, dtype=float).reshape(-1, 3), axis=0)
    except ValueError:
        raise QmtInputError(f"{where}: {path} has vertices that are not numbers; give a valid .obj or .stl") from None
    if len(out) < 4 or not np.all(np.isfinite(out)) or np.linalg.matrix_rank(out[1:] - out[0], tol=1e-9) < 3:
        raise QmtInputError(f"{where}: {path} has no volume (fewer than four points off a plane); give a solid mesh")
    return out


def convex_of_file(path: Path, scale: float, where: str) -> Convex:
    """The convex hull of a mesh file's vertices, scaled (m)."""
    return Convex(read_mesh_points(path, where).T * float(scale), str(path.name))


def proximity() -> ProximityProperties:
    """Collision properties of the cell (friction 0.5: only distances are read from it)."""
    props = ProximityProperties()
    props.AddProperty("material", "coulomb_friction", CoulombFriction(0.5, 0.5))
    return props


def register_obstacles(plant, obstacles, *, illustration: bool = True) -> list:
    """Add the obstacles to an unfinalized plant (registered with a SceneGraph) as collision geometry of
    the world body, named "obstacle/<name>", and (illustration) the same shapes drawn; the collision
    GeometryIds in order."""
    world = plant.world_body()
    ids = []
    for ob in obstacles:
        shape, X = ob.shape(), ob.pose()
        ids.append(plant.RegisterCollisionGeometry(world, X, shape, f"obstacle/{ob.name}", proximity()))
        if illustration:
            plant.RegisterVisualGeometry(world, X, shape, f"obstacle_visual/{ob.name}", OBSTACLE_COLOR)
    return ids
