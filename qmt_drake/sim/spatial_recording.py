"""Meshcat recordings of the spatial co-simulation (sim/spatial_cosim.py), as self-contained HTML.

The arm is drawn with its URDF's own visual geometry: model/urdf_check strips visuals for planning,
so `urdf_visuals` parses a copy of the URDF that keeps only the visuals with Drake's parser (package://
paths resolved against the directories above the URDF file) and the shapes are registered on the
plant's bodies of the same names, with the URDF's materials. Drake's Meshcat draws .obj, .gltf and
.dae meshes but not .stl (example-robot-data's xArm, TIAGo and UR collision meshes are .stl): an .stl
is converted to an in-memory .obj (`stl_as_obj`). Only a link whose visual cannot be shown (another
mesh format, a missing file, a URDF without visuals) falls back to the stick figure: a cylinder from
its origin to each child joint and a sphere at the joint, and the page says which links. The
scenario's obstacles (`world.obstacles`, when the scenario has them) and every other illustration
geometry of the plant are drawn too; the part is a box at its centre of mass (suction, magnet) or the
cup's own cylinder (tray); a floor one reach below the base catches a lost part. The camera is framed
on the workspace (`frame_workspace`). Recording adds only illustration geometry and the floor: the
plant's dynamics and the verdict are the same as without.

    rec = SpatialRecording.for_scenario(builder, plant, arm_instance, sc)   # before plant.Finalize()
    ... rec.connect(builder) after Finalize; rec.start(plant, plant_context, task_points) after the
    context is set; rec.save(path) after the run
"""

from __future__ import annotations

import re
import struct
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.common import MemoryFile
from pydrake.geometry import (
    Box,
    Cylinder,
    GeometryInstance,
    InMemoryMesh,
    Mesh,
    Role,
    SceneGraph,
    Sphere,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder

from qmt_drake.errors import QmtInputError
from qmt_drake.model.arm import add_urdf
from qmt_drake.model.urdf_package import mesh_file
from qmt_drake.recording import (
    add_floor,
    add_meshcat_visualizer,
    arm_reach_m,
    make_headless_meshcat,
    save_recording,
    start_recording,
)

ARM_RGBA = np.array([0.95, 0.55, 0.15, 1.0])
JOINT_RGBA = np.array([0.25, 0.25, 0.3, 1.0])
PART_RGBA = np.array([0.2, 0.45, 0.9, 1.0])
OBSTACLE_RGBA = np.array([0.55, 0.45, 0.35, 0.6])  # translucent: the arm stays visible behind walls
MESHCAT_MESHES = (".obj", ".gltf", ".dae")  # what Drake's Meshcat draws (it warns and skips the rest)
FOV_Y_DEG = 75.0  # Meshcat's default perspective camera


def stl_as_obj(path: Path) -> str:
    """The triangles of an .stl file (binary or ASCII) as .obj text, shared vertices merged."""
    data = path.read_bytes()
    n = struct.unpack_from("<I", data, 80)[0] if len(data) >= 84 else -1
    if len(data) == 84 + 50 * n:  # binary: 80-byte header, count, 50 bytes per triangle
        rec = np.frombuffer(data, np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]), n, 84)
        tri = rec["v"].reshape(-1, 3).astype(float)
    else:
        tri = np.array(re.findall(rb"vertex\s+(\S+)\s+(\S+)\s+(\S+)", data), float)
    verts, idx = np.unique(tri, axis=0, return_inverse=True)
    faces = idx.reshape(-1, 3) + 1
    return ("".join(f"v {x:.6g} {y:.6g} {z:.6g}\n" for x, y, z in verts)
            + "".join(f"f {a} {b} {c}\n" for a, b, c in faces))


