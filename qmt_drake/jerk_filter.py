"""TOPP-RA's path timing seen through moving averages: a jerk-limited timing of the same path.

TOPP-RA's profile s(t) on a path q(s) is piecewise quadratic in t (s-ddot `u` constant per grid interval),
so its acceleration steps and its jerk is unbounded. `FilteredTiming(base, windows_s)` plays the path with
that timing seen through one or two moving averages (box FIRs of widths w1, w2 in series), s held at its
start before 0 and at its end L after T. One box:

    s_f(t)    = (1/w) * integral_{t-w}^{t} s(x) dx = (S(t) - S(t-w)) / w
    s_f'(t)   = (s(t) - s(t-w)) / w
    s_f''(t)  = (sd(t) - sd(t-w)) / w
    s_f'''(t) = (u(t) - u(t-w)) / w

and a second box takes the same window difference again (of S's antiderivative for the position, of sd
for the jerk, over w1 w2). S and its antiderivative, of the piecewise quadratic s, are piecewise cubic and
quartic, so every derivative is exact in closed form (no resampling). The timing is rest to rest, reaches
L at T + w1 + w2, and its s-jerk is bounded (one box: the largest s-ddot difference across a window over
w; two: continuous). On a C2 path the joint jerk

    q''' = q_s s_f''' + 3 q_ss s_f' s_f'' + q_sss s_f'^3

is then bounded too (`jerk(t)`), smooth between `breakpoints_s`: the base's grid times shifted by every
sum of windows (where s_f''' jumps or kinks) and the times the filtered timing passes the path's knots
(where q_sss jumps). The path is unchanged, so every task pose is still passed (`time_at`). The filter
averages (s_f'', s_f'^2) over the window while the limits depend on s, so a limit the base rides can be
exceeded slightly; the plan is re-checked and slowed (jerk.py). Its file form: the base TOPP-RA timing's
and the windows (`{"kind": "filtered_toppra", "base": {toppra}, "windows_s": [w1, ...]}`,
planners/spatial_plan_io.py, plan_files.REBUILD_MODULES).

(sim/spatial_reference.BoxShapedReference averages joint positions for a servo's reference: it cuts the
path's corners; this averages the path position, so the hand stays on the path.)
"""

from __future__ import annotations

import numpy as np

from qmt_drake.plan_files import register_rebuild
from qmt_drake.planners.spatial_plan_io import trajectory_from_spec, trajectory_spec
from qmt_drake.planners.spatial_trajectory import TimeScaled, ToppraTrajectory
from qmt_drake.trajectory import ONE_SIDED_S, JointTrajectory

MAX_BOXES = 2  # the base's antiderivatives are kept to the second
TIME_AT_TOL = 1e-12  # path units: time_at's s_f(t) - s (on a path a few rad long; FK measures the poses)
TIME_AT_ITERATIONS = 100  # at most, in time_at (Newton converges in a few; bisection halves a bracket to rounding)


