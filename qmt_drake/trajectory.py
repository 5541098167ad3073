"""Joint trajectories as every planner returns them (planar and spatial), and their conversion to Drake.

One protocol for every trajectory of the package (tests/test_one_trajectory.py checks it over the source):
a JointTrajectory has `duration_s`, `n_dof`, `breakpoints_s` (sorted, from 0 to the duration: 0, the
instants where a limit column may jump or kink, and the duration), `evaluate(t_s, t_piece_s)` giving q,
qd, qdd with the formula of the piece that contains `t_piece_s` (so one-sided values at a boundary can be
asked for), and `sample(t_s)` -> q [rad], qd [rad/s], qdd [rad/s^2], each (len(t), n_dof). The one
re-check between samples (limits/refine.py) samples every piece with both ends through `evaluate` and
refines the local maxima inside each piece: the planar LimitSet.report and the spatial
spatial_trajectory.between_pieces both take `breakpoints_s` and `evaluate` of whatever kind they get.

`sample` has two conventions at and after the end (`holds_end_value`): the planar trajectories (False)
rest there (qd = qdd = 0 from T on); the spatial ones (True: TOPP-RA's profile, the via cubic, the
families' segments, Ruckig, an export stream) clip t into [0, T] and so give the last piece's value at T
(the stopping acceleration), which their sampled check needs. Both stay because published numbers read
them (measured in session 16): the spatial sampled check (planners/spatial_trajectory.check: the planners'
searches, scale_to_hold, each plan's columns) takes its end sample through sample(), and a family plan's
stop is a peak there (ur5-suction-bins' family_optimum plan ends at 9.57 rad/s^2; at rest its
joint_acceleration column would read 0.63712 instead of 0.63796, motor_torque 0.37092 instead of 0.37107);
the planar Plan.sample, CSV and goldens give rest at T (thesis-ch3/ch4's thesis plans would give their last
piece's 1.89 / 6.43 rad/s^2 there). One convention moves one set of goldens; the re-check between samples
(evaluate, one-sided by t_piece) is the same for both. TimeScaledTrajectory and
ConcatenatedTrajectory follow their parts (one implementation of time scaling and of playing
trajectories one after another for both; spatial_trajectory's TimeScaled and SequenceTrajectory are
these classes) and still take an object that only samples (duration_s, sample).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
import numpy.typing as npt
from pydrake.polynomial import Polynomial_
from pydrake.trajectories import PiecewisePolynomial

ONE_SIDED_S = 1e-9  # a breakpoint's one-sided value: evaluated this far inside the piece


def inside_piece(breakpoints_s, t_s, t_piece_s) -> np.ndarray:
    """t [s] moved at most ONE_SIDED_S inside the piece of `breakpoints_s` holding t_piece_s (one-sided
    values at a boundary for a formula that picks its piece by t itself)."""
    bp = np.asarray(breakpoints_s)
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    j = np.clip(np.searchsorted(bp, np.broadcast_to(t_piece_s, t.shape), side="right") - 1, 0, len(bp) - 2)
    return np.clip(t, bp[j] + ONE_SIDED_S, bp[j + 1] - ONE_SIDED_S)


class JointTrajectory:
    duration_s: float
    breakpoints_s: np.ndarray
    n_dof: int
    holds_end_value = False  # sample() at and after T: rest (False) or the last piece's value (module docstring)

    def evaluate(self, t_s, t_piece_s):
        """q, qd, qdd at times t_s with the formulas of the pieces holding t_piece_s; at rest (t_piece_s >= T)
        the end at rest. This default serves a trajectory that samples itself (holds_end_value): its
        sample() ONE_SIDED_S inside the piece (one-sided at a breakpoint); the others give their formulas."""
        if not self.holds_end_value:  # pragma: no cover - interface
            raise NotImplementedError
        t = np.atleast_1d(np.asarray(t_s, float))
        rest = np.broadcast_to(t_piece_s, t.shape) >= self.duration_s
        te = np.where(rest, self.duration_s, inside_piece(self.breakpoints_s, t, t_piece_s))
        q, qd, qdd = (np.array(a, dtype=float) for a in self.sample(te))
        qd[rest], qdd[rest] = 0.0, 0.0
        return q, qd, qdd

    def sample(self, t_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q [rad], qd [rad/s], qdd [rad/s^2], each (len(t), n), at times t [s] (right-continuous).
        Outside [0, duration] the arm holds its end states: q(0) before the start, q(T) after the
        end, with qd = qdd = 0 (never the pieces' polynomials extrapolated)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        bp = self.breakpoints_s
        outside = (t < bp[0]) | (t > bp[-1])
        tc = np.clip(t, bp[0], bp[-1])
        j = np.clip(np.searchsorted(bp, tc, side="right") - 1, 0, len(bp) - 2)
        mid = np.where(tc >= bp[-1], bp[-1] + 1.0, 0.5 * (bp[j] + bp[j + 1]))
        q, qd, qdd = self.evaluate(tc, mid)
        if outside.any():
            qd, qdd = np.array(qd, dtype=float, copy=True), np.array(qdd, dtype=float, copy=True)
            qd[outside] = 0.0
            qdd[outside] = 0.0
        return q, qd, qdd

    def to_piecewise_polynomial(self, rate_hz: float = 1000.0) -> PiecewisePolynomial:
        """Cubic Hermite interpolation of q through samples at rate_hz (and every breakpoint),
        with the exact qd at each sample: a Drake trajectory for TrajectorySource and friends."""
        t = np.union1d(np.linspace(0.0, self.duration_s,
                                   int(np.ceil(self.duration_s * rate_hz)) + 1), self.breakpoints_s)
        q, qd, _ = self.sample(t)
        # At the end point sample() gives the resting value; q is continuous there anyway.
        return PiecewisePolynomial.CubicHermite(t, q.T, qd.T)


class FamilyTrajectory(JointTrajectory):
    """One gene vector of a trajectory family (exact formulas)."""

    def __init__(self, family, genes) -> None:
        self.family = family
        self.genes = np.atleast_2d(np.asarray(genes, dtype=float))
        self.breakpoints_s = np.unique(family.breakpoints_s(self.genes)[0])
        self.duration_s = float(family.motion_time_s(self.genes)[0])
        self.n_dof = family.n_dof

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        return self.family.evaluate(self.genes, np.zeros(t.size, dtype=int), t,
                                    np.broadcast_to(t_piece_s, t.shape).astype(float))


def _segment_times(pp) -> np.ndarray:
    """A Drake trajectory's piece boundaries [s, its own time]: a PiecewisePolynomial's segment times, a
    B-spline's distinct knots."""
    if hasattr(pp, "get_segment_times"):
        return np.asarray(pp.get_segment_times(), dtype=float)
    return np.unique(np.asarray(pp.basis().knots(), dtype=float))