def _visual_only_urdf(urdf: Path) -> tuple[str, dict]:
    """The URDF's text with only its links, joints and visuals (mesh paths absolute, .stl and missing or
    undrawable meshes taken out), and {link: reason} for every visual taken out."""
    root = ET.fromstring(urdf.read_text())
    dropped = {}
    for el in list(root):
        if el.tag not in ("link", "joint", "material"):
            root.remove(el)
    for link in root.findall("link"):
        for tag in ("collision", "inertial"):
            for el in link.findall(tag):
                link.remove(el)
        for vis in link.findall("visual"):
            mesh = vis.find("geometry/mesh")
            if mesh is None:
                continue
            path = mesh_file(mesh.get("filename", ""), urdf)
            ext = path.suffix.lower() if path else ""
            if path is None or ext not in MESHCAT_MESHES + (".stl",):
                dropped[link.get("name")] = f"{Path(mesh.get('filename', '')).name} " + \
                    ("not found" if path is None else f"({ext} is not drawn by Meshcat)")
                link.remove(vis)
                continue
            mesh.set("filename", "file://" + str(path))  # an .stl is redrawn from an in-memory .obj (urdf_visuals)
    for j in root.findall("joint"):
        for tag in ("dynamics", "safety_controller", "calibration", "mimic"):
            for el in j.findall(tag):
                j.remove(el)
    return ET.tostring(root, encoding="unicode"), dropped


def urdf_visuals(urdf) -> tuple[list, dict]:
    """([(link name, X_LG, shape, illustration properties)], {link: reason not drawn}) of a URDF file,
    read by Drake's parser (module docstring); .stl meshes become in-memory .obj meshes."""
    text, dropped = _visual_only_urdf(Path(urdf))
    builder = DiagramBuilder()
    scratch, sg = AddMultibodyPlantSceneGraph(builder, 0.0)
    try:
        add_urdf(scratch, text, source="the URDF's visuals")
    except QmtInputError as exc:  # the recording is a view: draw sticks and say why rather than stop the run
        return [], {"(all links)": str(exc).strip().splitlines()[0]}
    inspector = sg.model_inspector()
    out, objs = [], {}
    for g in inspector.GetAllGeometryIds(Role.kIllustration):
        shape = inspector.GetShape(g)
        if isinstance(shape, Mesh) and shape.extension() == ".stl":
            src = Path(shape.source().path())
            if src not in objs:
                objs[src] = stl_as_obj(src)
            shape = Mesh(InMemoryMesh(mesh_file=MemoryFile(objs[src], ".obj", src.stem + ".obj")), shape.scale3())
        body = scratch.GetBodyFromFrameId(inspector.GetFrameId(g))
        out.append((body.name(), inspector.GetPoseInFrame(g), shape, inspector.GetIllustrationProperties(g)))
    return out, dropped


def add_urdf_visuals(plant, arm_instance, urdf) -> tuple[int, dict]:
    """Register the URDF's visuals on the arm's bodies of the same names (before Finalize); (how many,
    {link: reason}) for the links left without (no body of that name in the plant counts too)."""
    visuals, dropped = urdf_visuals(urdf)
    n = 0
    for k, (link, X, shape, props) in enumerate(visuals):
        if not plant.HasBodyNamed(link, arm_instance):
            dropped.setdefault(link, "no such body in the plant")
            continue
        inst = GeometryInstance(X, shape, f"urdf_visual/{link}/{k}")
        inst.set_illustration_properties(props)
        plant.RegisterVisualGeometry(plant.GetBodyByName(link, arm_instance), inst)
        n += 1
    return n, dropped


def add_stick_figure(plant, arm_instance, bodies=None) -> float:
    """Stick-figure geometry (module docstring) before Finalize, on the parent bodies of the arm's joints
    (only those in `bodies`, names, when given); returns the link radius [m]."""
    reach = _chain_reach_m(plant, arm_instance)
    r = 0.025 * reach
    for j in plant.GetJointIndices(arm_instance):
        joint = plant.get_joint(j)
        body = joint.parent_body()
        if bodies is not None and body.name() not in bodies:
            continue
        p = np.asarray(joint.frame_on_parent().GetFixedPoseInBodyFrame().translation(), float)
        name = f"stick_{joint.name()}"
        plant.RegisterVisualGeometry(body, RigidTransform(p), Sphere(1.4 * r), name + "_joint", JOINT_RGBA)
        length = float(np.linalg.norm(p))
        if length > 1e-6:  # a cylinder along p (Drake's Cylinder runs along its frame's z)
            R = RotationMatrix.MakeFromOneVector(p / length, 2)
            plant.RegisterVisualGeometry(body, RigidTransform(R, p / 2), Cylinder(r, length), name, ARM_RGBA)
    return r


