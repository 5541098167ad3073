"""Trajectory families of a spatial scenario: what the family optimum, the GA and TOPP-RA search over.

    via_cubic       the joint-space via-point cubic through the task poses (genes T1..T_m, the segment
                    times; the arm passes the inner poses without stopping)
    line_cubic_velocity
                    the hand on the straight line between neighbouring task poses, its face normal
                    (or, for a task of rotations, its rotation) slerped from one pose's to the next
                    (model/spatial_ik.slerp_unit, slerp_rotations); each segment from
                    rest to rest with the chapter-2 cubic-velocity time law (families/line.cubic_velocity_law;
                    genes per segment: T1 accel/decel time, T2 cruise time)
    trapezoid_ptp   joint-space point-to-point: the joints on the straight joint-space segment between
                    neighbouring task poses, synchronised, with the chapter-3 trapezoidal velocity
                    (families/trapezoid.trapezoid_law; genes per segment: T1 accel/decel time, T2 cruise)

A rest-to-rest family's trajectory is a `SegmentTrajectory`: segment i follows its joint path q_i(u),
u in [0, 1], with the time law u(t), so qd = q_u u_dot and qdd = q_u u_ddot + q_uu u_dot^2.

The Cartesian line's joint path comes from IK along the line (`line_paths`): N + 1 evenly spaced
points per segment, each by minimum-norm Gauss-Newton continuation from the one before (SpatialIK.follow:
the redundant joints move least, so q(u) is smooth), joined by a C2 cubic in u (not-a-knot ends). The
hand's distance to the straight line and its normal's angle to the slerped normal are measured by
Drake's forward kinematics at 4 points inside every interval; N doubles until they are below
LINE_TOL_M and LINE_TOL_RAD (`line_deviation` reports both).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.families.line import cubic_velocity_law
from qmt_drake.families.trapezoid import trapezoid_law
from qmt_drake.model.spatial_ik import slerp_rotations, slerp_unit
from qmt_drake.planners.spatial_toppra import DrakePath
from qmt_drake.planners.spatial_trajectory import PolyTrajectory
from qmt_drake.trajectory import JointTrajectory

FAMILIES = ("via_cubic", "line_cubic_velocity", "trapezoid_ptp")  # the planar families' names (families/)
LAWS = {"line_cubic_velocity": "cubic_velocity", "trapezoid_ptp": "trapezoid"}
LINE_TOL_M = 1e-5  # the hand's largest distance to the straight line between task poses
LINE_TOL_RAD = 1e-4  # the face normal's largest angle to the slerped normal (the rotation's, for rotations)
LINE_STEP_M = 0.02  # first IK point spacing along a line; halved until the tolerances hold
LINE_MAX_POINTS = 4096  # per segment
T1_MIN_S = 0.02  # gene bounds (s): accel/decel times at least this, cruise times from 0
GENE_MAX_S = 3.0
KNOT_TIME_BISECTIONS = 60  # the time a segment's law reaches a path knot, to 2^-60 of the segment


def law_values(law: str, T1, T2, t):
    """(u, u_dot, u_ddot) of a unit rest-to-rest move at times t (arrays broadcast): the chapter-2
    cubic-velocity law or the chapter-3 trapezoid."""
    if law == "cubic_velocity":
        return cubic_velocity_law(1.0, T1, T2, t)
    if law == "trapezoid":
        return trapezoid_law(1.0, T1, 2.0 * T1 + T2, 1.0 / (T1 + T2), t)
    raise ValueError(f"unknown time law {law!r}")


class SegmentTrajectory(JointTrajectory):
    """Rest-to-rest segments played one after another (module docstring): `paths` joint paths q_i(u)
    (Drake PiecewisePolynomials on [0, 1], or their DrakePaths, shared between trajectories so their
    derivatives are made once), `law` a law_values name, T1_s, T2_s per segment. breakpoints_s (made on
    first use): each segment's law phases (0, T1, T1 + T2, 2 T1 + T2: u-ddot jumps or kinks there) and the
    times the law passes its path's knots (a column kinks there); evaluate: JointTrajectory's, through sample()."""

    holds_end_value = True

    def __init__(self, paths, law: str, T1_s, T2_s) -> None:
        self.paths = [p if isinstance(p, DrakePath) else DrakePath(p) for p in paths]
        self.law = law
        self.T1_s, self.T2_s = np.asarray(T1_s, float), np.asarray(T2_s, float)
        if not (len(self.paths) == self.T1_s.size == self.T2_s.size) or np.any(self.T1_s <= 0) or np.any(self.T2_s < 0):
            raise ValueError("one positive T1 and non-negative T2 per segment path")
        law_values(law, 1.0, 0.0, 0.0)  # an unknown law fails here, not at the first sample
        self.segment_s = 2.0 * self.T1_s + self.T2_s
        self.t_start = np.r_[0.0, np.cumsum(self.segment_s)]
        self.duration_s = float(self.t_start[-1])
        self.n_dof = self.paths[0].dof

    @cached_property
    def breakpoints_s(self) -> np.ndarray:
        out = [self.t_start]
        for i, path in enumerate(self.paths):
            T1, T2 = self.T1_s[i], self.T2_s[i]
            knots = np.asarray(path.pp.get_segment_times(), float)
            knots = knots[(knots > 0.0) & (knots < 1.0)]
            lo, hi = np.zeros_like(knots), np.full_like(knots, self.segment_s[i])
            for _ in range(KNOT_TIME_BISECTIONS):  # u(t) is non-decreasing: bisect for u(t) = knot
                mid = 0.5 * (lo + hi)
                below = law_values(self.law, T1, T2, mid)[0] < knots
                lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
            out.append(self.t_start[i] + np.r_[T1, T1 + T2, 0.5 * (lo + hi)])
        return np.unique(np.clip(np.concatenate(out), 0.0, self.duration_s))

    def sample(self, t):
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.duration_s)
        k = np.clip(np.searchsorted(self.t_start, t, side="right") - 1, 0, len(self.paths) - 1)
        n = self.paths[0].dof
        q, qd, qdd = (np.empty((len(t), n)) for _ in range(3))
        for i, path in enumerate(self.paths):
            m = k == i
            if not np.any(m):
                continue
            tau = np.minimum(t[m] - self.t_start[i], self.segment_s[i])
            u, ud, udd = law_values(self.law, self.T1_s[i], self.T2_s[i], tau)
            u = np.clip(u, 0.0, 1.0)
            qu, quu = path(u, 1), path(u, 2)
            q[m] = path(u, 0)
            qd[m] = qu * ud[:, None]
            qdd[m] = qu * udd[:, None] + quu * (ud * ud)[:, None]
        return q, qd, qdd


def line_targets(sc, i: int, u):
    """Hand positions (m), face normals and rotations R_WH (None for a task of face normals) on the
    straight line from task pose i to i + 1 at fractions u, the orientation slerped."""
    u = np.atleast_1d(np.asarray(u, float))
    a, b = sc.poses_m[i], sc.poses_m[i + 1]
    pos = (1 - u)[:, None] * a + u[:, None] * b
    if sc.pose_rotations is None:
        return pos, slerp_unit(sc.pose_normals[i], sc.pose_normals[i + 1], u), None
    R = slerp_rotations(sc.pose_rotations[i], sc.pose_rotations[i + 1], u)
    return pos, R @ sc.ik.face_axis, R


def line_deviation(sc, i: int, pp, per_interval: int = 4) -> tuple[float, float]:
    """(m, rad): the largest distance of the hand (Drake FK on pp) to the line from pose i to i + 1 and
    of its face normal (or its rotation) to the slerped one, at per_interval points inside every
    interval of pp."""
    b = np.asarray(pp.get_segment_times())
    f = np.arange(1, per_interval + 1) / (per_interval + 1)
    u = (b[:-1, None] + np.diff(b)[:, None] * f).ravel()
    a, d = sc.poses_m[i], sc.poses_m[i + 1] - sc.poses_m[i]
    _, normals, rotations = line_targets(sc, i, u)
    worst_m = worst_rad = 0.0
    for k, qk in enumerate(pp.vector_values(u).T):
        target = {"normal": normals[k]} if rotations is None else {"rotation": rotations[k]}
        p = sc.ik.pose(qk)[0]
        x = np.clip((p - a) @ d / max(d @ d, 1e-300), 0.0, 1.0)
        worst_m = max(worst_m, float(np.linalg.norm(p - a - x * d)))
        worst_rad = max(worst_rad, sc.ik.errors(qk, p, **target)[1])
    return worst_m, worst_rad


def line_paths(sc) -> tuple[list, dict]:
    """The joint paths q_i(u) of the Cartesian line between neighbouring task poses (module docstring),
    each starting where the one before ends; (paths, facts: points per segment, largest deviations).
    Cached on the scenario."""
    cached = getattr(sc, "_line_paths", None)
    if cached is not None:
        return cached
    paths, points, dev_m, dev_rad = [], [], 0.0, 0.0
    q0 = sc.q_poses_rad[0]
    for i in range(len(sc.poses_m) - 1):
        length = float(np.linalg.norm(sc.poses_m[i + 1] - sc.poses_m[i]))
        n = max(int(np.ceil(length / LINE_STEP_M)), 4)
        while True:
            u = np.linspace(0.0, 1.0, n + 1)
            pos, nor, rot = line_targets(sc, i, u)
            Q = sc.ik.follow(pos, nor, q0, rotations=rot,
                             what=f"{sc.name}: the straight line from task pose {i} to {i + 1}, point")
            pp = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(u, Q.T, False)
            e_m, e_rad = line_deviation(sc, i, pp)
            if e_m <= LINE_TOL_M and e_rad <= LINE_TOL_RAD:
                break
            if 2 * n > LINE_MAX_POINTS:
                raise QmtInputError(f"{sc.name}: the straight line from task pose {i} to {i + 1} needs more than "
                                    f"{LINE_MAX_POINTS} IK points to stay within {LINE_TOL_M * 1e3:g} mm (it passes "
                                    "near a singularity); move the poses or use the via_cubic family")
            n *= 2
        paths.append(pp)
        points.append(n + 1)
        dev_m, dev_rad = max(dev_m, e_m), max(dev_rad, e_rad)
        q0 = Q[-1]
    out = (paths, {"ik_points_per_segment": points, "max_line_deviation_m": dev_m,
                   "max_normal_deviation_rad": dev_rad})
    sc._line_paths = out
    return out


def joint_segment_paths(sc) -> list:
    """The straight joint-space segments between neighbouring task poses' IK solutions, q_i(u) linear."""
    Q = sc.q_poses_rad
    return [PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.column_stack([a, b])) for a, b in zip(Q[:-1], Q[1:])]


