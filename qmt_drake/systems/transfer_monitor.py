"""Transfer monitor: payload slip, tilt, gap and detachment; tracking error; motor peaks; energy.

Sampled every `period_s` (a periodic discrete update; the running extrema live in the state).
With period_s=None there is no per-step update and no summary port: the monitor then only checks
the seated start and serves slip / tilt / gap on demand, and the summary is computed after the run
from per-step C++ logs (`sim.posthoc.summary_from_logs`, the co-simulation's default: same numbers,
no Python call per plant step). `motion_in_hand` is the one implementation of slip / tilt / gap,
for one pose or a stack of them.

Needs: a plant built with `sim.plant.transfer_plant_config` (live output ports: with sampled ones
the monitor pairs the next plant state with this step's reference) and a context that starts with
the payload seated. At initialization it checks that: a payload that is not seated at t = 0
(slip or gap above `seated_tolerance_m`, tilt above `seated_tolerance_rad`) raises
QmtSimulationError naming the numbers, instead of reporting "detached at 0 s" as a result
(`check_seated_at_start=False` turns the check off, e.g. for a drop test).

    slip      in-plane (hand x-y) distance of the payload's face centre from its seated position [m]
    tilt      angle between the payload's face normal and the hand's face normal [rad]
    gap       distance of the payload's face centre below the hand's face plane [m]
    detached  first sample time at which gap > detach_gap_m or slip > detach_slip_m [s]
    tracking  max over joints and time of |q_des - q| [rad]
    motor     max |motor torque| per motor [N*m]
    energy    integral of the summed electrical power [J] (net: regeneration counts negative)

Ports
    inputs
        body_poses        abstract, MultibodyPlant.get_body_poses_output_port()
        arm_state         (2n,) [rad, rad/s]  the arm model instance's state
        desired_state     (2n,) [rad, rad/s]
        motor_torque      (n,)  [N*m]
        electrical_power  (n,)  [W]
    outputs
        slip              (1,) [m]     current slip
        tilt              (1,) [rad]   current tilt
        gap               (1,) [m]     current gap
        summary           (6+n,)       [max_slip_m, max_tilt_rad, detached_at_s (NaN if never),
                                        max_tracking_error_rad, energy_J, max_gap_m,
                                        peak_motor_torque_Nm (n)]   (the `SUMMARY_FIELDS` order)
"""

from __future__ import annotations

import math

import numpy as np
from pydrake import symbolic
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Demultiplexer, MatrixGain

from qmt_drake.errors import QmtSimulationError
from qmt_drake.systems.scalar_ops import FLOAT, SYMBOLIC, symbolic_law

SUMMARY_FIELDS = ("max_slip_m", "max_tilt_rad", "detached_at_s", "max_tracking_error_rad", "energy_J",
                  "max_gap_m")
DETACH_GAP_M = 2e-3  # a payload is detached once its gap exceeds this [m] ...
DETACH_SLIP_M = 5e-3  # ... or its slip this [m]


def motion_from_joint(q, ops=FLOAT):
    """(slip [m], tilt [rad], gap [m]) of a payload seated at the identity of its 6-DOF joint to the
    hand (payload.add_payload), from the joint's positions q = (w, x, y, z, px, py, pz): quaternion
    (any norm; it cancels), then p_HP [m]. tilt = atan2(|z_P x z_H|, z_P . z_H) with z_P's components
    in H (twice the quaternion's rotation of e_z, times |q|^2). Floats, numpy arrays (ops=NUMPY, q as
    seven arrays) or drake symbolic Expressions (ops=SYMBOLIC); the same quantities `motion_in_hand`
    computes from poses."""
    w, x, y, z, px, py, pz = q
    zx, zy = x * z + w * y, y * z - w * x  # in-plane components of z_P (halved)
    tilt = ops.atan2(2.0 * ops.sqrt(zx * zx + zy * zy), w * w - x * x - y * y + z * z)
    return ops.sqrt(px * px + py * py), tilt, ops.clip(-pz, 0.0, math.inf)


SEATED_TOLERANCE_M, SEATED_TOLERANCE_RAD = 1e-4, 1e-2


