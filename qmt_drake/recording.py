"""Headless Meshcat recording of a co-simulation, saved as one self-contained HTML file.

    meshcat = make_headless_meshcat()                     # localhost, free port, no browser needed
    add_floor(plant, arm_instance)                        # before Finalize: a lost part lands on it
    vis = add_meshcat_visualizer(builder, scene_graph, meshcat)
    frame_arm(meshcat, plant, plant_context, arm_instance)  # camera from the arm's reach
    ... simulator.Initialize(); start_recording(vis); simulator.AdvanceTo(T)
    save_recording(vis, meshcat, "out/transfer.html")    # StaticHtml(): plays offline
"""

from __future__ import annotations

from html import escape
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    Box,
    Meshcat,
    MeshcatParams,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    Role,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import CoulombFriction

from qmt_drake.outputs import write_text_atomic

# The arms span about 0.3 m: look at the work area from the front and above, close enough to see
# the payload (Meshcat's default camera sits metres away).
CAMERA_IN_WORLD_M = np.array([0.0, -0.42, 0.38])
CAMERA_TARGET_IN_WORLD_M = np.array([0.0, 0.10, -0.03])


def make_headless_meshcat(camera_in_world_m=None, target_in_world_m=None) -> Meshcat:
    """A Meshcat server on localhost with an OS-chosen port (no clashes in CI), its camera at
    camera_in_world_m [m] looking at target_in_world_m [m] (default: the thesis arms' work area;
    e.g. the CRANE-X7 tray study looks at its vertical plane from the side)."""
    meshcat = Meshcat(MeshcatParams(host="localhost", port=0))
    meshcat.SetCameraPose(np.asarray(CAMERA_IN_WORLD_M if camera_in_world_m is None else camera_in_world_m, float),
                          np.asarray(CAMERA_TARGET_IN_WORLD_M if target_in_world_m is None else target_in_world_m,
                                     float))
    return meshcat


def arm_reach_m(plant, arm_instance) -> float:
    """Sum of the distances between consecutive joint frames of `arm_instance` (its reach from the
    base [m], any posture) plus the extent of the bodies welded beyond the last joint (hand,
    payload) up to 0.1 m. Works before or after Finalize."""
    reach = 0.0
    for j in plant.GetJointIndices(arm_instance):
        joint = plant.get_joint(j)
        reach += float(np.linalg.norm(joint.frame_on_parent().GetFixedPoseInBodyFrame().translation()))
        reach += float(np.linalg.norm(joint.frame_on_child().GetFixedPoseInBodyFrame().translation()))
    return max(reach + 0.1, 0.1)


def add_floor(plant, arm_instance, *, below_base_m: float | None = None, friction: float = 0.5) -> float:
    """Before Finalize: a floor (collision and visual box, top face horizontal) under the arm, at the
    base's height minus below_base_m [m] (default: the arm's reach, so a horizontal arm never touches
    it while a lost part lands on it instead of falling for ever). Returns the floor's height [m]."""
    reach = arm_reach_m(plant, arm_instance)
    drop = reach if below_base_m is None else float(below_base_m)
    z_top = -drop  # the arms' bases sit at the world origin (the URDFs weld them there)
    size = 8.0 * reach
    X = RigidTransform([0.0, 0.0, z_top - 0.01])
    shape = Box(size, size, 0.02)
    plant.RegisterCollisionGeometry(plant.world_body(), X, shape, "floor", CoulombFriction(friction, friction))
    plant.RegisterVisualGeometry(plant.world_body(), X, shape, "floor_visual", np.array([0.85, 0.85, 0.8, 1.0]))
    return z_top


def frame_arm(meshcat: Meshcat, plant, plant_context, arm_instance, *, view: str = "front") -> None:
    """Point the camera at the arm so that its whole reach fills most of the frame: the target is the
    base, the camera 1.1 reach away (Meshcat's 75 degree vertical field of view then spans 1.7 reach),
    in front (view 'front', looking along +y) or at the side (view 'side', along -x), raised 30 degrees."""
    reach = arm_reach_m(plant, arm_instance)
    bodies = [plant.get_body(b) for b in plant.GetBodyIndices(arm_instance)]
    base = bodies[0].EvalPoseInWorld(plant_context).translation() if bodies else np.zeros(3)
    d = 1.1 * reach
    horizontal = np.array([0.0, -1.0, 0.0]) if view == "front" else np.array([1.0, 0.0, 0.0])
    camera = base + d * (np.cos(np.radians(30)) * horizontal + np.array([0.0, 0.0, np.sin(np.radians(30))]))
    meshcat.SetCameraPose(camera, base + np.array([0.0, 0.0, -0.1 * reach]))


def add_meshcat_visualizer(builder, scene_graph, meshcat: Meshcat, publish_period_s: float = 1 / 30):
    params = MeshcatVisualizerParams(publish_period=publish_period_s, role=Role.kIllustration)
    return MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)


def start_recording(visualizer) -> None:
    visualizer.StartRecording(set_transforms_while_recording=False)


def save_recording(visualizer, meshcat: Meshcat, path, note: str = "") -> Path:
    """Stop, publish the animation and write meshcat.StaticHtml() to path; returns the path. A note
    (plain text, e.g. which links are drawn as sticks) is shown in a small box at the page's top left."""
    visualizer.StopRecording()
    visualizer.PublishRecording()
    html = meshcat.StaticHtml()
    if note:
        box = ('<div id="qmt-note" style="position:absolute;top:8px;left:8px;max-width:45%;z-index:10;'
               'font:13px sans-serif;background:rgba(255,255,255,0.85);padding:4px 8px">'
               f"{escape(note)}</div>")
        html = html.replace("<body>", "<body>" + box, 1)
    write_text_atomic(path, html)  # atomic, unpredictable temporary; '-' is stdout
    return Path(path)
