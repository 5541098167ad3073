"""The task poses of a spatial scenario (spatial_task.py): their orientations (a face normal per pose or
a full hand rotation), the refusal of a pose that repeats the one before, and the path points between
them (the carry between the two lifts, the orientation slerped). Plain functions of the task section."""

from __future__ import annotations

import numpy as np
from pydrake.math import RollPitchYaw

from qmt_drake.config import fields as F
from qmt_drake.errors import QmtInputError
from qmt_drake.model.spatial_ik import slerp_rotations, slerp_unit


def refuse_repeated_poses(P, normals, rotations, w: str) -> None:
    """One line when a task pose repeats the one before (position and orientation): the hand would not move."""
    for k in range(1, len(P)):
        same_turn = (np.allclose(normals[k], normals[k - 1], rtol=0.0, atol=1e-12) if rotations is None
                     else np.allclose(rotations[k], rotations[k - 1], rtol=0.0, atol=1e-12))
        if np.linalg.norm(P[k] - P[k - 1]) < 1e-9 and same_turn:
            raise QmtInputError(f"{w}.poses_m[{k}] repeats pose {k - 1} (same position and orientation), so the hand "
                                "would not move between them; drop one")


def pose_rotations(tk: dict, n_poses: int, w: str) -> np.ndarray | None:
    """(K, 3, 3) R_WH from task.hand_rpy_rad (one [roll, pitch, yaw] per pose), None when not given."""
    given = [k for k in ("face_normal", "face_normals", "hand_rpy_rad") if k in tk]
    if len(given) != 1:
        raise QmtInputError(f"{w}: give exactly one of face_normal (one normal for every pose), face_normals "
                            f"(one per pose) or hand_rpy_rad (a rotation per pose){'; got ' + ', '.join(given) if given else ''}")
    if "hand_rpy_rad" not in tk:
        return None
    raw = F.sequence(tk, "hand_rpy_rad", w, length=n_poses, what="[roll, pitch, yaw] (rad), one per task pose")
    rpy = [F.radians({"r": r}, "r", f"{w}.hand_rpy_rad[{k}]", length=3) for k, r in enumerate(raw)]
    out = np.array([RollPitchYaw(r).ToRotationMatrix().matrix() for r in rpy])
    for k in range(n_poses - 1):
        if np.arccos(np.clip((np.trace(out[k].T @ out[k + 1]) - 1.0) / 2.0, -1.0, 1.0)) > np.pi - 1e-6:
            raise QmtInputError(f"{w}.hand_rpy_rad[{k + 1}] turns the hand by 180 degrees from the pose before, so "
                                "the turn has no unique axis; add a pose in between")
    return out


def pose_normals(tk: dict, n_poses: int, w: str) -> np.ndarray:
    """(K, 3) unit face normals: task.face_normal for every pose, or task.face_normals one per pose."""
    if "face_normal" in tk:
        raw = [tk["face_normal"]] * n_poses
        names = ["face_normal"] * n_poses
    else:
        raw = F.sequence(tk, "face_normals", w, length=n_poses, what="normals [x, y, z], one per task pose")
        names = [f"face_normals[{k}]" for k in range(n_poses)]
    out = np.array([F.vector({"n": r}, "n", f"{w}.{name}", length=3) for r, name in zip(raw, names)])
    norm = np.linalg.norm(out, axis=1)
    if np.any(norm < 1e-9):
        raise QmtInputError(f"{w}.{names[int(np.argmin(norm))]} has no direction; give a nonzero vector")
    out /= norm[:, None]
    for k in range(n_poses - 1):
        if out[k] @ out[k + 1] < -1.0 + 1e-6:
            raise QmtInputError(f"{w}.{names[k + 1]} is opposite to the normal before it, so the turn between "
                                "them has no unique axis; add a pose in between")
    return out


def path_points(P: np.ndarray, n_transfer: int, normals: np.ndarray, rotations, face_axis):
    """The geometric path: the task poses with n_transfer straight-line points between poses 1 and K-2
    (the carry between the two lifts), the face normal (or the rotation) slerped along; (points, index
    of each pose, normals, rotations or None)."""
    if len(P) < 4 or n_transfer == 0:
        return P.copy(), np.arange(len(P)), normals.copy(), None if rotations is None else rotations.copy()
    a, b = P[1], P[-2]
    u = np.linspace(0, 1, n_transfer + 2)[1:-1]
    inner = (1 - u)[:, None] * a + u[:, None] * b
    pts = np.vstack([P[:2], inner, P[2:]])
    idx = np.r_[0, 1, np.arange(2, len(P)) + n_transfer]
    if rotations is None:
        return pts, idx, np.vstack([normals[:2], slerp_unit(normals[1], normals[-2], u), normals[2:]]), None
    R = np.concatenate([rotations[:2], slerp_rotations(rotations[1], rotations[-2], u), rotations[2:]])
    return pts, idx, np.einsum("kij,j->ki", R, face_axis), R