def _chain_reach_m(plant, arm_instance) -> float:
    """arm_reach_m over the moving joints only (a mobile robot's welded base, head and wheels would
    otherwise count as reach): the arm's size [m] for link radii and the part's box."""
    reach = 0.0
    for j in plant.GetJointIndices(arm_instance):
        joint = plant.get_joint(j)
        if joint.num_positions() > 0:
            reach += float(np.linalg.norm(joint.frame_on_parent().GetFixedPoseInBodyFrame().translation()))
            reach += float(np.linalg.norm(joint.frame_on_child().GetFixedPoseInBodyFrame().translation()))
    return max(reach + 0.1, 0.1) if reach > 0 else arm_reach_m(plant, arm_instance)


def add_part_box(plant, part_body, com_m, size_m: float) -> None:
    """A cube of edge size_m [m] at the part's centre of mass (in its body frame)."""
    plant.RegisterVisualGeometry(part_body, RigidTransform(np.asarray(com_m, float)), Box(size_m, size_m, size_m),
                                 "part_visual", PART_RGBA)


def add_obstacle_visuals(plant, obstacles) -> np.ndarray:
    """The scenario's obstacles (objects with name, pose() and shape(), model/obstacles.py) drawn on the
    world body: illustration only, so they push nothing in the simulated dynamics. Returns points [m]
    (k x 3) the camera keeps in view: a box's or cylinder's corners, another shape's origin."""
    points = []
    for ob in obstacles:
        X, shape = ob.pose(), ob.shape()
        plant.RegisterVisualGeometry(plant.world_body(), X, shape, f"obstacle_visual/{ob.name}", OBSTACLE_RGBA)
        half = (0.5 * np.array([shape.width(), shape.depth(), shape.height()]) if isinstance(shape, Box) else
                np.array([shape.radius(), shape.radius(), 0.5 * shape.length()]) if isinstance(shape, Cylinder)
                else np.zeros(3))
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
        points += [X.multiply(c) for c in corners]
    return np.array(points).reshape(-1, 3)


def moving_body_positions(plant, plant_context, arm_instance) -> np.ndarray:
    """World positions [m] (k x 3) of the parent and child bodies of the arm's moving joints."""
    bodies = {}
    for j in plant.GetJointIndices(arm_instance):
        joint = plant.get_joint(j)
        if joint.num_positions() > 0:
            for b in (joint.parent_body(), joint.child_body()):
                bodies[b.index()] = b
    return np.array([b.EvalPoseInWorld(plant_context).translation() for b in bodies.values()]).reshape(-1, 3)


def workspace_camera(points_m, *, margin_m: float = 0.15, elevation_deg: float = 35.0,
                     azimuth_deg: float = 45.0) -> tuple[np.ndarray, np.ndarray]:
    """(camera, target) [m] that keep every point in view: the target is the centre of the points'
    bounding box grown by margin_m, the camera on a 3/4 view from above (azimuth_deg off the horizontal
    direction from the box centre to the first point, i.e. the arm's base, turned away from it;
    elevation_deg up) at the distance where the sphere around the box fills Meshcat's vertical field of
    view (distance: the sphere's radius over tan(fov/2))."""
    P = np.asarray(points_m, float).reshape(-1, 3)
    lo, hi = P.min(axis=0) - margin_m, P.max(axis=0) + margin_m
    centre = 0.5 * (lo + hi)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    toward_base = P[0] - centre
    toward_base[2] = 0.0
    if np.linalg.norm(toward_base) < 1e-6:
        toward_base = np.array([-1.0, 0.0, 0.0])
    heading = np.arctan2(toward_base[1], toward_base[0]) + np.pi + np.radians(azimuth_deg)  # from the work side
    el = np.radians(elevation_deg)
    direction = np.array([np.cos(heading) * np.cos(el), np.sin(heading) * np.cos(el), np.sin(el)])
    distance = radius / np.tan(np.radians(FOV_Y_DEG) / 2)  # the box's corners rarely all face the camera
    return centre + distance * direction, centre