def check_seated(slip_m: float, tilt_rad: float, gap_m: float, t_s: float, tol_m: float = SEATED_TOLERANCE_M,
                 tol_rad: float = SEATED_TOLERANCE_RAD) -> None:
    """One-line QmtSimulationError when the payload is not seated at the start (module docstring)."""
    if slip_m > tol_m or gap_m > tol_m or tilt_rad > tol_rad:
        raise QmtSimulationError(
            f"payload not seated on the hand at t = {t_s:g} s (slip {slip_m * 1e3:.3g} mm, "
            f"gap {gap_m * 1e3 + 0.0:.3g} mm, tilt {tilt_rad:.3g} rad); start from the diagram's default context or "
            "call TransferDiagram.set_initial_state")


def payload_motion_as_primitives(plant, payload_joint, *, host_has_continuous_state: bool = False):
    """slip, tilt and gap (`motion_from_joint`) of the payload on `payload_joint` as a Diagram of Drake
    primitives: input plant_state (nq + nv) of the finalised plant; outputs slip (1) [m], tilt (1)
    [rad], gap (1) [m]. host_has_continuous_state: see scalar_ops.symbolic_law."""
    q = [symbolic.Variable(v) for v in ("w", "x", "y", "z", "px", "py", "pz")]
    pick = np.zeros((7, plant.num_positions() + plant.num_velocities()))
    pick[np.arange(7), payload_joint.position_start() + np.arange(7)] = 1.0
    b = DiagramBuilder()
    select = b.AddNamedSystem("payload_pose", MatrixGain(pick))
    law = b.AddNamedSystem("motion", symbolic_law(q, list(motion_from_joint(q, SYMBOLIC)),
                                                  host_has_continuous_state=host_has_continuous_state))
    split = b.AddNamedSystem("split", Demultiplexer(3, 1))
    b.Connect(select.get_output_port(), law.get_input_port())
    b.Connect(law.get_output_port(), split.get_input_port())
    b.ExportInput(select.get_input_port(), "plant_state")
    for k, name in enumerate(("slip", "tilt", "gap")):
        b.ExportOutput(split.get_output_port(k), name)
    diagram = b.Build()
    diagram.set_name("payload_motion")
    return diagram


def relative_payload_motion(X_WH: RigidTransform, X_WP: RigidTransform, X_HP0: RigidTransform):
    """(slip [m], tilt [rad], gap [m]) of payload pose X_WP relative to the seated X_HP0 in hand H."""
    return _motion_in_hand(X_WH.InvertAndCompose(X_WP).GetAsMatrix34(), X_HP0.translation().tolist(),
                           X_HP0.rotation().matrix()[:, 2].tolist())


