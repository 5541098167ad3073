"""Limits as terms: each limit is its own module producing columns from the batched hand state
(payload_moment.py, motor_torque.py, joint_range.py, tray.py: no slide / no tip / no lift-off of an
unfixed object on a tray and joint speeds; tray_contact.py: the same for a cup on a spatial arm's
tray, and the ratio formulas both use; base.py says how columns are read); the LimitSet
(limit_set.py) evaluates them together for the GA, the re-check report and TOPP-RA. tray.py is
imported from qmt_drake.tray.limit_terms (it needs Drake through systems/tray_object.py)."""

from qmt_drake.limits.base import LimitTerm, RowOptions
from qmt_drake.limits.joint_range import JointRangeTerm
from qmt_drake.limits.limit_set import BatchPeaks, LimitReport, LimitSet
from qmt_drake.limits.motor_torque import MotorTorqueTerm
from qmt_drake.limits.payload_moment import PayloadMomentTerm

__all__ = ["BatchPeaks", "JointRangeTerm", "LimitReport", "LimitSet", "LimitTerm", "MotorTorqueTerm",
           "PayloadMomentTerm"]