class FilteredTiming(JointTrajectory):
    """`base` (a ToppraTrajectory) with its path timing box-filtered over each of windows_s [s] in series
    (module docstring); duration_s = base's + the windows' sum."""

    holds_end_value = True  # a JointTrajectory that samples itself (qmt_drake/trajectory.py)

    def __init__(self, base: ToppraTrajectory, windows_s) -> None:
        w = np.atleast_1d(np.asarray(windows_s, float))
        if not (isinstance(base, ToppraTrajectory) and w.ndim == 1 and 1 <= w.size <= MAX_BOXES
                and np.all(np.isfinite(w)) and np.all(w > 0)):
            raise ValueError(f"a filtered timing needs a TOPP-RA trajectory and 1 to {MAX_BOXES} positive windows")
        self.base, self.windows_s = base, tuple(float(x) for x in w)
        self.path, self.n_dof = base.path, base.n_dof
        self.duration_s = base.duration_s + float(sum(self.windows_s))
        self._sss = base.path.pp.derivative(3)
        s, v, a = base.grid, base.sd, base.u
        d = np.diff(base.t_grid)
        S = np.r_[0.0, np.cumsum(s[:-1] * d + v[:-1] * d ** 2 / 2 + a * d ** 3 / 6)]  # integral_0^t_i s
        SS = np.r_[0.0, np.cumsum(S[:-1] * d + s[:-1] * d ** 2 / 2 + v[:-1] * d ** 3 / 6 + a * d ** 4 / 24)]
        self._S, self._SS = S, SS
        n = len(self.windows_s)  # the window difference: the base at t minus every sum of windows, signed
        self._shifts = [(sum(self.windows_s[k] for k in range(n) if m >> k & 1), (-1) ** bin(m).count("1"))
                        for m in range(2 ** n)]
        self._breakpoints: np.ndarray | None = None

    def _base(self, t) -> np.ndarray:
        """(5, len(t)): the base's integral_0^t S, S = integral_0^t s, s, sd, u at times t (any real t: at
        rest outside [0, T], s held at its start before 0 and at its end L after T)."""
        b = self.base
        T, L, s0 = b.duration_s, b.grid[-1], b.grid[0]
        tc = np.clip(t, 0.0, T)
        i = np.clip(np.searchsorted(b.t_grid, tc, side="right") - 1, 0, len(b.u) - 1)
        x, si, vi, ai = tc - b.t_grid[i], b.grid[i], b.sd[i], b.u[i]
        inside = (t >= 0.0) & (t < T)
        s = np.where(t < 0.0, s0, np.where(t >= T, L, np.minimum(si + vi * x + ai * x ** 2 / 2, L)))
        sd = np.where(inside, np.maximum(vi + ai * x, 0.0), 0.0)
        u = np.where(inside, ai, 0.0)
        S = self._S[i] + si * x + vi * x ** 2 / 2 + ai * x ** 3 / 6
        SS = self._SS[i] + self._S[i] * x + si * x ** 2 / 2 + vi * x ** 3 / 6 + ai * x ** 4 / 24
        before, after = np.minimum(t, 0.0), np.maximum(t - T, 0.0)
        SS = SS + s0 * before ** 2 / 2 + S * after + L * after ** 2 / 2
        S = S + s0 * before + L * after
        return np.array([SS, S, s, sd, u])

    def base_position(self, t_s) -> np.ndarray:
        """The base timing's path position s at its own times t_s [s]."""
        return self._base(np.atleast_1d(np.asarray(t_s, float)))[2]

    def timing(self, t_s):
        """(s_f, s_f', s_f'', s_f''') at times t_s [s] (path units, per s, s^2, s^3): with n boxes the
        derivative of order m is the n-fold window difference of the base's order m - n over the windows'
        product."""
        t = np.clip(np.atleast_1d(np.asarray(t_s, float)), 0.0, self.duration_s)
        n = len(self.windows_s)
        out = sum(sign * self._base(t - shift) for shift, sign in self._shifts) / float(np.prod(self.windows_s))
        b = self.base
        return np.clip(out[2 - n], b.grid[0], b.grid[-1]), out[3 - n], out[4 - n], out[5 - n]

    def sample(self, t_s):
        s, v, a, _ = self.timing(t_s)
        qs, qss = self.path(s, 1), self.path(s, 2)
        return self.path(s, 0), qs * v[:, None], qs * a[:, None] + qss * (v ** 2)[:, None]

    def jerk(self, t_s) -> np.ndarray:
        """Joint jerk [rad/s^3] (len(t), n) at times t_s: q_s s''' + 3 q_ss s' s'' + q_sss s'^3."""
        s, v, a, j = self.timing(t_s)
        qsss = self._sss.vector_values(s).T
        return (self.path(s, 1) * j[:, None] + 3.0 * self.path(s, 2) * (v * a)[:, None]
                + qsss * (v ** 3)[:, None])

    def time_at(self, s) -> np.ndarray:
        """The times [s] at which the filtered timing reaches path positions s: s_f(t) lies between the base's
        s(t - sum of windows) and s(t), so t is bracketed by the base's time there and that plus the windows;
        safeguarded Newton (s_f' exact) inside the bracket, bisection where a step leaves it, to TIME_AT_TOL."""
        s = np.atleast_1d(np.asarray(s, float))
        lo = np.clip(self.base.time_at(s), 0.0, self.duration_s)
        hi = np.minimum(lo + sum(self.windows_s), self.duration_s)
        t = 0.5 * (lo + hi)
        for _ in range(TIME_AT_ITERATIONS):
            sf, v, _, _ = self.timing(t)
            f = sf - s
            lo, hi = np.where(f < 0.0, t, lo), np.where(f < 0.0, hi, t)
            newton = t - f / np.where(v > 0.0, v, np.inf)
            t = np.where((newton > lo) & (newton < hi), newton, 0.5 * (lo + hi))
            if np.all((hi - lo <= 4.0 * np.spacing(self.duration_s)) | (np.abs(f) <= TIME_AT_TOL)):
                break
        return np.where(s <= self.base.grid[0], 0.0, np.where(s >= self.base.grid[-1], self.duration_s, t))  # at rest

    @property
    def breakpoints_s(self) -> np.ndarray:
        if self._breakpoints is None:
            b = self.base
            knots = np.asarray(b.path.pp.get_segment_times(), float)
            inner = knots[(knots > b.grid[0]) & (knots < b.grid[-1])]
            t = np.r_[np.add.outer([x for x, _ in self._shifts], b.t_grid).ravel(), self.time_at(inner)]
            self._breakpoints = np.unique(np.clip(np.r_[0.0, t, self.duration_s], 0.0, self.duration_s))
        return self._breakpoints

    def file_spec(self) -> dict:
        """What rebuilds it exactly: the base TOPP-RA timing's spec and the windows."""
        return {"kind": "filtered_toppra", "base": trajectory_spec(self.base), "windows_s": list(self.windows_s)}