class ViaCubicFamily:
    """The via-point cubic: genes T1..T_m, the segment times (s)."""

    kind = "via_cubic"
    facts: dict = {}

    def __init__(self, sc) -> None:
        self.sc = sc
        m = len(sc.q_poses_rad) - 1
        self.gene_names = tuple(f"T{i + 1}" for i in range(m))
        self.lower, self.upper = np.full(m, 0.05), np.full(m, GENE_MAX_S)

    def trajectory(self, genes) -> PolyTrajectory:
        return via_cubic(self.sc, genes)

    def pose_times(self, genes) -> np.ndarray:
        return np.r_[0.0, np.cumsum(genes)]

    def duration_s(self, G) -> np.ndarray:
        """(P,) motion times of (P, m) genes."""
        return np.atleast_2d(G).sum(axis=1)

    def segment_times(self, genes) -> np.ndarray:
        return np.asarray(genes, float)


def via_cubic(sc, T) -> PolyTrajectory:
    """The via cubic through sc's task poses with segment times T (s): zero end velocities, continuous
    acceleration at the vias (Drake's CubicWithContinuousSecondDerivatives)."""
    breaks = np.r_[0.0, np.cumsum(np.asarray(T, float))]
    zero = np.zeros(sc.n_dof)
    return PolyTrajectory(PiecewisePolynomial.CubicWithContinuousSecondDerivatives(breaks, sc.q_poses_rad.T,
                                                                                   zero, zero))


