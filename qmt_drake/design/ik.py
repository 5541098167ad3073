"""Inverse kinematics of the generated arms, every branch, batched; collision with boxes.

Position (joints 1-3). Joint 1 is vertical through the base origin, so the wrist centre
p_w = Rz(q1) g(q2, q3): q2, q3 solve the two azimuth-free equations
    g_x^2 + g_y^2 = rho*^2,   g_z = z*
and q1 = atan2(p_y, p_x) - atan2(g_y, g_x). The 2x2 system is solved by damped Newton from a grid of
N_START x N_START starts in (q2, q3) and the distinct roots are kept: a general 3R chain has up to
four, and the grid finds them for these arms (a test compares with a dense scan). This replaces
the seed's per-type closed forms with one solver for all ten types; each root is verified by full
forward kinematics (position error < POS_TOL_M).

Orientation (spherical wrist, L5 = 0): axes 4 and 6 coincide at the zero configuration and axis 5 is
perpendicular, so R4 R5 R6 = W Rz(q4) Ry(q5) Rz(q6) W^T: a ZYZ decomposition with two branches
(q5 >= 0 and its flip). The flip negates Jacobian columns 4 and 6 and moves no link (links lie on
the joint axes' lines), so it changes neither operability nor collision: the search uses one wrist
branch; `solve(..., both_wrists=True)` returns both.

Branch labels (`branch_label`): each root gets one of four labels from two signs that change only
through a singularity, so that one label can be used for a whole task (the seed's branch choice,
problem.py).

Collision. Links are capsules (segments between joint points with a radius) tested against
axis-aligned boxes: a segment sampled at N_SAMPLES points, each tested against the box grown by the
radius. The grown box contains the exact capsule-box contact set (conservative by at most
r (sqrt(3) - 1) at box corners); tests compare with Drake SceneGraph signed distances, and the
winners are re-checked by SceneGraph (problem.confirm). Units: m, rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from qmt_drake.design.arm_types import ArmType, forward, rotation
from qmt_drake.errors import QmtInputError

N_START = 4
NEWTON_ITERS = 30
POS_TOL_M = 1e-6
DUP_TOL_RAD = 1e-2  # roots closer than this are one configuration (near a fold they spread)
N_SAMPLES = 24


def _cross(a, v):
    """a x v for a fixed axis a (3,) and vectors v (N, 3) (explicit: faster than np.cross)."""
    out = np.empty_like(v)
    out[:, 0] = a[1] * v[:, 2] - a[2] * v[:, 1]
    out[:, 1] = a[2] * v[:, 0] - a[0] * v[:, 2]
    out[:, 2] = a[0] * v[:, 1] - a[1] * v[:, 0]
    return out


def _rot_apply(axis, q, v, c=None, s=None):
    """Rotate vectors v (N, 3) about unit axis (3,) by q (N,) (Rodrigues, no matrices)."""
    c = np.cos(q) if c is None else c
    s = np.sin(q) if s is None else s
    av = v @ axis
    return v * c[:, None] + _cross(axis, v) * s[:, None] + np.outer(av * (1 - c), axis)


def position_roots(at: ArmType, origins: np.ndarray, p_w: np.ndarray, with_labels: bool = False):
    """Roots (q1, q2, q3) placing the wrist centre at p_w. origins (N, 7, 3) zero-config points,
    p_w (N, 3). Returns q (N, S, 3) and ok (N, S): S = N_START^2 start slots, ok marks converged
    distinct roots (duplicates and failures False); with_labels also the branch label (N, S) of
    each slot (see `branch_label`)."""
    N = p_w.shape[0]
    S = N_START * N_START
    grid = (np.arange(N_START) + 0.5) * 2 * np.pi / N_START - np.pi
    q2s, q3s = np.meshgrid(grid, grid, indexing="ij")
    o2 = np.repeat(origins[:, 1], S, axis=0)
    o3 = np.repeat(origins[:, 2], S, axis=0)
    o5 = np.repeat(origins[:, 4], S, axis=0)
    pw = np.repeat(p_w, S, axis=0)
    rho2 = pw[:, 0] ** 2 + pw[:, 1] ** 2
    zt = pw[:, 2]
    q2 = np.tile(q2s.ravel(), N)
    q3 = np.tile(q3s.ravel(), N)
    a2, a3 = at.axes[1], at.axes[2]
    u = o5 - o3
    scale = 1.0 + np.sqrt(rho2)  # residual 1 is in m^2: scale it to m
    # rows whose target lies beyond the chain's length cannot converge: skip them
    reach = np.linalg.norm(o2, axis=1) + np.linalg.norm(o3 - o2, axis=1) + np.linalg.norm(u, axis=1)
    act = np.flatnonzero(np.linalg.norm(pw, axis=1) <= reach + 1e-9)
    for it in range(NEWTON_ITERS):
        A2, A3 = q2[act], q3[act]
        c2, s2, c3, s3 = np.cos(A2), np.sin(A2), np.cos(A3), np.sin(A3)
        hu = _rot_apply(a3, A3, u[act], c3, s3)
        h = o3[act] + hu
        gv = _rot_apply(a2, A2, h - o2[act], c2, s2)
        g = o2[act] + gv
        dg2 = _cross(a2, gv)
        dg3 = _rot_apply(a2, A2, _cross(a3, hu), c2, s2)
        sc = scale[act]
        r1 = (g[:, 0] ** 2 + g[:, 1] ** 2 - rho2[act]) / sc
        r2 = g[:, 2] - zt[act]
        j11 = 2 * (g[:, 0] * dg2[:, 0] + g[:, 1] * dg2[:, 1]) / sc
        j12 = 2 * (g[:, 0] * dg3[:, 0] + g[:, 1] * dg3[:, 1]) / sc
        j21, j22 = dg2[:, 2], dg3[:, 2]
        # damped Gauss-Newton on the 2x2 system (Levenberg: stays finite at singular points)
        rr = r1 ** 2 + r2 ** 2
        lam = 1e-9 + 1e-3 * rr
        a11 = j11 * j11 + j21 * j21 + lam
        a12 = j11 * j12 + j21 * j22
        a22 = j12 * j12 + j22 * j22 + lam
        b1 = j11 * r1 + j21 * r2
        b2 = j12 * r1 + j22 * r2
        det = a11 * a22 - a12 * a12
        d2 = -(a22 * b1 - a12 * b2) / det
        d3 = -(a11 * b2 - a12 * b1) / det
        n = np.sqrt(d2 ** 2 + d3 ** 2)
        f = np.minimum(1.0, 0.5 / np.maximum(n, 1e-300))  # at most 0.5 rad per step
        q2[act] = A2 + f * d2
        q3[act] = A3 + f * d3
        if it % 5 == 4:  # drop rows already converged to machine precision
            act = act[rr > 1e-26]
            if act.size == 0:
                break
    hu = _rot_apply(a3, q3, u)
    g = o2 + _rot_apply(a2, q2, o3 + hu - o2)
    q1 = np.arctan2(pw[:, 1], pw[:, 0]) - np.arctan2(g[:, 1], g[:, 0])
    q = _wrap(np.stack([q1, q2, q3], axis=1)).reshape(N, S, 3)
    # converged: rotate g by q1 and compare with the target
    p = _rot_apply(at.axes[0], q1, g)
    ok = (np.linalg.norm(p - pw, axis=1) < POS_TOL_M).reshape(N, S)
    for s in range(1, S):  # drop roots already found by an earlier start
        d = np.abs(_wrap(q[:, :s] - q[:, s:s + 1])).max(axis=2)
        ok[:, s] &= ~np.any(ok[:, :s] & (d < DUP_TOL_RAD), axis=1)
    if not with_labels:
        return q, ok
    dg2 = _cross(a2, g - o2)
    dg3 = _rot_apply(a2, q2, _cross(a3, hu))
    return q, ok, branch_label(at, g, dg2, dg3).reshape(N, S)


N_LABELS = 4


def branch_label(at: ArmType, g: np.ndarray, dg2: np.ndarray, dg3: np.ndarray) -> np.ndarray:
    """Branch label 0..3 of position roots from the wrist centre g (M, 3) at q1 = 0 and its
    derivatives dg/dq2, dg/dq3 (M, 3). The roots solve F(q2, q3) = (rho^2, z) = (g_x^2 + g_y^2, g_z)
    = target; label = 2 [det dF/d(q2, q3) > 0] + [s > 0] with
      s = g_x (the wrist centre in front of / behind the arm's vertical plane at q1 = 0: the PUMA's
          right / left arm) when axes 1 and 2 are perpendicular (B-, F-first types),
      s = d rho^2 / d q2 (the SCARA's elbow left / right) when they are parallel (P-first types).

    Why: the seed labels its closed-form solutions by the formulas' sign choices (elbow up/down,
    shoulder front/back, wrist flip). det dF changes sign only through a singularity (elbow
    up/down); the second sign was chosen among ten candidates (signs of g_x, g_y, the four partials,
    sin and cos of q2, q3) as the one that, for these types, separates the up to four roots of a
    regular point and never changes along a joint-space path except where det dF vanishes
    (measured on 200 random paths and points per type: no such change; roots separated at 99-100 %
    of random points, the rest near-singular; tests/test_design_ik.py). So a label is a set of
    configurations the arm can move between without a singularity, as the seed's labels are. On
    arms with a zero link the roots form a continuum at det = 0 and may share a label; the best
    root of a label then stands for it. The wrist flip is not labelled: it changes neither
    operability nor any link position (module docstring)."""
    f12 = 2 * (g[:, 0] * dg2[:, 0] + g[:, 1] * dg2[:, 1])
    f13 = 2 * (g[:, 0] * dg3[:, 0] + g[:, 1] * dg3[:, 1])
    det = f12 * dg3[:, 2] - f13 * dg2[:, 2]
    parallel_12 = abs(float(np.dot(at.axes[0], at.axes[1]))) > 0.5
    s = f12 if parallel_12 else g[:, 0]
    return 2 * (det > 0).astype(int) + (s > 0).astype(int)


def labels_of(at: ArmType, origins: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Branch labels (M,) of configurations q (M, >= 3) of arms with zero-config points origins
    (M, 7, 3) or (7, 3) (the label of the root each configuration is)."""
    q = np.atleast_2d(q)
    o = np.broadcast_to(origins, (q.shape[0], 7, 3))
    a2, a3 = at.axes[1], at.axes[2]
    hu = _rot_apply(a3, q[:, 2], o[:, 4] - o[:, 2])
    gv = _rot_apply(a2, q[:, 1], o[:, 2] + hu - o[:, 1])
    return branch_label(at, o[:, 1] + gv, _cross(a2, gv), _rot_apply(a2, q[:, 1], _cross(a3, hu)))


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def wrist_angles(at: ArmType, q123: np.ndarray, R_tool: np.ndarray, flip: bool = False) -> np.ndarray:
    """q4, q5, q6 (M, 3) for the tool rotation R_tool (M, 3, 3) given q1..q3 (M, 3)."""
    R03 = np.broadcast_to(np.eye(3), (q123.shape[0], 3, 3))
    for i in range(3):
        R03 = R03 @ rotation(at.axes[i], q123[:, i])
    Q = np.swapaxes(R03, 1, 2) @ R_tool @ at.tool_rotation.T
    z = at.axes[3]
    y = at.axes[4]
    W = np.column_stack([np.cross(y, z), y, z])
    M = W.T @ Q @ W
    s5 = np.sqrt(M[:, 0, 2] ** 2 + M[:, 1, 2] ** 2)
    if flip:
        s5 = -s5
    q5 = np.arctan2(s5, M[:, 2, 2])
    reg = np.abs(s5) > 1e-9
    sg = np.where(s5 < 0, -1.0, 1.0)
    q4 = np.where(reg, np.arctan2(sg * M[:, 1, 2], sg * M[:, 0, 2]), 0.0)
    q6 = np.where(reg, np.arctan2(sg * M[:, 2, 1], -sg * M[:, 2, 0]),
                  np.arctan2(M[:, 1, 0], M[:, 0, 0]) * np.where(M[:, 2, 2] > 0, 1.0, -1.0))
    return np.stack([q4, q5, q6], axis=1)


