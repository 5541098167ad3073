"""Chapter 2: straight tip line with a cubic-velocity accel/decel profile (eq. 2-10..2-22).

The tip moves from the start point to the goal point along the segment between them (length
L = l_o); the tool angle stays at the scenario's `tool_angle_rad` for a 3-joint arm. With genes
T1 (accel time = decel time) and T2 (cruise time), T0 = 2*T1 + T2, the path coordinate is

    0 <= t <= T1:         s = k*(2*T1*t^3 - t^4)                       (eq. 2-10)
    T1 <= t <= T1 + T2:   s = s(T1) + v_max*(t - T1),  v_max = 2*k*T1^3  (eq. 2-11)
    T1 + T2 <= t <= T0:   s = L - k*(2*T1*u^3 - u^4),  u = T0 - t       (eq. 2-12)

with k = L / (2*T1^3*(T1 + T2)) (eq. 2-14). The tip acceleration is zero at t = 0, T1, T1+T2 and
T0 and peaks at 3*L/(2*T1*(T1+T2)) at t = T1/2 (eq. 2-25). Joint motion follows from analytic IK
and the Jacobian (eq. 2-15..2-19).
"""

from __future__ import annotations

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.families.base import TrajectoryFamily


class LineCubicVelocity(TrajectoryFamily):
    expected_genes = ("T1", "T2")

    def __init__(self, scenario) -> None:
        super().__init__(scenario)
        pts = scenario.task.points_m
        if len(pts) != 2:
            raise QmtInputError(f"{scenario.source_path}: family line_cubic_velocity takes exactly "
                                f"two task points (start, goal), got {len(pts)}")
        self.start_m = pts[0]
        delta = pts[1] - pts[0]
        self.length_m = float(np.hypot(*delta))
        if self.length_m <= 0:
            raise QmtInputError(f"{scenario.source_path}: start and goal points coincide")
        self.direction = delta / self.length_m
        self.tool_angle_rad = scenario.task.tool_angle_rad
        # The whole line must be reachable on the chosen branch and inside the joint ranges.
        s = np.linspace(0.0, self.length_m, 201)
        q = self._ik(self.start_m + s[:, None] * self.direction, check=False)
        self.arm.check_joint_range(q, what="the straight line between start and goal")
        self._check_branch_continuity(q)

    def _check_branch_continuity(self, q: np.ndarray) -> None:
        if np.any(np.abs(np.diff(q, axis=0)) > 0.5):
            raise QmtInputError("the IK solution jumps along the line (it passes a singularity or "
                                "wraps past +-pi); choose other points or the other ik_branch")

    def _ik(self, xy, check: bool = True):
        return self.arm.inverse_kinematics(xy, self.tool_angle_rad, self.scenario.task.ik_branch,
                                           check_range=check, what="line point")

    def motion_time_s(self, genes):
        g = np.atleast_2d(genes)
        return 2 * g[:, 0] + g[:, 1]

    def breakpoints_s(self, genes):
        g = np.atleast_2d(genes)
        T1, T2 = g[:, 0], g[:, 1]
        return np.stack([np.zeros_like(T1), T1, T1 + T2, 2 * T1 + T2], axis=1)

    def path_coordinate(self, T1, T2, t, t_piece):
        """s, s_dot, s_ddot along the line (m, m/s, m/s^2) for per-sample T1, T2."""
        return cubic_velocity_law(self.length_m, T1, T2, t, t_piece)

    def evaluate(self, genes, candidate, t_s, t_piece_s):
        g = np.atleast_2d(genes)
        T1, T2 = g[candidate, 0], g[candidate, 1]
        s, v, a = self.path_coordinate(T1, T2, t_s, t_piece_s)
        # With the tool angle fixed, the joints follow from IK and the augmented Jacobian
        # (eq. 2-15..2-19), the one mapping every straight-line planner shares.
        return self.arm.joint_motion_on_tip_path(self.start_m + s[:, None] * self.direction,
                                                 v[:, None] * self.direction, a[:, None] * self.direction,
                                                 self.tool_angle_rad, self.scenario.task.ik_branch)


def cubic_velocity_law(L, T1, T2, t, t_phase=None):
    """The chapter-2 time law (eq. 2-10..2-12) of a rest-to-rest move over a distance L: (s, s_dot,
    s_ddot) at times t (s) for per-sample accel/decel time T1 and cruise time T2 (arrays broadcast
    with t); t_phase (default t) picks the phase, so a caller can pass the times its pieces start at.
    Used by the planar line family and by the spatial Cartesian-line and joint families."""
    t = np.asarray(t, float)
    t_piece = t if t_phase is None else np.asarray(t_phase, float)
    T1, T2, L = (np.broadcast_to(np.asarray(x, float), t.shape) for x in (T1, T2, L))
    T0 = 2 * T1 + T2
    k = L / (2 * T1**3 * (T1 + T2))
    vmax = 2 * k * T1**3
    s_acc_end = k * T1**4
    s = np.empty_like(t)
    v = np.empty_like(t)
    a = np.empty_like(t)
    acc = t_piece < T1
    dec = (t_piece > T1 + T2) & (t_piece < T0)
    cru = ~acc & ~dec & (t_piece < T0)
    rest = t_piece >= T0
    tt = t[acc]
    kk, T1a = k[acc], T1[acc]
    s[acc] = kk * (2 * T1a * tt**3 - tt**4)
    v[acc] = kk * (6 * T1a * tt**2 - 4 * tt**3)
    a[acc] = kk * (12 * T1a * tt - 12 * tt**2)
    s[cru] = s_acc_end[cru] + vmax[cru] * (t[cru] - T1[cru])
    v[cru] = vmax[cru]
    a[cru] = 0.0
    u = T0[dec] - t[dec]
    kk, T1d = k[dec], T1[dec]
    s[dec] = L[dec] - kk * (2 * T1d * u**3 - u**4)
    v[dec] = kk * (6 * T1d * u**2 - 4 * u**3)
    a[dec] = -kk * (12 * T1d * u - 12 * u**2)
    s[rest], v[rest], a[rest] = L[rest], 0.0, 0.0
    return s, v, a
