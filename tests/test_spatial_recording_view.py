"""Spatial recordings draw the URDF's own meshes (.dae as is, .stl through an in-memory .obj), fall back
to sticks only for a link whose mesh Meshcat cannot draw (and say so on the page), draw obstacles, and
frame the camera on the workspace. The page is read back by decoding Meshcat's embedded commands."""

import base64
import re
import struct
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder

from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant
from qmt_drake.sim.spatial_recording import SpatialRecording, stl_as_obj, workspace_camera


def _commands(html: str) -> list[bytes]:
    """The msgpack payloads of the page's embedded Meshcat commands (base64 data: URLs)."""
    return [base64.b64decode(m) for m in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)]


def _record(tmp_path, urdf, hand, lock=(), obstacles=()):
    builder = DiagramBuilder()
    plant, H, _ = load_arm_plant(urdf, hand, lock_joints=lock, finalize=False)
    builder.AddSystem(plant)
    rec = SpatialRecording.add(builder, plant, H.model_instance(), urdf=urdf, obstacles=obstacles)
    plant.Finalize()
    rec.connect(builder, plant)
    diagram = builder.Build()
    ctx = diagram.CreateDefaultContext()
    pctx = plant.GetMyContextFromRoot(ctx)
    rec.start(plant, pctx, [[0.4, 0.2, 0.1], [0.4, -0.2, 0.1]])
    diagram.ForcedPublish(ctx)
    path = rec.save(tmp_path / "run.html")
    return rec, path.read_text()


@dataclass(frozen=True)
class _Ob:
    name: str

    def pose(self):
        return RigidTransform([0.5, 0.0, -0.1])

    def shape(self):
        return Box(0.3, 0.3, 0.02)


def test_ur5_recording_has_its_dae_meshes_obstacles_and_camera(tmp_path):
    urdf, hand, lock = example_robot_urdf("ur5")
    rec, html = _record(tmp_path, urdf, hand, lock, obstacles=(_Ob("table"),))
    cmds = _commands(html)
    meshes = [c for c in cmds if b"set_object" in c and b"_meshfile" in c]
    assert len(meshes) >= 6 and all(b"format\xa3dae" in c for c in meshes)  # base, shoulder, ..., wrist 3
    assert any(b"urdf_visual/upper_arm_link" in c or b"upper_arm_link" in c for c in meshes)
    assert not any(b"stick_" in c for c in cmds)  # no stick figure where the meshes are drawn
    assert any(b"obstacle_visual/table" in c for c in cmds)
    assert any(b"set_target" in c for c in cmds) and any(b"/Cameras/default" in c for c in cmds)
    assert rec.note == "" and "qmt-note" not in html
    corners = rec.obstacle_points_m  # the table's corners are framed too
    assert corners.shape == (8, 3) and np.allclose(corners.min(axis=0), [0.35, -0.15, -0.11])


def test_stl_meshes_drawn_as_obj_on_a_7dof_arm(tmp_path):
    urdf, hand, lock = example_robot_urdf("xarm7")  # every visual an .stl, which Meshcat does not read
    _, html = _record(tmp_path, urdf, hand, lock)
    meshes = [c for c in _commands(html) if b"set_object" in c and b"_meshfile" in c]
    assert len(meshes) >= 8 and all(b"format\xa3obj" in c and b"\nf " in c for c in meshes)


def test_undrawable_mesh_falls_back_to_sticks_and_says_so(tmp_path):
    urdf, hand, lock = example_robot_urdf("ur5")
    share = str(urdf)[:str(urdf).index("/example-robot-data/") + 1]
    ply = tmp_path / "forearm.ply"
    ply.write_text("ply\n")
    text = urdf.read_text().replace("package://", share)  # absolute paths, resolved as files
    text = re.sub(r'filename="[^"]*visual/forearm\.dae"', f'filename="{ply}"', text)
    own = tmp_path / "ur5_ply.urdf"
    own.write_text(text)
    rec, html = _record(tmp_path, own, hand, lock)
    assert set(rec.fallback_links) == {"forearm_link"}
    assert "forearm_link: forearm.ply (.ply is not drawn by Meshcat)" in html and 'id="qmt-note"' in html
    cmds = _commands(html)
    assert any(b"stick_wrist_1_joint" in c for c in cmds)  # the forearm's joint to its child, as a stick
    assert sum(b"_meshfile" in c and b"set_object" in c for c in cmds) >= 5  # the other links' meshes


def test_stl_as_obj_binary_and_ascii(tmp_path):
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
    b = tmp_path / "t.stl"
    b.write_bytes(b"\0" * 80 + struct.pack("<I", 2) + b"".join(
        struct.pack("<3f", 0, 0, 1) + tri[3 * k:3 * k + 3].tobytes() + b"\0\0" for k in range(2)))
    obj = stl_as_obj(b)
    assert obj.count("v ") == 4 and obj.count("f ") == 2  # (0,0,0) and (0,1,0) shared
    a = tmp_path / "a.stl"
    a.write_text("solid t\n" + "".join("facet normal 0 0 1\nouter loop\n" + "".join(
        f"vertex {x} {y} {z}\n" for x, y, z in tri[3 * k:3 * k + 3]) + "endloop\nendfacet\n" for k in range(2))
        + "endsolid t\n")
    assert stl_as_obj(a) == obj


def test_workspace_camera_sees_every_point():
    P = np.array([[0, 0, 0], [0.8, 0.5, 0.2], [0.8, -0.5, 0.2], [0.3, 0, 0.9]])
    cam, target = workspace_camera(P)
    for p in P:  # every point within Meshcat's 75 degree field of view (half-angle 37.5 deg) and in front
        v, axis = p - cam, (target - cam) / np.linalg.norm(target - cam)
        assert np.degrees(np.arccos(np.dot(v, axis) / np.linalg.norm(v))) < 37.5
    assert cam[2] > P[:, 2].max()  # from above
    assert min(np.linalg.norm(cam - p) for p in P) > 0.5  # not inside the robot


def test_urdf_without_visuals_is_drawn_as_sticks_and_says_so(tmp_path):
    urdf, hand, lock = example_robot_urdf("ur5")
    own = tmp_path / "bare.urdf"
    own.write_text(re.sub(r"<visual>.*?</visual>", "", urdf.read_text(), flags=re.S))
    rec, html = _record(tmp_path, own, hand, lock)
    assert "drawn as a stick figure: its URDF has no visual Meshcat can draw" in html
    assert any(b"stick_elbow_joint" in c for c in _commands(html))