class RestToRestFamily:
    """A family of rest-to-rest segments (line_cubic_velocity, trapezoid_ptp): genes (T1_1, T2_1, ...,
    T1_m, T2_m)."""

    def __init__(self, sc, kind: str) -> None:
        self.kind, self.law = kind, LAWS[kind]
        if kind == "line_cubic_velocity":
            self.paths, self.facts = line_paths(sc)
        else:
            self.paths, self.facts = joint_segment_paths(sc), {}
        self._drake_paths = [DrakePath(pp) for pp in self.paths]  # derivatives made once, for every candidate
        m = len(self.paths)
        self.gene_names = tuple(f"{name}_{i + 1}" for i in range(m) for name in ("T1", "T2"))
        self.lower = np.tile([T1_MIN_S, 0.0], m)
        self.upper = np.full(2 * m, GENE_MAX_S)

    @property
    def n_segments(self) -> int:
        return len(self.paths)

    def trajectory(self, genes) -> SegmentTrajectory:
        g = np.asarray(genes, float).reshape(-1, 2)
        return SegmentTrajectory(self._drake_paths, self.law, g[:, 0], g[:, 1])

    def segment_trajectory(self, i: int, T1_s: float, T2_s: float) -> SegmentTrajectory:
        """Segment i alone with accel/decel time T1_s and cruise time T2_s."""
        return SegmentTrajectory([self._drake_paths[i]], self.law, [T1_s], [T2_s])

    def duration_s(self, G) -> np.ndarray:
        """(P,) motion times of (P, 2m) genes: the sum of 2 T1 + T2 over the segments."""
        g = np.atleast_2d(G)
        return 2.0 * g[:, 0::2].sum(axis=1) + g[:, 1::2].sum(axis=1)

    def pose_times(self, genes) -> np.ndarray:
        return self.trajectory(genes).t_start

    def segment_times(self, genes) -> np.ndarray:
        return self.trajectory(genes).segment_s


def spatial_family(sc, kind: str):
    """The family `kind` (one of FAMILIES) on sc; one line naming the families for any other."""
    if kind not in FAMILIES:
        raise QmtInputError(f"family {kind!r} is not a spatial family; use one of {', '.join(FAMILIES)}")
    return ViaCubicFamily(sc) if kind == "via_cubic" else RestToRestFamily(sc, kind)
