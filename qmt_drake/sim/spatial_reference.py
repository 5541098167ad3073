"""Closed-loop-aware references for the spatial drives (issue 29 item 2): feedforward `shaped`.

What the plain plan does to the closed loop (measured, docs/spatial_drives.md): a TOPP-RA plan's joint
acceleration jumps at its switching points (on the UR5 magnet task by up to 5 rad/s^2 within one 1 ms
step). Either drive follows the jump within a step, but (a) the discrete plant lags the interpolated
reference after it and the loop's correction adds 3-9 % to the hand's wrench for a few ms, and (b) the
jump rings the carried part on its weld (about 70 Hz): the ratio that was 0.97 in the plan reaches 1.86.
A plan on its limit is then carried only when played about 1.36x slower, whatever the drive.

`shaped` sends the loop the plan seen through two moving averages of width w/2 each (two box FIRs in
series, a triangular kernel of total width w). One box of width b (BoxShapedReference):

    q_s(t)   = (1/b) * integral_{t-b}^{t} q(tau) dtau      (q held at rest before 0 and after T)
    qd_s(t)  = (q(t) - q(t-b)) / b
    qdd_s(t) = (qd(t) - qd(t-b)) / b

exact derivatives of one another, so the feedforward (the inverse dynamics through the motor's inverse,
sim/spatial_actuation) is evaluated on a consistent motion. After one box the acceleration is continuous
(the jerk at most the largest acceleration jump over w/2; the start is jerk-limited), after the second the
jerk is continuous too: on the UR5 magnet plan one 42 ms box leaves a 9 % overshoot of the hand ratio where
the jerk jumps, two 21 ms boxes 4 % (docs/spatial_drives.md).
The hand's acceleration is (to first order in w times the joint speed) the moving average of the plan's,
so a wrench inside the hand's convex limit set stays inside: the shaped motion keeps the plan's limits
and ends w later.

As the sampled-data plant integrates it (`SampledDataReference`, h the plant's step): the discrete plant
steps v+ = v + h a, q+ = q + h v+, so played against the continuous reference it runs h qd / 2 ahead and
the PD brakes it (3-9 % of the hand's wrench after a jump). The loop is sent q(t) + h/2 qd(t), qd(t) and
the step's mean acceleration (qd(t+h) - qd(t)) / h: stepped with the feedforward's acceleration the plant
reproduces the velocity exactly and the position to h^3/12 times the jerk. (The DC motors' implicit loop
damping takes D h qdd more over a step: spatial_actuation.add_stepping_feedforward gives it back.)

Where the motors cannot follow (`drive_fit_scale`): the feedforward's current and voltage (dc_motor
.motor_signals_from_joint_torque of the drive's inverse dynamics) are checked along the plan; a plan that
needs more than the motors' limits is slowed (timescale.smallest_holding_scale) until it fits, before
shaping. The shipped UR5 and Panda plans fit at scale 1.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.tree import MultibodyForces

from qmt_drake.systems.dc_motor import motor_signals_from_joint_torque
from qmt_drake.timescale import smallest_holding_scale
from qmt_drake.trajectory import JointTrajectory, TimeScaledTrajectory

SHAPING_WINDOW_S = 0.042  # w: two boxes of 21 ms (1.5 periods of the part's ringing on its weld, about 14 ms)
QUADRATURE_STEP_S = 2.5e-4  # the running integral of q: Hermite-corrected trapezoid (exact for cubics)
FIT_SAMPLE_S = 1e-3  # the feedforward's current / voltage check along the plan
FIT_MAX_SCALE = 4.0
FIT_REL_TOL = 1e-3


class SampledDataReference(JointTrajectory):
    """`traj` as the loop's sampled-data plant integrates it (module docstring): at t, q(t) + h/2 qd(t), qd(t)
    and the step's mean acceleration (qd(t + h) - qd(t)) / h, h = time_step_s [s]."""

    holds_end_value = True  # a JointTrajectory that samples itself (qmt_drake/trajectory.py)

    def __init__(self, traj, time_step_s: float) -> None:
        self.inner, self.h = traj, float(time_step_s)
        self.duration_s = traj.duration_s

    n_dof = property(lambda self: self.inner.n_dof)
    breakpoints_s = property(lambda self: np.unique(np.clip(np.r_[self.inner.breakpoints_s, self.inner.breakpoints_s
                                                                  - self.h], 0.0, self.duration_s)))

    def sample(self, t_s):
        t = np.atleast_1d(np.asarray(t_s, float))
        q, qd, _ = self.inner.sample(t)
        _, qd_next, _ = self.inner.sample(np.minimum(t + self.h, self.duration_s))
        return q + 0.5 * self.h * qd, qd, (qd_next - qd) / self.h


