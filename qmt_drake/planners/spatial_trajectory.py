"""Joint trajectories of a spatial scenario, their sampled limit check, time scaling and pose check.

Every trajectory is a qmt_drake.trajectory.JointTrajectory (one protocol with the planar ones: duration_s,
n_dof, breakpoints_s, evaluate(t, t_piece), `sample(t) -> (q, qd, qdd)` ((S, n) arrays for (S,) times in
s), sampling clipped into [0, T]: holds_end_value). The kinds: `ToppraTrajectory` (a path q(s) with
TOPP-RA's constant-s-ddot profile on its grid), `SequenceTrajectory` (trajectories one after another),
`PolyTrajectory(pp)` (trajectory.PolynomialTrajectory of a Drake trajectory in time: a via-point cubic
PiecewisePolynomial, trajopt's BsplineTrajectory; the name stays for callers), `RuckigTrajectory` (Ruckig
segments, each from rest to rest), planners/spatial_families.SegmentTrajectory. `TimeScaled(traj, k)` plays
one k times slower: q(t / k), qd / k, qdd / k^2 (positions, hence every task pose, unchanged).
TimeScaled and SequenceTrajectory are qmt_drake.trajectory's TimeScaledTrajectory and
ConcatenatedTrajectory (one implementation for planar and spatial trajectories; the names stay).

`check(sc, traj, rate_hz)` samples at rate_hz (and both ends) and returns the largest ratio of every
limit: joint speed, joint acceleration, joint torque (through the scenario's SpatialChain: gravity,
the carried part, reflected rotor inertia), the hand's term (limits/suction.py, ...), the joint range;
1 = on the limit; with refine=True (the re-check of every plan) the local maxima between the samples
refined as the planar re-check does (limits/spatial_columns.py, limits/refine.py), and the binding
column named.
`between_pieces(sc, traj, rate_hz)` re-checks any trajectory on its own pieces (its breakpoints_s, through
its evaluate: the planar re-check's way): each piece sampled with both ends (one-sided) and refined
inside, so a column that jumps at a breakpoint (TOPP-RA's s-ddot at its grid points, where it holds its
rows only; a time law's phase switch; a Ruckig jerk switch) or kinks there (a path's knots) is seen.
`scale_to_hold(sc, traj, rate_hz)` returns the trajectory itself when every ratio is <= 1, else the
smallest time scale k > 1 (bisection to a relative 1e-4, k then rounded up) for which the sampled
check holds (with refine=True: the refined check, then `between_pieces`).
`pose_errors(sc, traj, times)` measures, with Drake's forward kinematics, how far the hand is from each
task pose (position, and face normal or rotation) at the given times (m, rad).
"""

from __future__ import annotations

import numpy as np

from qmt_drake.budgets import MEMORY_BUDGET_BYTES, TIME_BUDGET_S, check_rate_estimate
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.refine import REFINE_NEAR_LIMIT, peaks_on_pieces
from qmt_drake.limits.spatial_columns import (
    SPATIAL_RELATIVE_MARGIN,
    TIMED_GROUPS_EXCLUDE,
    SpatialColumns,
    binding,
    peaks,
)
from qmt_drake.planners.ruckig_core import RuckigProfile
from qmt_drake.planners.spatial_toppra import DrakePath
from qmt_drake.timescale import Grow, search_scale, smallest_holding_scale
from qmt_drake.trajectory import (
    ConcatenatedTrajectory,
    JointTrajectory,
    PolynomialTrajectory,
    TimeScaledTrajectory,
)

SequenceTrajectory = ConcatenatedTrajectory  # `t_start`: ConcatenatedTrajectory.offsets
TimeScaled = TimeScaledTrajectory  # `k`: TimeScaledTrajectory.factor


def PolyTrajectory(pp) -> PolynomialTrajectory:  # noqa: N802 - the old class's name, for callers
    """A spatial trajectory of a Drake trajectory in time (PiecewisePolynomial or BsplineTrajectory): the one
    PolynomialTrajectory, sampling clipped into [0, T] (holds_end_value)."""
    return PolynomialTrajectory(pp, holds_end_value=True)


