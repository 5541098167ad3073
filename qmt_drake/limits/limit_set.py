"""LimitSet: a scenario's limit terms, and the one place limits are evaluated.

The set computes the hand state of all samples once and stacks every term's columns (S, M). From
those columns come the GA's feasibility (`BatchPeaks`), the re-check report of every plan
(`limit_report`) and, through the terms' toppra rows, the TOPP-RA constraint.

TOPP-RA (`toppra_constraint`): every term with a linear form gives w (affine in qdd, quadratic in
qd) and rows F w <= g; one toppra SecondOrderConstraint stacks them (F block diagonal) and computes
its parameters a, b, c for ALL grid points at once from three batched hand states (w at
(qd, qdd) = (0, 0), (0, q'), (q', q'')), instead of toppra's default of three Python inverse-dynamics
calls per grid point (`batched=False`, kept to measure the difference: studies/crane_tray.py
`toppra_timing`); its rows are scaled to unit norm (limits/toppra_form.py says why).

"Feasible" holds between the samples too: `limit_report` refines every sampled local maximum that
comes near its column's peak or near the limit by a batched golden-section search on the
trajectory itself (within the sample's piece, between its neighbours; limits/refine.py, the one
implementation the spatial re-check uses too), so the reported peak is the trajectory's local
maximum, not the largest sample. `tests/test_planners_recheck.py` samples
every planner's output 10x finer and finds no ratio above the refined peak.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.linalg import block_diag

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.base import RowOptions
from qmt_drake.limits.refine import REFINE_MAX_PER_COLUMN as REFINE_MAX_PER_COLUMN  # re-exported (tests)
from qmt_drake.limits.refine import REFINE_NEAR_LIMIT, peaks_on_pieces
from qmt_drake.limits.toppra_form import rows_constraint

JOINT_EXCESS_TOL_RAD = 1e-12


class LimitSet:
    def __init__(self, arm, terms) -> None:
        self.arm = arm
        self.terms = list(terms)
        self.slices, start = {}, 0
        for t in self.terms:
            self.slices[t.name] = slice(start, start + len(t.column_names))
            start += len(t.column_names)
        self.n_columns = start
        self.ratio_mask = np.concatenate([np.full(len(t.column_names), t.kind == "ratio") for t in self.terms])
        self.column_names = [c for t in self.terms for c in t.column_names]

    def term(self, name: str):
        return next((t for t in self.terms if t.name == name), None)

    @property
    def time_scaling_is_exact(self) -> bool:
        """Playing a motion lam times slower divides every ratio column by lam^2 and leaves the rest:
        the exact time-scaling shortcut of the planners is valid only then."""
        return all(t.scaling in ("inverse_square", "invariant") for t in self.terms)

    def columns(self, q, qd, qdd) -> np.ndarray:
        state = self.arm.hand_state(q, qd, qdd)
        return np.concatenate([t.columns(state) for t in self.terms], axis=1)

    # ------------------------------------------------------------------ TOPP-RA
    def toppra_rows(self, **row_options):
        """(terms, F, g): the terms with a linear form and their stacked rows F w <= g (F block
        diagonal in term order). row_options: the fields of base.RowOptions (typed; an unknown name
        is a one-line QmtInputError)."""
        options = RowOptions.from_keywords(**row_options)
        terms, blocks = [], []
        for t in self.terms:
            rows = t.toppra_rows(options)
            if rows is not None:
                terms.append(t)
                blocks.append(rows)
        return terms, block_diag(*[b[0] for b in blocks]), np.concatenate([b[1] for b in blocks])

    def toppra_w(self, terms, q, qd, qdd) -> np.ndarray:
        """(S, k) the stacked w of `terms` at joint samples (S, n)."""
        state = self.arm.hand_state(np.atleast_2d(q), np.atleast_2d(qd), np.atleast_2d(qdd))
        parts = [t.toppra_w(state) for t in terms]
        if any(p is None for p in parts):
            raise QmtInputError("TOPP-RA: a limit of this scenario has no linear form on this arm (e.g. the "
                                "payload face is not in the arm's plane); use the GA or ruckig")
        return np.concatenate(parts, axis=-1)

    def toppra_constraint(self, *, batched: bool = True, **row_options):
        """One toppra SecondOrderConstraint of every term with a linear form (module docstring;
        limits/toppra_form.py: parameters of all grid points in one batch, unit-norm rows).
        batched=False leaves the parameters to toppra (three w calls per grid point), to measure
        the difference. row_options go to every term's toppra_rows."""
        # lazy: toppra loads matplotlib.pyplot, too slow for every CLI start
        from toppra.constraint import DiscretizationType, SecondOrderConstraint

        terms, F, g = self.toppra_rows(**row_options)
        if batched:
            return rows_constraint(lambda q, qd, qdd: self.toppra_w(terms, q, qd, qdd), F, g, self.arm.n_dof)
        return SecondOrderConstraint(lambda q, qd, qdd: self.toppra_w(terms, q, qd, qdd)[0],
                                     lambda q: F, lambda q: g, self.arm.n_dof,
                                     discretization_scheme=DiscretizationType.Interpolation)

    # ------------------------------------------------------------------ batched peaks (planners)
    def batch_peaks(self, motion_time_s, valid, peaks) -> BatchPeaks:
        return BatchPeaks(motion_time_s, valid, peaks, self)

    # ------------------------------------------------------------------ one trajectory (re-check)
    def report(self, trajectory, rate_hz: float, valid: bool = True, refine: bool = True) -> LimitReport:
        """The re-check of a trajectory of any kind: its pieces sampled at rate_hz, the sampled local maxima that
        matter refined between the samples (limits/refine.peaks_on_pieces, the spatial re-check's too)."""
        near_limit = np.where(self.ratio_mask, REFINE_NEAR_LIMIT, -0.02)
        peak, t_peak, refined_count, _ = peaks_on_pieces(self.columns, trajectory, rate_hz, near_limit, refine=refine)
        return self._make_report(rate_hz, float(trajectory.duration_s), peak, t_peak, valid, refined_count)

    def _make_report(self, rate_hz, T, peak, t_peak, valid, refined_count) -> LimitReport:
        moment = self.term("payload_moment")
        motor = self.term("motor_torque")
        joint = self.term("joint_range")
        ratios = peak[self.ratio_mask]
        worst = float(ratios.max()) if ratios.size else 0.0
        joint_ok = True if joint is None else bool(peak[self.slices["joint_range"]].max() <= JOINT_EXCESS_TOL_RAD)
        m_ratio = float(peak[self.slices["payload_moment"]][0]) if moment else 0.0
        motor_ratios = peak[self.slices["motor_torque"]] if motor else np.zeros(0)
        return LimitReport(
            rate_hz=float(rate_hz), motion_time_s=T,
            peak_moment_Nm=m_ratio * moment.moment_limit_Nm if moment else 0.0,
            moment_limit_Nm=moment.moment_limit_Nm if moment else None,
            peak_moment_ratio=m_ratio,
            peak_moment_time_s=float(t_peak[self.slices["payload_moment"]][0]) if moment else None,
            peak_motor_torque_Nm=(motor_ratios * motor.limit_Nm).tolist() if motor else [],
            motor_torque_limit_Nm=motor.limit_Nm.tolist() if motor else [],
            peak_motor_torque_ratio=float(motor_ratios.max()) if motor_ratios.size else 0.0,
            joint_range_ok=joint_ok,
            feasible=bool(valid and joint_ok and worst <= 1.0),
            peak_ratios={t.name: float(peak[self.slices[t.name]].max()) for t in self.terms if t.kind == "ratio"},
            refined_local_maxima=refined_count)


