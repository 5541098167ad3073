"""Headless Meshcat recording of a co-simulation, saved as one self-contained HTML file.

    meshcat = make_headless_meshcat()                     # localhost, free port, no browser needed
    vis = add_meshcat_visualizer(builder, scene_graph, meshcat)
    ... simulator.Initialize(); start_recording(vis); simulator.AdvanceTo(T)
    save_recording(vis, meshcat, "out/transfer.html")    # StaticHtml(): plays offline
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatParams, MeshcatVisualizer, MeshcatVisualizerParams, Role


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


def add_meshcat_visualizer(builder, scene_graph, meshcat: Meshcat, publish_period_s: float = 1 / 30):
    params = MeshcatVisualizerParams(publish_period=publish_period_s, role=Role.kIllustration)
    return MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)


def start_recording(visualizer) -> None:
    visualizer.StartRecording(set_transforms_while_recording=False)


def save_recording(visualizer, meshcat: Meshcat, path) -> Path:
    """Stop, publish the animation and write meshcat.StaticHtml() to path; returns the path."""
    visualizer.StopRecording()
    visualizer.PublishRecording()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(meshcat.StaticHtml())
    tmp.replace(path)  # atomic: never half a file
    return path