def frame_workspace(meshcat, plant, plant_context, arm_instance, task_points_m=(), also_m=()) -> tuple:
    """Camera on the arm's workspace: the base, the moving links at the start pose, the task points
    (the hand's path) and also_m (e.g. the obstacles' corners) [m] all in view (workspace_camera);
    returns (camera, target)."""
    P = moving_body_positions(plant, plant_context, arm_instance)
    extra = [np.asarray(x, float).reshape(-1, 3) for x in (task_points_m, also_m)]
    camera, target = workspace_camera(np.vstack([P if len(P) else np.zeros((1, 3)), *extra]))
    meshcat.SetCameraPose(camera, target)
    return camera, target


@dataclass
class SpatialRecording:
    scene_graph: object
    meshcat: object
    arm_instance: object
    link_radius_m: float
    visualizer: object = None
    note: str = ""
    fallback_links: dict = field(default_factory=dict)
    obstacle_points_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    @classmethod
    def add(cls, builder, plant, arm_instance, scene_graph=None, *, urdf=None, obstacles=()) -> SpatialRecording:
        """Register the plant with a SceneGraph (a new one unless given, i.e. already registered) and add the
        URDF's visuals (the stick figure where they cannot be shown, or everywhere without `urdf`), the
        obstacles and the floor; call before plant.Finalize()."""
        if scene_graph is None:
            scene_graph = builder.AddSystem(SceneGraph())
            plant.RegisterAsSourceForSceneGraph(scene_graph)
        dropped, n = {}, 0
        if urdf is not None:
            n, dropped = add_urdf_visuals(plant, arm_instance, urdf)
        names = {plant.get_body(b).name() for b in plant.GetBodyIndices(arm_instance)}
        if urdf is None or n == 0:
            r = add_stick_figure(plant, arm_instance)
            why = "no URDF was given" if urdf is None else "its URDF has no visual Meshcat can draw" + (
                "" if not dropped else " (" + "; ".join(f"{k}: {v}" for k, v in sorted(dropped.items())) + ")")
            note = f"The arm is drawn as a stick figure: {why}."
        else:
            stick = {k: v for k, v in dropped.items() if k in names}
            r = add_stick_figure(plant, arm_instance, bodies=set(stick)) if stick else \
                0.025 * _chain_reach_m(plant, arm_instance)
            note = "" if not stick else ("Drawn as sticks (their URDF visuals cannot be shown): "
                                         + "; ".join(f"{k}: {v}" for k, v in sorted(stick.items())) + ".")
        corners = add_obstacle_visuals(plant, obstacles)
        add_floor(plant, arm_instance, below_base_m=_chain_reach_m(plant, arm_instance))
        return cls(scene_graph, make_headless_meshcat(), arm_instance, r, note=note, fallback_links=dropped,
                   obstacle_points_m=corners)

    @classmethod
    def for_scenario(cls, builder, plant, arm_instance, sc, scene_graph=None) -> SpatialRecording:
        """`add` with the scenario's URDF and its obstacles (`sc.obstacles`, none in a scenario without)."""
        return cls.add(builder, plant, arm_instance, scene_graph, urdf=sc.urdf,
                       obstacles=tuple(getattr(sc, "obstacles", None) or ()))

    def connect(self, builder, plant, *, geometry_connected: bool = False) -> None:
        """After Finalize: the plant's poses to the SceneGraph (unless the caller did) and the visualizer."""
        if not geometry_connected:
            builder.Connect(plant.get_geometry_pose_output_port(),
                            self.scene_graph.get_source_pose_port(plant.get_source_id()))
            builder.Connect(self.scene_graph.get_query_output_port(), plant.get_geometry_query_input_port())
        self.visualizer = add_meshcat_visualizer(builder, self.scene_graph, self.meshcat)

    def start(self, plant, plant_context, task_points_m=None) -> None:
        """Frame the camera on the workspace and the obstacles (frame_workspace) and record."""
        frame_workspace(self.meshcat, plant, plant_context, self.arm_instance,
                        () if task_points_m is None else task_points_m, self.obstacle_points_m)
        start_recording(self.visualizer)

    def save(self, path) -> Path:
        return save_recording(self.visualizer, self.meshcat, path, note=self.note)