def motion_in_hand(M_HP: np.ndarray, p_HP0, z_HP0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(slip [m], tilt [rad], gap [m]) arrays from payload poses in the hand frame X_HP stacked as
    (K, 3, 4) arrays ([R | p]) and the seated pose's origin p_HP0 and z axis z_HP0 (in H).
    slip: in-plane distance of the face centre from its seated point; tilt: angle between the
    payload's z axis and the seated one; gap: how far the face centre is below its seated height."""
    M = np.asarray(M_HP, float).reshape(-1, 3, 4)
    d = M[:, :, 3] - np.asarray(p_HP0, float)
    z, z0 = M[:, :, 2], np.asarray(z_HP0, float)  # payload z and seated z, both in H
    # atan2(|z x z0|, z . z0): well conditioned at small tilts, where arccos(z . z0) loses half the digits.
    tilt = np.arctan2(np.linalg.norm(np.cross(z, z0), axis=1), z @ z0)
    return np.hypot(d[:, 0], d[:, 1]), tilt, np.maximum(-d[:, 2], 0.0)


def _motion_in_hand(M_HP, p_HP0, z_HP0):
    """slip, tilt, gap as floats for one X_HP (a 3x4 array): `motion_in_hand` of one pose."""
    slip, tilt, gap = motion_in_hand(M_HP, p_HP0, z_HP0)
    return float(slip[0]), float(tilt[0]), float(gap[0])


class TransferMonitor(LeafSystem):
    """See the module docstring for quantities, ports and units."""

    def __init__(self, n_joints: int, hand_body_index, payload_body_index, *, period_s: float | None = 1e-3,
                 seated_pose_in_hand: RigidTransform | None = None, detach_gap_m: float = DETACH_GAP_M,
                 detach_slip_m: float = DETACH_SLIP_M, check_seated_at_start: bool = True,
                 seated_tolerance_m: float = SEATED_TOLERANCE_M, seated_tolerance_rad: float = SEATED_TOLERANCE_RAD):
        super().__init__()
        n = n_joints
        self._n = n
        self._hand = int(hand_body_index)
        self._payload = int(payload_body_index)
        self._T = None if period_s is None else float(period_s)
        X_HP0 = seated_pose_in_hand or RigidTransform()
        self._p_HP0 = X_HP0.translation().tolist()
        self._z_HP0 = X_HP0.rotation().matrix()[:, 2].tolist()
        self._detach_gap = detach_gap_m
        self._detach_slip = detach_slip_m
        self._poses_in = self.DeclareAbstractInputPort("body_poses", AbstractValue.Make([RigidTransform()]))
        self._x_in = self.DeclareVectorInputPort("arm_state", 2 * n)
        self._xd_in = self.DeclareVectorInputPort("desired_state", 2 * n)
        self._tau_in = self.DeclareVectorInputPort("motor_torque", n)
        self._p_in = self.DeclareVectorInputPort("electrical_power", n)
        init = np.zeros(len(SUMMARY_FIELDS) + n)
        init[2] = np.nan
        self._s = self.DeclareDiscreteState(init)
        if self._T is not None:
            self.DeclarePeriodicDiscreteUpdateEvent(self._T, 0.0, self._update)
        self._seat_tol = (float(seated_tolerance_m), float(seated_tolerance_rad))
        if check_seated_at_start:
            self.DeclareInitializationDiscreteUpdateEvent(self._check_seated)
        self.DeclareVectorOutputPort("slip", 1, lambda c, o: o.SetAtIndex(0, self._motion(c)[0]))
        self.DeclareVectorOutputPort("tilt", 1, lambda c, o: o.SetAtIndex(0, self._motion(c)[1]))
        self.DeclareVectorOutputPort("gap", 1, lambda c, o: o.SetAtIndex(0, self._motion(c)[2]))
        if self._T is not None:  # without the per-step update the state holds no summary
            self.DeclareStateOutputPort("summary", self._s)

    @property
    def seated_axes(self) -> tuple[list, list]:
        """(p_HP0, z_HP0): the seated payload's origin and z axis in the hand frame."""
        return self._p_HP0, self._z_HP0

    @property
    def detach_thresholds_m(self) -> tuple[float, float]:
        """(detach_gap_m, detach_slip_m)."""
        return self._detach_gap, self._detach_slip

    def _motion(self, context):
        poses = self._poses_in.Eval(context)
        # InvertAndCompose and GetAsMatrix34 run in C++: one conversion instead of a dozen small ones.
        return _motion_in_hand(poses[self._hand].InvertAndCompose(poses[self._payload]).GetAsMatrix34(),
                               self._p_HP0, self._z_HP0)

    def _check_seated(self, context, discrete_state):
        check_seated(*self._motion(context), context.get_time(), *self._seat_tol)
        discrete_state.set_value(self._s, context.get_discrete_state(self._s).get_value())

    def _update(self, context, discrete_state):
        # Plain floats: this runs every plant step (see DcMotorWithGear._signals).
        s = context.get_discrete_state(self._s).get_value().tolist()
        slip, tilt, gap = self._motion(context)
        n = self._n
        err = (self._xd_in.Eval(context)[:n] - self._x_in.Eval(context)[:n]).tolist()
        s[0] = max(s[0], slip)
        s[1] = max(s[1], tilt)
        if math.isnan(s[2]) and (gap > self._detach_gap or slip > self._detach_slip):
            s[2] = context.get_time()
        s[3] = max(s[3], max(map(abs, err)))
        s[4] += self._T * sum(self._p_in.Eval(context).tolist())
        s[5] = max(s[5], gap)
        for k, tau in enumerate(self._tau_in.Eval(context).tolist()):
            s[6 + k] = max(s[6 + k], abs(tau))
        discrete_state.set_value(self._s, s)

    @staticmethod
    def unpack(summary: np.ndarray) -> dict:
        """The summary vector as a dict of named values (peak_motor_torque_Nm is an array)."""
        d = {k: float(summary[i]) for i, k in enumerate(SUMMARY_FIELDS)}
        d["peak_motor_torque_Nm"] = np.asarray(summary[len(SUMMARY_FIELDS):], float)
        return d