class ToppraTrajectory(JointTrajectory):
    """A path q(s) (a Drake PiecewisePolynomial in s) played with TOPP-RA's profile: s-dot `sd` at the `grid`
    points, s-ddot constant between them. breakpoints_s: the times of its pieces (`pieces`)."""

    holds_end_value = True

    def __init__(self, pp, grid, sd) -> None:
        self.path = DrakePath(pp)
        self.grid, self.sd = np.asarray(grid, float), np.asarray(sd, float)
        ds = np.diff(self.grid)
        self.u = (self.sd[1:] ** 2 - self.sd[:-1] ** 2) / (2.0 * ds)
        self.t_grid = np.r_[0.0, np.cumsum(2.0 * ds / (self.sd[:-1] + self.sd[1:]))]
        self.duration_s = float(self.t_grid[-1])
        self.n_dof = self.path.dof
        self._pieces = None

    @property
    def breakpoints_s(self) -> np.ndarray:
        return self.pieces()[0]

    def sample(self, t):
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.duration_s)
        i = np.clip(np.searchsorted(self.t_grid, t, side="right") - 1, 0, len(self.u) - 1)
        tau = t - self.t_grid[i]
        s = np.minimum(self.grid[i] + self.sd[i] * tau + 0.5 * self.u[i] * tau ** 2, self.grid[-1])
        sd = np.maximum(self.sd[i] + self.u[i] * tau, 0.0)
        q, qs, qss = self.path(s, 0), self.path(s, 1), self.path(s, 2)
        return q, qs * sd[:, None], qs * self.u[i][:, None] + qss * (sd ** 2)[:, None]

    def time_at(self, s) -> np.ndarray:
        """Times (s) at which the profile passes path positions s."""
        s = np.atleast_1d(np.asarray(s, float))
        i = np.clip(np.searchsorted(self.grid, s, side="right") - 1, 0, len(self.u) - 1)
        d = s - self.grid[i]
        v = np.sqrt(np.maximum(self.sd[i] ** 2 + 2.0 * self.u[i] * d, 0.0))
        return self.t_grid[i] + 2.0 * d / np.maximum(self.sd[i] + v, 1e-300)

    def pieces(self):
        """(times (P,), path positions (P,)) of the pieces on which every limit column is smooth: the grid
        points (s-ddot jumps there) and the path's knots (its third derivative jumps there, so a column
        kinks; a C1 path's second derivative jumps). TOPP-RA holds its rows at the grid points only."""
        if self._pieces is None:
            knots = np.asarray(self.path.pp.get_segment_times(), float)
            inner = knots[(knots > self.grid[0]) & (knots < self.grid[-1]) & ~np.isin(knots, self.grid)]
            s = np.concatenate([self.grid, inner])
            t = np.concatenate([self.t_grid, self.time_at(inner)])
            order = np.argsort(s, kind="stable")
            self._pieces = (np.maximum.accumulate(t[order]), s[order])
        return self._pieces

    def evaluate(self, t, t_piece):
        """q, qd, qdd at times t (s) with the formulas of the piece holding t_piece (one-sided at a grid
        point or knot: the path is evaluated inside the piece's [s_a, s_b)); at rest (t_piece >= T) the end."""
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.duration_s)
        rest = np.broadcast_to(np.asarray(t_piece, float), t.shape) >= self.duration_s
        tp = np.clip(np.broadcast_to(np.asarray(t_piece, float), t.shape), 0.0, self.duration_s)
        bt, bs = self.pieces()
        j = np.clip(np.searchsorted(bt, tp, side="right") - 1, 0, len(bt) - 2)
        i = np.clip(np.searchsorted(self.t_grid, tp, side="right") - 1, 0, len(self.u) - 1)
        tau = t - self.t_grid[i]
        s = np.clip(self.grid[i] + self.sd[i] * tau + 0.5 * self.u[i] * tau ** 2, bs[j], np.nextafter(bs[j + 1], -np.inf))
        s = np.where(rest, self.grid[-1], s)
        sd = np.where(rest, 0.0, np.maximum(self.sd[i] + self.u[i] * tau, 0.0))
        u = np.where(rest, 0.0, self.u[i])
        q, qs, qss = self.path(s, 0), self.path(s, 1), self.path(s, 2)
        return q, qs * sd[:, None], qs * u[:, None] + qss * (sd ** 2)[:, None]


