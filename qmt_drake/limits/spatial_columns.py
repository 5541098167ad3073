"""The spatial re-check's limit columns, refined between samples like the planar ones.

`SpatialColumns(sc, terms)` stacks, for joint samples (S, n) of a spatial scenario, every limit as a
ratio column (value / limit, held while <= 1): joint speed |qd| / v_max and acceleration |qdd| / a_max
per joint, the scenario's terms (joint torques through sc.chain, the hand's term) and the joint RANGE
from the URDF, |q - mid| / half-range per joint (0 for a joint without finite limits), so a plan that
leaves a joint's range between task poses is reported like any other limit. Joints are found in the
plant by name (the range of the joint called so, whatever its position index).

`peaks(columns, traj, t_s, refine)` samples a trajectory (anything with `sample(t) -> (q, qd, qdd)`) at
t_s and, with refine, refines the local maxima between samples by limits/refine.py, the same
implementation as the planar LimitSet.report; it returns every column's peak and its time.
`binding(columns, peak, t_peak)` names the largest column: the limit, the joint or hand row, the time.
"""

from __future__ import annotations

import numpy as np

from qmt_drake.limits.refine import REFINE_NEAR_LIMIT, refine_local_maxima
from qmt_drake.sampling import uniform_grid

JOINT_RANGE = "joint_range"
TIMED_GROUPS_EXCLUDE = (JOINT_RANGE,)
# refine the local maxima above 98 % of a limit (every one that could break it) and those within 0.5 %
# of their column's peak (the reported peaks); the planar 2 % would refine hundreds of maxima of the
# many spatial columns (6-7 joints x 4 groups and the hand's rows) at 60 golden-section steps each
SPATIAL_RELATIVE_MARGIN = 0.005  # positions only: playing the motion slower does not change them


def joint_range_by_name(plant, joint_names) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) rad of the named one-DOF joints, in the order of joint_names."""
    lo, up = [], []
    for name in joint_names:
        j = plant.GetJointByName(name)
        lo.append(float(j.position_lower_limits()[0]))
        up.append(float(j.position_upper_limits()[0]))
    return np.array(lo), np.array(up)


class SpatialColumns:
    def __init__(self, sc, terms=None) -> None:
        self.chain = sc.chain
        self.terms = list(sc.terms() if terms is None else terms)
        names = list(sc.joint_names)
        self.v_max = np.asarray(sc.velocity_limit_rad_s, float)
        self.a_max = np.asarray(sc.acceleration_limit_rad_s2, float)
        lower, upper = joint_range_by_name(sc.plant, names)
        finite = np.isfinite(lower) & np.isfinite(upper)
        self.mid = np.where(finite, 0.5 * (lower + upper), 0.0)
        self.inv_half = np.where(finite, 2.0 / np.where(finite, upper - lower, 1.0), 0.0)
        per_joint = {g: tuple(f"{g}[{n}]" for n in names) for g in ("joint_speed", "joint_acceleration", JOINT_RANGE)}
        self.groups = ([("joint_speed", per_joint["joint_speed"]), ("joint_acceleration", per_joint["joint_acceleration"])]
                       + [(t.name, tuple(t.column_names)) for t in self.terms] + [(JOINT_RANGE, per_joint[JOINT_RANGE])])
        self.slices, start = {}, 0
        for name, cols in self.groups:
            self.slices[name] = slice(start, start + len(cols))
            start += len(cols)
        self.n_columns = start
        self.column_labels = [(g, c) for g, cols in self.groups for c in cols]

    def columns(self, q, qd, qdd) -> np.ndarray:
        """(S, M) every ratio column at the samples."""
        state = self.chain.evaluate(q, qd, qdd)
        parts = [np.abs(qd) / self.v_max, np.abs(qdd) / self.a_max]
        parts += [t.columns(state) for t in self.terms]
        parts.append(np.abs(q - self.mid) * self.inv_half)
        return np.concatenate(parts, axis=1)


def peaks(columns: SpatialColumns, traj, t_s, refine: bool = True):
    """(peak (M,), t_peak (M,), refined count) of every column over the samples t_s (s), local maxima
    refined between the samples when `refine` (module docstring)."""
    t_s = np.asarray(t_s, float)
    q, qd, qdd = traj.sample(t_s)
    cols = columns.columns(q, qd, qdd)
    peak = cols.max(axis=0)
    t_peak = t_s[cols.argmax(axis=0)]
    if not refine or t_s.size < 2:
        return peak, t_peak, 0
    near = np.full(cols.shape[1], REFINE_NEAR_LIMIT)
    return refine_local_maxima(lambda t, tp: columns.columns(*traj.sample(t)), uniform_grid(t_s), cols, peak,
                               t_peak, near, relative_margin=SPATIAL_RELATIVE_MARGIN, skip_flat=True)


def binding(columns: SpatialColumns, peak, t_peak) -> dict:
    """The largest column: {'limit', 'column' (e.g. 'motor_torque[shoulder_lift_joint]' or the hand
    term's row), 'time_s', 'ratio'}."""
    i = int(np.argmax(peak))
    group, col = columns.column_labels[i]
    return {"limit": group, "column": str(col), "time_s": float(t_peak[i]), "ratio": float(peak[i])}
