"""Stick figures of planned motions of the vertical arm (X1 horizontal, X2 up), as in seed 001's
Fig. 3 and Fig. 4, and small helpers for the study's plots. Units: m, s."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps

from qmt_drake.energy.dynamics import VerticalArm


def joint_points(arm: VerticalArm, q) -> np.ndarray:
    """(..., n+1, 2) base, joints and tip for joint angles (..., n)."""
    phi = np.cumsum(np.asarray(q, dtype=float), axis=-1)
    seg = np.stack([arm.length_m * np.cos(phi), arm.length_m * np.sin(phi)], axis=-1)
    zero = np.zeros(seg.shape[:-2] + (1, 2))
    return np.concatenate([zero, np.cumsum(seg, axis=-2)], axis=-2)


def stick_figure(ax, arm: VerticalArm, family, x, frames: int = 11, title: str = "", legend: bool = True) -> None:
    """Postures of the motion x evenly spaced in time (colour: time), the tip path and the base; axes
    X1 horizontal and X2 up in metres. legend: draw the key (once per figure is enough)."""
    T = family.unpack(x)[2]
    t = np.linspace(0.0, T, frames)
    q, _, _ = family.sample(x, t)
    P = joint_points(arm, q)
    cmap = colormaps["viridis"]
    for k in range(frames):
        label = "arm at t = 0" if k == 0 else (f"arm at t = T = {T:.3f} s" if k == frames - 1 else None)
        ax.plot(P[k, :, 0], P[k, :, 1], "-o", color=cmap(k / max(frames - 1, 1)), ms=2, lw=1.2, label=label)
    tt = np.linspace(0.0, T, 200)
    tip = joint_points(arm, family.sample(x, tt)[0])[:, -1]
    ax.plot(tip[:, 0], tip[:, 1], "k:", lw=0.8, label="tip path")
    ax.plot([0], [0], "ks", ms=5, label="base")
    ax.set_xlabel("X1, horizontal [m]", fontsize=7)
    ax.set_ylabel("X2, up [m]", fontsize=7)
    if legend:
        ax.legend(fontsize=6, loc="best", title=f"{frames} postures, even in time", title_fontsize=6)
    ax.set_aspect("equal")
    # zoom on the motion (equal axes, 5 cm margin); the base is always in view
    lo = np.minimum(P.reshape(-1, 2).min(axis=0), 0.0) - 0.05
    hi = np.maximum(P.reshape(-1, 2).max(axis=0), 0.0) + 0.05
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.axhline(0, color="0.8", lw=0.5)
    ax.set_title(title, fontsize=8)
    ax.tick_params(labelsize=6)