@dataclass(frozen=True)
class BatchPeaks:
    """Peak columns of K candidates (inf where a candidate defines no trajectory)."""

    motion_time_s: np.ndarray  # (K,)
    valid: np.ndarray  # (K,) bool: the genes define a trajectory
    peaks: np.ndarray  # (K, M) in LimitSet column order
    limit_set: LimitSet = field(repr=False)

    def _term(self, name, width):
        s = self.limit_set.slices.get(name)
        return self.peaks[:, s] if s is not None else np.zeros((self.peaks.shape[0], width))

    @property
    def peak_moment_ratio(self) -> np.ndarray:
        return self._term("payload_moment", 1)[:, 0]

    @property
    def peak_motor_torque_ratio(self) -> np.ndarray:
        return self._term("motor_torque", self.limit_set.arm.n_dof)

    @property
    def joint_excess_rad(self) -> np.ndarray:
        ex = self.peaks[:, ~self.limit_set.ratio_mask]
        return ex.max(axis=1) if ex.shape[1] else np.full(self.peaks.shape[0], -np.inf)

    @property
    def joint_range_ok(self) -> np.ndarray:
        return self.joint_excess_rad <= JOINT_EXCESS_TOL_RAD

    @property
    def worst_ratio(self) -> np.ndarray:
        r = self.peaks[:, self.limit_set.ratio_mask]
        return r.max(axis=1) if r.shape[1] else np.zeros(self.peaks.shape[0])

    @property
    def feasible(self) -> np.ndarray:
        return self.valid & self.joint_range_ok & (self.worst_ratio <= 1.0)


@dataclass(frozen=True)
class LimitReport:
    """Limits of one trajectory on one sampling with its local maxima refined, in the units of its
    field names. peak_ratios: every ratio term's peak (name -> peak / limit)."""

    rate_hz: float
    motion_time_s: float
    peak_moment_Nm: float
    moment_limit_Nm: float | None
    peak_moment_ratio: float
    peak_moment_time_s: float | None
    peak_motor_torque_Nm: list
    motor_torque_limit_Nm: list
    peak_motor_torque_ratio: float
    joint_range_ok: bool
    feasible: bool
    peak_ratios: dict = field(default_factory=dict)
    refined_local_maxima: int = 0

    @property
    def worst_ratio(self) -> float:
        return max(self.peak_ratios.values(), default=0.0)

    def to_dict(self) -> dict:
        return asdict(self)