class _RuckigSegment(JointTrajectory):
    """One Ruckig trajectory (from rest to rest) through the one evaluator (planners/ruckig_core.RuckigProfile:
    Ruckig's at_time, vectorised); breakpoints_s: every joint's phase switches (its jerk jumps there, its
    acceleration kinks); evaluate: JointTrajectory's, through sample()."""

    holds_end_value = True

    def __init__(self, segment) -> None:
        self.segment = segment
        self.profile = RuckigProfile(segment)
        self.duration_s = self.profile.duration_s
        self.n_dof = self.profile.n
        self.breakpoints_s = self.profile.switch_times_s

    def sample(self, t):
        return self.profile.evaluate(t)


class RuckigTrajectory(SequenceTrajectory):
    """Ruckig trajectories played one after another (each segment from rest to rest); `segments`
    Ruckig's own."""

    def __init__(self, segments) -> None:
        self.segments = list(segments)
        super().__init__([_RuckigSegment(s) for s in self.segments])


def sample_times(duration_s: float, rate_hz: float) -> np.ndarray:
    n = max(int(np.ceil(duration_s * rate_hz)), 1)
    return np.linspace(0.0, duration_s, n + 1)


NOT_RATIOS = ("max", "max_timed", "n_samples", "binding", "binding_time_s", "refined_local_maxima")


def ratios_of(result: dict) -> dict:
    """The ratio entries of a `check` result (limit name -> peak / limit)."""
    return {k: v for k, v in result.items() if k not in NOT_RATIOS}


def check(sc, traj, rate_hz: float, terms=None, *, refine: bool = False) -> dict:
    """Largest ratio of every limit over the samples (module docstring; limits/spatial_columns.py:
    joint speed, acceleration, the terms, the joint range), with `refine` the local maxima between
    the samples refined (limits/refine.py, as the planar re-check); 'max' the largest of all,
    'max_timed' the largest of those a time scaling changes (all but the joint range), 'binding' the
    largest column ('motor_torque[shoulder_lift_joint]', 'suction', 'joint_range[elbow_joint]', ...)
    and 'binding_time_s' its time."""
    # a limit set far too tight (a joint speed of 1e-9 rad/s) times a path in decades: its samples would not fit
    est = check_rate_estimate(rate_hz, traj.duration_s, sc.n_dof, "the re-check")
    if not (est.bytes <= MEMORY_BUDGET_BYTES and est.seconds <= TIME_BUDGET_S):
        raise QmtInputError(f"{sc.name}: the timed path takes {traj.duration_s:.4g} s, and {est.what} needs "
                            f"{est.describe()}; a limit of the scenario is far too small for the task: check "
                            "actuators' velocity, acceleration, jerk and torque limits")
    t = sample_times(traj.duration_s, rate_hz)
    cols = SpatialColumns(sc, terms)
    peak, t_peak, refined = peaks(cols, traj, t, refine)
    out = {name: float(peak[cols.slices[name]].max()) for name, _ in cols.groups}
    timed = [v for k, v in out.items() if k not in TIMED_GROUPS_EXCLUDE]
    b = binding(cols, peak, t_peak)
    out["max"] = max(out.values())
    out["max_timed"] = max(timed)
    out["n_samples"] = int(len(t))
    out["binding"], out["binding_time_s"] = b["column"], b["time_s"]
    out["refined_local_maxima"] = int(refined)
    return out


def between_pieces(sc, traj, rate_hz: float) -> dict | None:
    """The re-check of a trajectory on its own pieces (its breakpoints_s: for TOPP-RA the grid points and the
    path's knots, where a column jumps or kinks), as the planar LimitSet.report does: every piece sampled at
    rate_hz and at both its ends (one-sided, through its evaluate), the local maxima refined inside each
    piece (limits/refine.py); {'max_timed', 'binding', 'binding_time_s', 'n_samples'}, or None for an object
    that only samples. Sampling across a jump or kink, the re-check's refinement brackets a maximum that is
    not smooth there and can miss it (TALOS's arm: 1.0008 of an acceleration limit between samples of a
    TOPP-RA plan re-checked at 0.9999)."""
    if not isinstance(traj, JointTrajectory):
        return None
    cols = SpatialColumns(sc)
    near = np.full(cols.n_columns, REFINE_NEAR_LIMIT)
    peak, t_peak, _, grid = peaks_on_pieces(cols.columns, traj, rate_hz, near, relative_margin=SPATIAL_RELATIVE_MARGIN,
                                            skip_flat=True)
    timed = np.array([g not in TIMED_GROUPS_EXCLUDE for g, _ in cols.column_labels])
    b = binding(cols, np.where(timed, peak, -np.inf), t_peak)
    return {"max_timed": b["ratio"], "binding": b["column"], "binding_time_s": b["time_s"], "n_samples": int(grid.t_s.size)}