@dataclass
class IkSolutions:
    """q (N, B, 6) joint angles of B branch slots per target, ok (N, B) valid distinct solutions
    (reachable; collision not yet applied), label (N, B) the branch label 0..N_LABELS-1 of each
    slot (`branch_label`; both wrist flips of a root share it)."""
    q: np.ndarray
    ok: np.ndarray
    label: np.ndarray


def solve(at: ArmType, origins: np.ndarray, p_tool: np.ndarray, R_tool: np.ndarray,
          both_wrists: bool = False) -> IkSolutions:
    """Every IK branch for tool poses (p_tool (N, 3), R_tool (N, 3, 3)) of arms with zero-config
    points origins (N, 7, 3) (broadcastable from (7, 3)). Requires a spherical wrist (L5 = 0)."""
    N = p_tool.shape[0]
    o = np.broadcast_to(origins, (N, 7, 3))
    off5 = np.linalg.norm(o[:, 5] - o[:, 4], axis=1)
    if np.any(off5 > 1e-12):
        raise QmtInputError("link L5 (offset between wrist axes 5 and 6) must be 0: the analytic IK "
                            "needs a spherical wrist (the seed's genes all have L5 = 0)")
    L6 = np.linalg.norm(o[:, 6] - o[:, 5], axis=1)
    R_tool = np.broadcast_to(R_tool, (N, 3, 3))
    p_w = p_tool - L6[:, None] * R_tool[:, :, 2]
    q3, ok, lab = position_roots(at, o, p_w, with_labels=True)
    S = q3.shape[1]
    flips = (False, True) if both_wrists else (False,)
    qs, oks = [], []
    Rrep = np.repeat(R_tool, S, axis=0)
    for fl in flips:
        qw = wrist_angles(at, q3.reshape(-1, 3), Rrep, flip=fl)
        qs.append(np.concatenate([q3.reshape(-1, 3), qw], axis=1).reshape(N, S, 6))
        oks.append(ok)
    q = np.concatenate(qs, axis=1)
    okk = np.concatenate(oks, axis=1)
    # verify the full pose by forward kinematics (catches wrist decomposition errors)
    idx = np.flatnonzero(okk.ravel())
    if idx.size:
        n_of = idx // q.shape[1]
        pose = forward(at, o[n_of], q.reshape(-1, 6)[idx])
        perr = np.linalg.norm(pose.tool_position - p_tool[n_of], axis=1)
        rerr = np.abs(pose.tool_rotation - R_tool[n_of]).max(axis=(1, 2))
        bad = (perr > 1e-6) | (rerr > 1e-6)
        flat = okk.ravel()
        flat[idx[bad]] = False
        okk = flat.reshape(okk.shape)
    return IkSolutions(q, okk, np.concatenate([lab] * len(flips), axis=1))


