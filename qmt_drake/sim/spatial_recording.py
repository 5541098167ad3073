"""Meshcat recordings of the spatial co-simulation (sim/spatial_cosim.py), as self-contained HTML.

The arms' URDF meshes are not loaded (model/urdf_check strips visuals and collisions: planning
needs neither, and example-robot-data's package:// meshes would need a package map), so the arm is
drawn as a stick figure: a cylinder from each body's origin to its child joint and a sphere at
every joint, sized from the arm's reach. The part is a box at its centre of mass (suction, magnet)
or the cup's own cylinder (tray); a floor one reach below the base catches a lost part. The camera
looks at the arm from the front at 1.1 reach (recording.frame_arm). Recording adds only
illustration geometry and the floor: the plant's dynamics and the verdict are the same as without.

    rec = SpatialRecording.add(builder, plant, arm_instance)   # before plant.Finalize()
    ... rec.connect(builder) after Finalize; rec.start(plant, plant_context) after the context is set;
    rec.save(path) after the run
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Box, Cylinder, SceneGraph, Sphere
from pydrake.math import RigidTransform, RotationMatrix

from qmt_drake.recording import (
    add_floor,
    add_meshcat_visualizer,
    arm_reach_m,
    frame_arm,
    make_headless_meshcat,
    save_recording,
    start_recording,
)

ARM_RGBA = np.array([0.95, 0.55, 0.15, 1.0])
JOINT_RGBA = np.array([0.25, 0.25, 0.3, 1.0])
PART_RGBA = np.array([0.2, 0.45, 0.9, 1.0])


def add_stick_figure(plant, arm_instance) -> float:
    """Illustration geometry of the arm (module docstring) before Finalize; returns the link radius [m]."""
    reach = arm_reach_m(plant, arm_instance)
    r = 0.025 * reach
    for j in plant.GetJointIndices(arm_instance):
        joint = plant.get_joint(j)
        body = joint.parent_body()
        p = np.asarray(joint.frame_on_parent().GetFixedPoseInBodyFrame().translation(), float)
        name = f"stick_{joint.name()}"
        plant.RegisterVisualGeometry(body, RigidTransform(p), Sphere(1.4 * r), name + "_joint", JOINT_RGBA)
        length = float(np.linalg.norm(p))
        if length > 1e-6:  # a cylinder along p (Drake's Cylinder runs along its frame's z)
            R = RotationMatrix.MakeFromOneVector(p / length, 2)
            plant.RegisterVisualGeometry(body, RigidTransform(R, p / 2), Cylinder(r, length), name, ARM_RGBA)
    return r


def add_part_box(plant, part_body, com_m, size_m: float) -> None:
    """A cube of edge size_m [m] at the part's centre of mass (in its body frame)."""
    plant.RegisterVisualGeometry(part_body, RigidTransform(np.asarray(com_m, float)), Box(size_m, size_m, size_m),
                                 "part_visual", PART_RGBA)


def frame_task(meshcat, task_points_m, *, elevation_deg: float = 30.0) -> None:
    """Camera on the task: target the centre of the base (world origin) and the task points [m], looking
    across the transfer (perpendicular to first -> last point, horizontal), raised elevation_deg, at
    2.4x the radius that holds them all, so the arm above and beside them stays in the frame."""
    P = np.vstack([np.zeros(3), np.asarray(task_points_m, float)])
    centre = 0.5 * (P.min(axis=0) + P.max(axis=0))
    radius = max(float(np.max(np.linalg.norm(P - centre, axis=1))), 0.2)
    d = P[-1] - P[1]
    across = np.array([d[1], -d[0], 0.0])
    if np.linalg.norm(across) < 1e-9:
        across = np.array([0.0, -1.0, 0.0])
    across /= np.linalg.norm(across)
    if np.dot(across, centre) > 0:  # look from the side away from the work, towards the base
        across = -across
    el = np.radians(elevation_deg)
    camera = centre + 2.4 * radius * (np.cos(el) * across + np.array([0.0, 0.0, np.sin(el)]))
    meshcat.SetCameraPose(camera, centre)


@dataclass
class SpatialRecording:
    scene_graph: object
    meshcat: object
    arm_instance: object
    link_radius_m: float
    visualizer: object = None

    @classmethod
    def add(cls, builder, plant, arm_instance, scene_graph=None) -> SpatialRecording:
        """Register the plant with a SceneGraph (a new one unless given, i.e. already registered) and add
        the stick figure and the floor; call before plant.Finalize()."""
        if scene_graph is None:
            scene_graph = builder.AddSystem(SceneGraph())
            plant.RegisterAsSourceForSceneGraph(scene_graph)
        r = add_stick_figure(plant, arm_instance)
        add_floor(plant, arm_instance)
        return cls(scene_graph, make_headless_meshcat(), arm_instance, r)

    def connect(self, builder, plant, *, geometry_connected: bool = False) -> None:
        """After Finalize: the plant's poses to the SceneGraph (unless the caller did) and the visualizer."""
        if not geometry_connected:
            builder.Connect(plant.get_geometry_pose_output_port(),
                            self.scene_graph.get_source_pose_port(plant.get_source_id()))
            builder.Connect(self.scene_graph.get_query_output_port(), plant.get_geometry_query_input_port())
        self.visualizer = add_meshcat_visualizer(builder, self.scene_graph, self.meshcat)

    def start(self, plant, plant_context, task_points_m=None) -> None:
        """Frame the camera (frame_task when task points are given, else recording.frame_arm) and record."""
        if task_points_m is None:
            frame_arm(self.meshcat, plant, plant_context, self.arm_instance)
        else:
            frame_task(self.meshcat, task_points_m)
        start_recording(self.visualizer)

    def save(self, path) -> Path:
        return save_recording(self.visualizer, self.meshcat, path)
