"""Chapter 3: point-to-point move with a trapezoidal velocity per joint (eq. 3-2..3-9).

Genes (thesis order) T11, T21, omega_1m: joint 1 accelerates for T11 up to omega_1m (its
cruise rate, rad/s, taken as a magnitude with the sign of the move), joint 2 for T21. Both joints
share the motion time T0 = T11 + |dtheta1| / omega_1m (from omega_1m = dtheta1/(T11 + T12) and
T0 = 2*T11 + T12, eq. 3-5); joint 2's cruise rate is dtheta2 / (T0 - T21) (eq. 3-9). Genes that
give a negative cruise time (T0 < 2*T11 or T0 < 2*T21) define no trapezoid and are invalid.
Acceleration jumps at every switching instant, so the peaks sit on the phase boundaries.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.families.base import TrajectoryFamily


class TrapezoidPtp(TrajectoryFamily):
    expected_genes = ("T11", "T21", "omega_1m")
    time_exponents = (1, 1, -1)

    def __init__(self, scenario) -> None:
        super().__init__(scenario)
        if len(scenario.task.points_m) != 2:
            raise QmtInputError(f"{scenario.source_path}: family trapezoid_ptp takes two task "
                                "points (start, goal)")
        if self.n_dof != 2:
            raise QmtInputError("trapezoid_ptp has genes for two joints; the arm has "
                                f"{self.n_dof}")
        self.q_start = self.joint_points[0]
        self.delta = self.joint_points[1] - self.joint_points[0]
        if abs(self.delta[0]) < 1e-9:
            raise QmtInputError("trapezoid_ptp: joint 1 does not move, so omega_1m cannot set T0")

    def motion_time_s(self, genes):
        g = np.atleast_2d(genes)
        return g[:, 0] + abs(self.delta[0]) / g[:, 2]

    def _accel_times(self, g):
        return g[:, 0], g[:, 1]

    def valid(self, genes):
        g = np.atleast_2d(genes)
        T0 = self.motion_time_s(g)
        return (T0 >= 2 * g[:, 0] - 1e-12) & (T0 >= 2 * g[:, 1] - 1e-12)

    def breakpoints_s(self, genes):
        g = np.atleast_2d(genes)
        T0 = self.motion_time_s(g)
        T11, T21 = g[:, 0], g[:, 1]
        bp = np.stack([np.zeros_like(T0), T11, T21, T0 - T21, T0 - T11, T0], axis=1)
        return np.sort(np.clip(bp, 0.0, T0[:, None]), axis=1)

    def cruise_rates(self, genes):
        """Signed cruise rate of each joint, rad/s, (K, 2)."""
        g = np.atleast_2d(genes)
        T0 = self.motion_time_s(g)
        accel = np.stack(self._accel_times(g), axis=1)
        return self.delta / (T0[:, None] - accel)

    def evaluate(self, genes, candidate, t_s, t_piece_s):
        g = np.atleast_2d(genes)
        T0 = self.motion_time_s(g)[candidate]
        Ta = np.stack(self._accel_times(g), axis=1)[candidate]  # (S, 2)
        w = self.cruise_rates(g)[candidate]  # (S, 2)
        q, qd, qdd = trapezoid_law(self.delta, Ta, T0[:, None], w, t_s[:, None], t_piece_s[:, None])
        return q + self.q_start, qd, qdd


def trapezoid_law(delta, Ta, T0, w, t, t_phase=None):
    """The chapter-3 trapezoidal velocity (eq. 3-2..3-9) of a rest-to-rest move by delta: (q - q_start,
    qd, qdd) at times t for accel/decel time Ta, motion time T0 and cruise rate w = delta / (T0 - Ta)
    (arrays broadcast together); t_phase (default t) picks the phase. Used by the planar trapezoid
    family and by the spatial joint-space PTP family."""
    t = np.asarray(t, float)
    tp = t if t_phase is None else np.asarray(t_phase, float)
    acc = tp < Ta
    dec = (tp > T0 - Ta) & (tp < T0)
    rest = tp >= T0
    u = T0 - t
    alpha = w / Ta
    q_acc = 0.5 * alpha * t**2
    q_cru = w * (t - 0.5 * Ta)
    q_dec = delta - 0.5 * alpha * u**2
    q = np.where(acc, q_acc, np.where(dec, q_dec, q_cru))
    qd = np.where(acc, alpha * t, np.where(dec, alpha * u, w))
    qdd = np.where(acc, alpha, np.where(dec, -alpha, 0.0))
    return np.where(rest, delta, q), np.where(rest, 0.0, qd), np.where(rest, 0.0, qdd)