def boxes_array(boxes) -> tuple[np.ndarray, np.ndarray]:
    """[(center, size), ...] -> centers (B, 3), half sizes (B, 3)."""
    if not len(boxes):
        return np.zeros((0, 3)), np.zeros((0, 3))
    c = np.array([b[0] for b in boxes], dtype=float)
    h = np.array([b[1] for b in boxes], dtype=float) / 2
    return c, h


def collides(points: np.ndarray, boxes, link_radius_m: float = 0.04,
             tool_radius_m: float = 0.01) -> np.ndarray:
    """(M,) True where a link capsule of the arm with joint points `points` (M, 7, 3) touches one of
    the boxes [(center, size)]. Links 1-5 have link_radius_m, the tool link 6 tool_radius_m."""
    M = points.shape[0]
    out = np.zeros(M, dtype=bool)
    c, h = boxes_array(boxes)
    if c.shape[0] == 0 or M == 0:
        return out
    t = np.linspace(0.0, 1.0, N_SAMPLES)
    radii = np.array([link_radius_m] * 5 + [tool_radius_m])
    for k in range(6):
        p0, p1 = points[:, k], points[:, k + 1]
        pts = p0[:, None] + t[None, :, None] * (p1 - p0)[:, None]          # (M, T, 3)
        for b in range(c.shape[0]):
            inside = np.all(np.abs(pts - c[b]) <= h[b] + radii[k], axis=2)   # (M, T)
            out |= inside.any(axis=1)
    return out