class PolynomialTrajectory(JointTrajectory):
    """A Drake trajectory of q in time (a PiecewisePolynomial: the via cubic, a stream's cubic Hermite; or
    trajopt's BsplineTrajectory), its derivatives giving qd, qdd; its start_time() is t = 0 here.
    `holds_end_value` (the spatial kind, spatial_trajectory.PolyTrajectory): sample() is the trajectory
    itself at t clipped into [0, T]; else the protocol's sample (resting after T)."""

    def __init__(self, pp, breakpoints_s=None, *, holds_end_value: bool = False) -> None:
        self.pp = pp
        self.pp_d = pp.MakeDerivative(1)  # the same values as PiecewisePolynomial.derivative
        self.pp_dd = pp.MakeDerivative(2)
        self.t0 = float(pp.start_time())
        self.duration_s = float(pp.end_time() - pp.start_time())
        self.n_dof = pp.rows()
        self.holds_end_value = bool(holds_end_value)
        bp = np.asarray(_segment_times(pp) - self.t0 if breakpoints_s is None else breakpoints_s)
        self.breakpoints_s = np.unique(np.clip(np.concatenate([[0.0, self.duration_s], bp]), 0.0, self.duration_s))

    def sample(self, t_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self.holds_end_value:
            return super().sample(t_s)
        t = self.t0 + np.clip(np.atleast_1d(np.asarray(t_s, float)), 0.0, self.duration_s)
        return tuple(d.vector_values(t).T for d in (self.pp, self.pp_d, self.pp_dd))

    def file_spec(self) -> dict | None:
        """What rebuilds it exactly (plan_files.rebuild_spec): a PiecewisePolynomial's coefficients; None for
        another Drake trajectory."""
        if not isinstance(self.pp, PiecewisePolynomial):
            return None
        return {"kind": "polynomial", "pp": polynomial_spec(self.pp), "breakpoints_s": self.breakpoints_s,
                "holds_end_value": self.holds_end_value}

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        tp = np.broadcast_to(t_piece_s, t.shape)
        rest = tp >= self.duration_s
        te = np.where(rest, self.duration_s, inside_piece(self.breakpoints_s, t, tp)) + self.t0
        q = self.pp.vector_values(te).T
        qd = np.where(rest[:, None], 0.0, self.pp_d.vector_values(te).T)
        qdd = np.where(rest[:, None], 0.0, self.pp_dd.vector_values(te).T)
        return q, qd, qdd


def polynomial_spec(p) -> dict:
    """A Drake PiecewisePolynomial's exact file form: its breaks and every segment's coefficients."""
    coefficients = [[[p.getPolynomial(i, r, c).GetCoefficients() for c in range(p.cols())] for r in range(p.rows())]
                    for i in range(p.get_number_of_segments())]
    return {"breaks": np.asarray(p.get_segment_times()), "coefficients": coefficients}


def polynomial_from_spec(spec: dict) -> PiecewisePolynomial:
    """The PiecewisePolynomial of `polynomial_spec` (the same coefficients, so the same values bit for bit)."""
    breaks = [float(b) for b in spec["breaks"]]
    mats = [np.array([[Polynomial_[float](np.asarray(c, dtype=float)) for c in row] for row in seg], dtype=object)
            for seg in spec["coefficients"]]
    if len(mats) != len(breaks) - 1 or not all(np.isfinite(breaks)):
        raise ValueError("a piecewise polynomial needs one coefficient block per interval between finite breaks")
    return PiecewisePolynomial(mats, breaks)


class SampledTrajectory(JointTrajectory):
    """A trajectory known by samples t, q, qd, qdd: what a plan file stores for planners without
    a closed form. Between samples it is the quintic Hermite interpolant (q, qd, qdd match at
    both ends), so acceleration is continuous between samples; a phase boundary is stored twice
    (its left and its right value), so jumps survive a save and load."""

    def __init__(self, t_s, q, qd, qdd, breakpoints_s=None) -> None:
        t = np.asarray(t_s, dtype=float)
        self.q, self.qd, self.qdd = (np.asarray(a, dtype=float) for a in (q, qd, qdd))
        keep = np.flatnonzero(np.diff(t) > 0)  # zero-length steps are the boundary duplicates
        self.left, self.right = keep, keep + 1
        self.start, self.end = t[keep], t[keep + 1]
        self.duration_s = float(t[-1] - t[0])
        self.n_dof = self.q.shape[1]
        bp = [t[0], t[-1]] if breakpoints_s is None else breakpoints_s
        self.breakpoints_s = np.unique(np.concatenate([[t[0], t[-1]], np.asarray(bp, float)]))

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        tp = np.broadcast_to(t_piece_s, t.shape)
        rest = tp >= self.duration_s
        # The sample interval: the one containing t, searched on the side t_piece lies.
        side_right = tp > t
        k = np.where(side_right, np.searchsorted(self.start, t, side="right") - 1,
                     np.searchsorted(self.end, t, side="left"))
        k = np.clip(k, 0, self.start.size - 1)
        k = np.where(rest, self.start.size - 1, k)
        h = (self.end - self.start)[k][:, None]
        u = np.clip((np.where(rest, self.end[k], t) - self.start[k])[:, None] / h, 0.0, 1.0)
        i0, i1 = self.left[k], self.right[k]
        p0, v0, a0 = self.q[i0], self.qd[i0] * h, self.qdd[i0] * h**2
        p1, v1, a1 = self.q[i1], self.qd[i1] * h, self.qdd[i1] * h**2
        # Quintic Hermite in u in [0, 1]: coefficients of p(u) = sum c_k u^k.
        c0, c1, c2 = p0, v0, a0 / 2
        c3 = 10 * (p1 - p0) - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1
        c4 = -15 * (p1 - p0) + 8 * v0 + 7 * v1 + 1.5 * a0 - a1
        c5 = 6 * (p1 - p0) - 3 * v0 - 3 * v1 - 0.5 * a0 + 0.5 * a1
        q = c0 + u * (c1 + u * (c2 + u * (c3 + u * (c4 + u * c5))))
        qd = (c1 + u * (2 * c2 + u * (3 * c3 + u * (4 * c4 + u * 5 * c5)))) / h
        qdd = (2 * c2 + u * (6 * c3 + u * (12 * c4 + u * 20 * c5))) / h**2
        qd = np.where(rest[:, None], 0.0, qd)
        qdd = np.where(rest[:, None], 0.0, qdd)
        return q, qd, qdd


class CallableTrajectory(JointTrajectory):
    """A trajectory given by a function f(t, order) -> (len(t), n) (e.g. toppra's spline output);
    derivatives are continuous inside the given breakpoints."""

    def __init__(self, f, duration_s, breakpoints_s, n_dof) -> None:
        self.f = f
        self.duration_s = float(duration_s)
        self.breakpoints_s = np.unique(np.clip(np.concatenate(
            [[0.0, self.duration_s], breakpoints_s]), 0.0, self.duration_s))
        self.n_dof = n_dof

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        rest = np.broadcast_to(t_piece_s, t.shape) >= self.duration_s
        te = np.clip(t, 0.0, self.duration_s)
        q = self.f(te, 0)
        qd = np.where(rest[:, None], 0.0, self.f(te, 1))
        qdd = np.where(rest[:, None], 0.0, self.f(te, 2))
        return q, qd, qdd


def _own_sample(traj) -> bool:
    """True where a combinator samples through its part's sample() (a part that holds its end value, or
    an object that only samples), False where it evaluates the protocol's way (module docstring)."""
    return not isinstance(traj, JointTrajectory) or traj.holds_end_value


def _slowed(q, qd, qdd, k: float):
    """The values of q(t / k), from q's at t / k: a trajectory played k times slower."""
    return q, qd / k, qdd / k**2


class TimeScaledTrajectory(JointTrajectory):
    """`inner` played `factor` times slower: q(t) = q_in(t/factor) (every inertial ratio / factor^2);
    `k` is `factor`. inner: a JointTrajectory or a sampling-only one (module docstring)."""

    def __init__(self, inner, factor: float) -> None:
        if not factor > 0:
            raise ValueError("time scale must be positive")
        self.inner, self.factor = inner, float(factor)
        self.duration_s = inner.duration_s * self.factor
        self.holds_end_value = _own_sample(inner)
        if isinstance(inner, JointTrajectory):
            self.n_dof = inner.n_dof

    @cached_property
    def breakpoints_s(self) -> np.ndarray:
        """inner's, scaled; made on first use (a TOPP-RA profile finds its pieces lazily); none (AttributeError)
        for a sampling-only inner."""
        if not isinstance(self.inner, JointTrajectory):
            raise AttributeError("breakpoints_s: a sampling-only trajectory has none")
        return self.inner.breakpoints_s * self.factor

    @property
    def k(self) -> float:
        return self.factor

    def evaluate(self, t_s, t_piece_s):
        f = self.factor
        return _slowed(*self.inner.evaluate(np.asarray(t_s) / f, np.asarray(t_piece_s) / f), f)

    def sample(self, t_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self.holds_end_value:
            return super().sample(t_s)
        return _slowed(*self.inner.sample(np.asarray(t_s, float) / self.factor), self.factor)


class ConcatenatedTrajectory(JointTrajectory):
    """Trajectories played one after another, each ending at rest where the next starts (via points
    chained segment by segment; TOPP-RA or Ruckig per rest-to-rest segment); `offsets` (also
    `t_start`) their start times [s] and the end. parts: JointTrajectories or sampling-only ones."""

    def __init__(self, parts) -> None:
        self.parts = list(parts)
        self.offsets = np.concatenate([[0.0], np.cumsum([p.duration_s for p in self.parts])])
        self.duration_s = float(self.offsets[-1])
        self.holds_end_value = any(_own_sample(p) for p in self.parts)
        if all(isinstance(p, JointTrajectory) for p in self.parts):
            self.n_dof = self.parts[0].n_dof

    @cached_property
    def breakpoints_s(self) -> np.ndarray:
        """The parts' breakpoints, offset; made on first use; none (AttributeError) if a part only samples."""
        if not all(isinstance(p, JointTrajectory) for p in self.parts):
            raise AttributeError("breakpoints_s: a sampling-only part has none")
        return np.unique(np.concatenate([p.breakpoints_s + o for p, o in zip(self.parts, self.offsets[:-1])]))

    @property
    def t_start(self) -> np.ndarray:
        return self.offsets

    def sample(self, t_s: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self.holds_end_value:
            return super().sample(t_s)
        t = np.clip(np.atleast_1d(np.asarray(t_s, float)), 0.0, self.duration_s)
        k = np.clip(np.searchsorted(self.offsets, t, side="right") - 1, 0, len(self.parts) - 1)
        out = None
        for i, part in enumerate(self.parts):
            m = k == i
            if np.any(m):
                vals = part.sample(t[m] - self.offsets[i])
                if out is None:
                    out = [np.empty((len(t), v.shape[1])) for v in vals]
                for o, v in zip(out, vals):
                    o[m] = v
        return tuple(out)

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        tp = np.broadcast_to(t_piece_s, t.shape)
        k = np.clip(np.searchsorted(self.offsets, tp, side="right") - 1, 0, len(self.parts) - 1)
        n = self.n_dof
        q, qd, qdd = np.empty((t.size, n)), np.empty((t.size, n)), np.empty((t.size, n))
        for i, p in enumerate(self.parts):
            m = k == i
            if np.any(m):
                o = self.offsets[i]
                q[m], qd[m], qdd[m] = p.evaluate(t[m] - o, tp[m] - o)
        return q, qd, qdd


class RestTrajectory(JointTrajectory):
    """Holding q for `duration_s` (0 by default): the trajectory of a plan that found no motion."""

    def __init__(self, q, duration_s: float = 0.0) -> None:
        self.q = np.asarray(q, dtype=float)
        self.duration_s = float(duration_s)
        self.breakpoints_s = np.array([0.0, self.duration_s])
        self.n_dof = self.q.size

    def evaluate(self, t_s, t_piece_s):
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        q = np.broadcast_to(self.q, (t.size, self.n_dof)).copy()
        return q, np.zeros_like(q), np.zeros_like(q)


# ============================================================================ plans