def filtered_from_file(spec: dict, scenario=None) -> FilteredTiming:
    """The FilteredTiming a `file_spec` describes (the same numbers, so the same values bit for bit)."""
    base = trajectory_from_spec(spec["base"])
    if not isinstance(base, ToppraTrajectory):
        raise ValueError("a filtered timing's base must be a TOPP-RA timing")
    return FilteredTiming(base, [float(w) for w in spec["windows_s"]])


def joint_jerk(traj, t_s) -> np.ndarray:
    """The exact joint jerk [rad/s^3] of a FilteredTiming, or of one played k times slower (/ k^3)."""
    if isinstance(traj, TimeScaled):
        return joint_jerk(traj.inner, np.asarray(t_s, float) / traj.k) / traj.k ** 3
    return traj.jerk(t_s)


def exact_peak_jerk(sc, traj, rate_hz: float) -> dict:
    """jerk.peak_jerk's keys from the exact jerk (joint_jerk) at rate_hz and on both sides of every breakpoint
    (it jumps there and is smooth between): the sampled jerk |qdd(t + h) - qdd(t)| / h, an average of it,
    stays within this at any rate."""
    T = traj.duration_s
    bp = np.asarray(traj.breakpoints_s, float)
    t = np.unique(np.clip(np.r_[np.linspace(0.0, T, max(int(np.ceil(T * rate_hz)), 2) + 1), bp - ONE_SIDED_S,
                                bp + ONE_SIDED_S], 0.0, T))
    j = np.abs(joint_jerk(traj, t)).max(axis=0)
    return {"peak_jerk_rad_s3": j, "peak_jerk_ratio": float(np.max(j / sc.jerk_limit_rad_s3)),
            "jerk_rate_hz": float(rate_hz)}


register_rebuild("filtered_toppra", filtered_from_file)