def _held(sc, traj, k, rate_hz, refine):
    return check(sc, traj if k == 1.0 else TimeScaled(traj, k), rate_hz, refine=refine)["max_timed"] <= 1.0


def scale_to_hold(sc, traj, rate_hz: float, *, k_max: float = 20.0, rel_tol: float = 1e-4, refine: bool = False):
    """(trajectory, k): traj itself (k = 1) if its check holds, else TimeScaled(traj, k) with the
    smallest k (to 1e-4 relative) whose check holds. Only the limits a time scaling changes decide
    (a joint outside its range stays outside; the re-check reports it). With `refine` the k found on
    the samples is then checked with the local maxima refined between them and, where a maximum
    between samples still breaks a limit, raised until the refined check holds too (the k of a plan
    that holds between its samples is the sampled one, unchanged); then raised the same way until it also holds
    on its own pieces (`between_pieces`: a column jumps or kinks at a breakpoint, e.g. TOPP-RA holds its rows
    at its grid points only, where the refinement between samples can miss a maximum)."""
    k = 1.0
    if not _held(sc, traj, 1.0, rate_hz, False):
        if not _held(sc, traj, k_max, rate_hz, False):
            worst = ratios_of(check(sc, TimeScaled(traj, k_max), rate_hz))
            worst.pop(TIMED_GROUPS_EXCLUDE[0], None)
            name = max(worst, key=worst.get)
            raise QmtInputError(f"the trajectory breaks its {name} limit (ratio {worst[name]:.3g}) even {k_max:g} times "
                                "slower, where speed no longer matters (e.g. gravity on a tilted hand); relax that limit "
                                "or keep the hand closer to the task's orientation")
        k = smallest_holding_scale(1.0, k_max, lambda m: _held(sc, traj, m, rate_hz, False), rel_tol)
    if refine:
        k = _raised_until(k, lambda m: _held(sc, traj, m, rate_hz, True), k_max, rel_tol)
        k = _raised_until(k, lambda m: _held_on_pieces(sc, traj, m, rate_hz), k_max, rel_tol)
    return (traj, 1.0) if k == 1.0 else (TimeScaled(traj, k), k)


def _held_on_pieces(sc, traj, k, rate_hz) -> bool:
    """True if the trajectory k times slower holds on its own pieces (`between_pieces`; True for an object that
    only samples)."""
    r = between_pieces(sc, traj if k == 1.0 else TimeScaled(traj, k), rate_hz)
    return r is None or r["max_timed"] <= 1.0


def _raised_until(k: float, holds, k_max: float, rel_tol: float) -> float:
    """k itself if holds(k), else the smallest scale above k (to rel_tol) that holds: bracketed upwards from
    k by 16 rel_tol, then 10 % steps up to k_max, then bisected (timescale.search_scale)."""
    found = search_scale(holds, k, k_max, rel_tol=rel_tol, ends=("lo",),
                         grow=Grow(start=k, first=min(k * (1.0 + 16.0 * rel_tol), k_max), factor=1.1, limit=k_max))
    if found.status == "capped":
        raise QmtInputError(f"the trajectory breaks a limit between its samples even {k_max:g} times slower; "
                            "relax that limit")
    return found.holding


def pose_errors(sc, traj, times_s) -> np.ndarray:
    """(K, 2) Drake-FK (position m, face-normal angle rad) errors to the task poses at times_s."""
    q, _, _ = traj.sample(np.asarray(times_s, float))
    return np.array([sc.ik.errors(qk, p, **sc.pose_target(k)) for k, (qk, p) in enumerate(zip(q, sc.poses_m))])
