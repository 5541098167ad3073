"""Figures of the structural design (seed 003): the ten types (Fig. 4 counterpart), an arm at every
task point with the work and obstacles (Fig. 6), best E per generation/batch (Fig. 7). matplotlib;
lengths in m."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatParams

from qmt_drake.design.arm_types import TYPES, arm_type, build_plant, forward
from qmt_drake.outputs import write_text_atomic

_REL = {"P": "P parallel", "B": "B link on 2nd axis", "F": "F link on 1st axis",
        "T": "T link on normal"}


def _box_edges(c, s):
    c, h = np.asarray(c), np.asarray(s) / 2
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h + c
    edges = []
    for i in range(8):
        for j in range(i + 1, 8):
            if np.sum(np.abs(corners[i] - corners[j]) > 1e-12) == 1:
                edges.append((corners[i], corners[j]))
    return edges


def draw_arm(ax, at, lengths, q, color="C0", axis_len=0.06, lw=3, label=None):
    """Links as thick lines, joint axes as short black segments through the joint points."""
    pose = forward(at, at.origins(np.asarray(lengths, float)), np.atleast_2d(q))
    P = pose.points[0]
    ax.plot(P[:, 0], P[:, 1], P[:, 2], "-", color=color, lw=lw, label=label)
    for i in range(6):
        a = pose.axes[0, i] * axis_len
        ax.plot(*np.stack([P[i] - a, P[i] + a]).T, "k-", lw=lw + 2.5, solid_capstyle="butt")
    ax.scatter(*P[6], color="r", s=12)
    return P


def draw_boxes(ax, boxes, color="0.5"):
    for c, s in boxes:
        for p0, p1 in _box_edges(c, s):
            ax.plot(*np.stack([p0, p1]).T, color=color, lw=0.6)


def _equal(ax, pts):
    pts = np.asarray(pts)
    c = (pts.max(0) + pts.min(0)) / 2
    r = (pts.max(0) - pts.min(0)).max() / 2 + 0.05
    ax.set_xlim(c[0] - r, c[0] + r)
    ax.set_ylim(c[1] - r, c[1] + r)
    ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")


def plot_types(path, lengths=(0.3, 0.25, 0.25, 0.15, 0.0, 0.1), q=(0.0, 0.5, 0.9, 0.0, 0.7, 0.0)):
    """Fig. 4 counterpart: each type with the same lengths at one joint configuration."""
    # lazy: plots only; start-up time, headless runs never load it
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(16, 7))
    for k, T in enumerate(TYPES):
        ax = fig.add_subplot(2, 5, k + 1, projection="3d")
        at = arm_type(T)
        P = draw_arm(ax, at, lengths, q)
        for i, p in enumerate(P[:6]):
            ax.text(*p, f" {i + 1}", fontsize=7)
        _equal(ax, np.vstack([P, [[0, 0, 0]]]))
        ax.set_title(f"{T}: 1-2 {_REL[T[0]]}, 2-3 {_REL[T[1]]}", fontsize=8)
        ax.view_init(20, -60)
    fig.suptitle("The ten joint combinations (joint axes black, links coloured, tool point red); "
                 f"L1..L6 = {list(lengths)} m, q = {list(q)} rad", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_arm_at_task(path, task, type_name, lengths, q_units, title=""):
    """Fig. 6 counterpart: the arm at every reachable unit task (3D, top and side views)."""
    # lazy: plots only; start-up time, headless runs never load it
    import matplotlib.pyplot as plt
    at = arm_type(type_name)
    fig = plt.figure(figsize=(15, 5))
    views = [(20, -60, "3D"), (90, -90, "top (x right, y up)"), (0, -90, "front (x right, z up)")]
    allp = [np.zeros(3)] + [u.position_m for u in task.units]
    for k, (el, az, nm) in enumerate(views):
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        draw_boxes(ax, task.work_boxes, "0.3")
        draw_boxes(ax, task.obstacles, "0.75")
        for i, q in enumerate(q_units):
            if q is None or not np.all(np.isfinite(q)):
                continue
            P = draw_arm(ax, at, lengths, q, color=plt.cm.viridis(i / max(1, len(q_units) - 1)),
                         lw=2, axis_len=0.04)
            allp.extend(P)
        for u in task.units:
            ax.text(*u.position_m, u.name, fontsize=7)
        _equal(ax, np.array(allp))
        ax.view_init(el, az)
        ax.set_title(nm)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_convergence(path, histories: dict, xlabel="batch of 200 designs", title=""):
    """Fig. 7 counterpart: best E so far against batch (a generation of 200 for the GA)."""
    # lazy: plots only; start-up time, headless runs never load it
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, h in histories.items():
        ax.plot(np.arange(1, len(h) + 1), h, label=name)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("best E so far [1/m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def meshcat_arm_at_task(path, task, type_name, lengths, q_units, dwell_s: float = 1.0,
                        relations: dict | None = None):
    """Fig. 6 in Meshcat: a static HTML animation visiting the reachable unit tasks in order
    (dwell_s each), with the work and obstacle boxes. Returns the path."""
    meshcat = Meshcat(MeshcatParams(host="localhost", port=0))
    arm = build_plant(type_name, lengths, boxes=task.boxes, link_radius_m=task.link_radius_m,
                      tool_radius_m=task.tool_radius_m, relations=relations, meshcat=meshcat)
    ctx = arm.diagram.CreateDefaultContext()
    pctx = arm.plant.GetMyMutableContextFromRoot(ctx)
    arm.visualizer.StartRecording(set_transforms_while_recording=False)
    t = 0.0
    for q in q_units:
        if q is None or not np.all(np.isfinite(q)):
            continue
        for _ in range(2):  # hold the pose for dwell_s
            ctx.SetTime(t)
            arm.plant.SetPositions(pctx, np.asarray(q))
            arm.diagram.ForcedPublish(ctx)
            t += dwell_s / 2
    arm.visualizer.StopRecording()
    arm.visualizer.PublishRecording()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, meshcat.StaticHtml())
    return path
