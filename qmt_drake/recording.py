"""Headless Meshcat recording of a co-simulation, saved as one self-contained HTML file.

    meshcat = make_headless_meshcat()                     # localhost, free port, no browser needed
    vis = add_meshcat_visualizer(builder, scene_graph, meshcat)
    ... simulator.Initialize(); start_recording(vis); simulator.AdvanceTo(T)
    save_recording(vis, meshcat, "out/transfer.html")    # StaticHtml(): plays offline
"""

from __future__ import annotations

from pathlib import Path

from pydrake.geometry import Meshcat, MeshcatParams, MeshcatVisualizer, MeshcatVisualizerParams, Role


def make_headless_meshcat() -> Meshcat:
    """A Meshcat server on localhost with an OS-chosen port (no clashes in CI)."""
    return Meshcat(MeshcatParams(host="localhost", port=0))


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
    path.write_text(meshcat.StaticHtml())
    return path
