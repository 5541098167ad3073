"""How far the hand leaves the task's straight lines on each shipped spatial scenario, per family.

The via-cubic family's geometric path (the planners' IK'd path: task poses and transfer points, a
joint-space C2 spline between them, planners/spatial_toppra.joint_path) and the line_cubic_velocity
family's (IK by continuation along each straight line, planners/spatial_families.line_paths) are
sampled at 400 path parameters (per segment for the line); Drake's forward kinematics gives the
hand's position, and its distance to the polyline of the path points is reported [mm].

    .venv/bin/python -m studies.spatial_path_deviation
"""

from __future__ import annotations

import sys

import numpy as np

from qmt_drake.model.spatial_ik import slerp_unit
from qmt_drake.planners.spatial_families import line_paths
from qmt_drake.planners.spatial_toppra import joint_path
from qmt_drake.spatial_task import load_spatial_scenario

SCENARIOS = ("ur5-suction-bins", "ur5-magnet-part", "panda-tray-cup")


def distance_to_polyline_m(p, points) -> float:
    """Distance [m] of point p to the polyline through `points` (P, 3)."""
    a, b = points[:-1], points[1:]
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-18), 0.0, 1.0)
    return float(np.min(np.linalg.norm(p - (a + t[:, None] * d), axis=1)))


def max_deviation_m(sc, samples: int = 400) -> float:
    pp = joint_path(sc.q_path_rad)
    pts = np.asarray(sc.path_points_m, float)
    s = np.linspace(pp.start_time(), pp.end_time(), samples)
    return max(distance_to_polyline_m(sc.ik.pose(pp.value(x).ravel())[0], pts) for x in s)


def line_family_deviation_m(sc, samples: int = 400) -> float:
    paths, _ = line_paths(sc)
    pts = np.asarray(sc.path_points_m, float)
    return max(distance_to_polyline_m(sc.ik.pose(q)[0], pts)
               for pp in paths for q in pp.vector_values(np.linspace(0.0, 1.0, samples)).T)


def line_errors(sc, plan, rate_hz: float = 1000.0):
    """(m, rad): the largest distance of the hand (Drake FK) to the straight line of the segment it is on
    and of its face normal to the normal slerped between the segment's poses, at rate_hz."""
    t = np.linspace(0.0, plan.duration_s, int(plan.duration_s * rate_hz) + 1)
    q = plan.trajectory.sample(t)[0]
    seg = np.clip(np.searchsorted(plan.pose_times_s, t, side="right") - 1, 0, len(sc.poses_m) - 2)
    worst_m = worst_rad = 0.0
    for qk, i in zip(q, seg):
        p, R = sc.ik.pose(qk)
        a, d = sc.poses_m[i], sc.poses_m[i + 1] - sc.poses_m[i]
        x = float(np.clip((p - a) @ d / (d @ d), 0.0, 1.0))
        worst_m = max(worst_m, float(np.linalg.norm(p - a - x * d)))
        n, n_ref = R @ sc.ik.face_axis, slerp_unit(sc.pose_normals[i], sc.pose_normals[i + 1], x)[0]
        worst_rad = max(worst_rad, float(np.arctan2(np.linalg.norm(np.cross(n, n_ref)), n @ n_ref)))
    return worst_m, worst_rad


def main(argv=None) -> int:
    for name in SCENARIOS:
        sc = load_spatial_scenario(name)
        print(f"{name}: {len(sc.path_points_m)} path points; the hand up to {max_deviation_m(sc) * 1e3:.1f} mm off "
              f"the straight lines between them on the via-cubic path, {line_family_deviation_m(sc) * 1e3:.2g} mm on "
              "the line_cubic_velocity family's")
    return 0


if __name__ == "__main__":
    sys.exit(main())