class BoxShapedReference(JointTrajectory):
    """`traj` (a spatial_trajectory kind: duration_s, sample(t) -> q, qd, qdd (len(t), n)) seen through a
    moving average of width window_s [s] (module docstring); duration_s = traj's + window_s."""

    holds_end_value = True  # a JointTrajectory that samples itself (qmt_drake/trajectory.py)

    def __init__(self, traj, window_s: float = SHAPING_WINDOW_S) -> None:
        if not window_s > 0:
            raise ValueError("the shaping window must be positive")
        self.inner, self.window_s = traj, float(window_s)
        self.duration_s = traj.duration_s + self.window_s
        T = traj.duration_s
        self._t = np.linspace(0.0, T, max(2, int(np.ceil(T / QUADRATURE_STEP_S)) + 1))
        q, qd, _ = traj.sample(self._t)
        self._q, self._qd = q, qd
        self._Q = np.vstack([np.zeros(q.shape[1]), np.cumsum(_hermite_area(np.diff(self._t)[:, None], q[:-1], qd[:-1], q[1:],
                                                                           qd[1:]), axis=0)])

    n_dof = property(lambda self: self.inner.n_dof)
    breakpoints_s = property(lambda self: np.unique(np.r_[self.inner.breakpoints_s, self.inner.breakpoints_s
                                                          + self.window_s]))

    def _held(self, t):
        """The plan at times t [s], at rest before 0 and after its end."""
        T = self.inner.duration_s
        q, qd, qdd = self.inner.sample(np.clip(t, 0.0, T))
        out = (t < 0.0) | (t > T)
        qd[out], qdd[out] = 0.0, 0.0
        return q, qd, qdd

    def _integral(self, t, q_t, qd_t):
        """integral_0^t q [rad*s] (q held outside [0, T]); q_t, qd_t: the held plan at t."""
        T = self.inner.duration_s
        tc = np.clip(t, 0.0, T)
        k = np.clip(np.searchsorted(self._t, tc, side="right") - 1, 0, len(self._t) - 1)
        qc, qdc, _ = self.inner.sample(tc)
        inside = self._Q[k] + _hermite_area((tc - self._t[k])[:, None], self._q[k], self._qd[k], qc, qdc)
        return inside + np.minimum(t, 0.0)[:, None] * self._q[0] + np.maximum(t - T, 0.0)[:, None] * self._q[-1]

    def sample(self, t_s):
        t = np.atleast_1d(np.asarray(t_s, float))
        w = self.window_s
        q1, qd1, _ = self._held(t)
        q0, qd0, _ = self._held(t - w)
        q = (self._integral(t, q1, qd1) - self._integral(t - w, q0, qd0)) / w
        return q, (q1 - q0) / w, (qd1 - qd0) / w


def _hermite_area(dt, qa, qda, qb, qdb):
    """integral of q over a step dt from its ends' values and slopes (exact for a cubic)."""
    return 0.5 * dt * (qa + qb) + dt**2 / 12.0 * (qda - qdb)


def feedforward_signals(drive, traj, t_s):
    """(joint torque [N*m], current [A], voltage [V]) (len(t), n) the drive's feedforward asks of its motors
    along traj: the inverse dynamics of its plant (arm + part + N^2 J_r, Drake CalcInverseDynamics) through
    the motor model backwards (dc_motor.motor_signals_from_joint_torque)."""
    q, qd, qdd = traj.sample(np.asarray(t_s, float))
    tau = inverse_dynamics(drive.id_plant, q, qd, qdd)
    cur, volt = np.zeros_like(q), np.zeros_like(q)
    for k in range(len(q)):
        volt[k], cur[k], _, _ = motor_signals_from_joint_torque(drive.params, tau[k], qd[k])
    return tau, cur, volt


def inverse_dynamics(plant, q, qd, qdd) -> np.ndarray:
    """(len(q), n) joint torques [N*m] of a continuous plant, as pydrake's InverseDynamics system computes its
    output (the feedforward's): CalcInverseDynamics with the force elements' contribution (gravity)."""
    ctx = plant.CreateDefaultContext()
    forces = MultibodyForces(plant)
    tau = np.zeros_like(np.atleast_2d(q))
    for k in range(len(tau)):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, qd[k])
        plant.CalcForceElementsContribution(ctx, forces)
        tau[k] = plant.CalcInverseDynamics(ctx, qdd[k], forces)
    return tau


def drive_load_ratio(drive, traj) -> float:
    """The largest |i|/I_max or |v|/V_max of the feedforward along traj (<= 1: the motors can follow it)."""
    t = np.arange(0.0, traj.duration_s + 1e-12, FIT_SAMPLE_S)
    _, i, v = feedforward_signals(drive, traj, t)
    mp = drive.params
    return float(max((np.abs(i) / mp.current_limit_A).max(), (np.abs(v) / mp.voltage_limit_V).max()))


def drive_fit_scale(drive, traj) -> float:
    """1 when the motors can follow traj's feedforward; else the smallest time scale (to FIT_REL_TOL) at
    which they can (ValueError beyond FIT_MAX_SCALE: the plan asks for more than the motors ever give)."""
    if drive is None or drive_load_ratio(drive, traj) <= 1.0:
        return 1.0
    if drive_load_ratio(drive, TimeScaledTrajectory(traj, FIT_MAX_SCALE)) > 1.0:
        raise ValueError(f"the plan needs more than the motors give even {FIT_MAX_SCALE:g}x slower")
    return smallest_holding_scale(1.0, FIT_MAX_SCALE,
                                  lambda k: drive_load_ratio(drive, TimeScaledTrajectory(traj, k)) <= 1.0, FIT_REL_TOL)


def closed_loop_reference(traj, feedforward: str, drive=None, time_step_s: float | None = None,
                          window_s: float = SHAPING_WINDOW_S):
    """The reference the loop is sent: traj itself unless feedforward is 'shaped'; then traj slowed until
    the drive's motors can follow it (drive_fit_scale; dc_motor only), shaped by two boxes of window_s / 2
    (it ends window_s later) and, given the plant's step time_step_s [s], as the sampled-data plant
    integrates it (SampledDataReference)."""
    if feedforward != "shaped":
        return traj
    k = drive_fit_scale(drive, traj)
    slowed = traj if k == 1.0 else TimeScaledTrajectory(traj, k)
    shaped = BoxShapedReference(BoxShapedReference(slowed, window_s / 2), window_s / 2)
    return shaped if time_step_s is None else SampledDataReference(shaped, time_step_s)
