"""Matplotlib figures of plans (Agg backend; every function writes one PNG and returns its path).

The chapter studies use them for the counterparts of the thesis's figures: GA convergence
(Fig. 2.10, 3.9, 4.9), joint angles (Fig. 2.11 top), payload moment against its limit (Fig. 2.11
bottom, 3.10, 4.10), motor torques against theirs (Fig. 2.12, 3.10, 4.11) and the arm's loci
(Fig. 2.13, 3.11, 4.13).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from qmt_drake.outputs import atomic_output  # noqa: E402

STYLES = ["-", "--", ":", "-."]


def _save(fig, path: Path) -> Path:
    path = Path(path)
    fig.tight_layout()
    with atomic_output(path, suffix=".tmp.png") as tmp:  # unpredictable temporary name
        fig.savefig(path if tmp is None else tmp, dpi=110)  # None: a device node, written through
    plt.close(fig)
    return path


def _series(plan, rate_hz=2000.0):
    t = np.union1d(np.linspace(0, plan.motion_time_s, int(plan.motion_time_s * rate_hz) + 1),
                   plan.trajectory.breakpoints_s)
    # Sample just inside each piece so jumps show as vertical steps.
    t = np.clip(t, 0, plan.motion_time_s * (1 - 1e-9))
    q, qd, qdd = plan.sample(t)
    return t, q, qd, qdd


def convergence(histories: dict, path, *, thesis_T0=None, optimum_T0=None, title=""):
    """Best feasible motion time per generation for each GA run (`histories`: label -> list)."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for label, h in histories.items():
        ax.plot(np.arange(1, len(h) + 1), h, lw=1, label=label)
    if thesis_T0:
        ax.axhline(thesis_T0, color="k", ls="--", lw=1, label=f"thesis {thesis_T0:.3f} s")
    if optimum_T0:
        ax.axhline(optimum_T0, color="r", ls=":", lw=1.2, label=f"family optimum {optimum_T0:.4f} s")
    ax.set_xscale("log")
    ax.set_xlabel("generation")
    ax.set_ylabel("best feasible motion time T0 [s]")
    finite = [v for h in histories.values() for v in h if np.isfinite(v)]
    if finite and optimum_T0:
        ax.set_ylim(optimum_T0 * 0.995, min(max(finite), optimum_T0 * 1.25))
    ax.set_title(title or "GA convergence")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return _save(fig, path)


def joint_angles(plans: dict, path, title=""):
    fig, ax = plt.subplots(figsize=(7, 4))
    for k, (label, plan) in enumerate(plans.items()):
        t, q, _, _ = _series(plan)
        for j in range(q.shape[1]):
            ax.plot(t, np.degrees(q[:, j]), STYLES[k % 4], color=f"C{j}",
                    label=f"{label}: joint {j + 1}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("joint angle [deg]")
    ax.set_title(title or "joint angles")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, path)


def _moment_Nm(scenario, q, qd, qdd):
    return scenario.limit_set.term("payload_moment").moment_Nm(scenario.arm.hand_state(q, qd, qdd))


def moment(plans: dict, path, title=""):
    fig, ax = plt.subplots(figsize=(7, 4))
    limit = None
    for k, (label, plan) in enumerate(plans.items()):
        t, q, qd, qdd = _series(plan)
        m = _moment_Nm(plan.scenario, q, qd, qdd)
        limit = plan.scenario.limits.moment_limit_Nm
        ax.plot(t, m * 1e3, STYLES[k % 4], color=f"C{k}",
                label=f"{label} (T0 {plan.motion_time_s:.3f} s, peak {plan.check.peak_moment_ratio:.4f})")
    ax.axhline(limit * 1e3, color="r", ls="--", lw=1, label="limit")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("payload moment |tau_M| [mNm]")
    ax.set_title(title or "payload moment against its limit")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="center", framealpha=0.9)
    return _save(fig, path)


def motor_torques(plans: dict, path, title=""):
    first = next(iter(plans.values()))
    n = first.n_dof
    fig, axes = plt.subplots(n, 1, figsize=(7, 2.2 * n), sharex=True)
    for k, (label, plan) in enumerate(plans.items()):
        t, q, qd, qdd = _series(plan)
        tau = plan.scenario.arm.motor_torque(q, qd, qdd)
        for j in range(n):
            axes[j].plot(t, tau[:, j] * 1e3, STYLES[k % 4], color=f"C{k}", label=label)
    for j in range(n):
        lim = first.scenario.limits.motor_torque_limit_Nm[j] * 1e3
        peak = max(abs(p.check.peak_motor_torque_Nm[j]) for p in plans.values()) * 1e3
        axes[j].axhline(lim, color="r", ls="--", lw=1)
        axes[j].axhline(-lim, color="r", ls="--", lw=1)
        axes[j].set_ylim(-1.3 * peak, 1.3 * peak)
        axes[j].set_ylabel(f"motor {j + 1} [mNm]")
        axes[j].text(0.99, 0.95, f"limit +-{lim:.3g} mNm (off scale)" if lim > 1.3 * peak else
                     f"limit +-{lim:.3g} mNm", transform=axes[j].transAxes, ha="right",
                     va="top", fontsize=7, color="r")
        axes[j].grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title or "motor torques (joint torque / N)", fontsize=10)
    return _save(fig, path)


def loci(plan, path, title="", frames: int = 12):
    """Stick figures of the arm at equal time steps and the hand's path, seen from above."""
    arm = plan.scenario.arm
    t, q, _, _ = _series(plan)
    fig, ax = plt.subplots(figsize=(6, 5))
    tip = arm.tip_position(q)
    ax.plot(tip[:, 0], tip[:, 1], "k-", lw=1.5, label="hand path")
    for k, i in enumerate(np.linspace(0, len(t) - 1, frames).astype(int)):
        pts = arm.planar.joint_positions(q[i])
        ax.plot(pts[:, 0], pts[:, 1], "o-", color=plt.cm.viridis(k / (frames - 1)), lw=1.2,
                ms=3, alpha=0.8)
    pts = plan.scenario.task.points_m
    ax.plot(pts[:, 0], pts[:, 1], "rs", ms=5, label="task points")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title or "loci of the arm (colour: time)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, path)
