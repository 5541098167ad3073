"""Joint trajectory tracking: PID with anti-windup producing a motor voltage command.

Control law (per joint i, evaluated at the control period T_c with the latest measurement)

    e_m   = N * (q_des - q)            motor-side angle error [rad]
    ed_m  = N * (qd_des - qd)          motor-side speed error [rad/s]
    u     = Kp e_m + Ki z + Kd ed_m  [+ Ke N qd_des]  [+ tau_ff * R / (N eta Kt)]      [V]
    v_cmd = clip(u, -V_max, V_max)
    z[k+1] = z[k] + T_c e_m   unless the output is saturated and e_m pushes further into
                              saturation (conditional integration / clamping anti-windup)

Sampled law (`hold_period_s` = T_h > T_c, a firmware loop slower than the plant step T_c): u is computed at
sample instants only and held (zero-order hold) in between; a sample falls on the first update (period T_c)
at or after each k T_h, its voltage applies from that step on (no computation delay), and the integral then
grows by T_h e_m per sample. hold_period_s None (default): u is evaluated at every step, as before.
A held VOLTAGE drives a current (V - K_e N qd)/R that falls over the hold as the joint speeds up: the motors'
torque saws by b qdd (T_h - T_c) per hold (b = N^2 eta Kt^2 / R, the back-EMF damping), which on motors whose b
dominates the joint inertia (b/M ~ 90-260 1/s on the UR5 and Panda) saws the arm's acceleration by tens of percent.
`current_loop` models the amplifier's current loop instead: u is then a current command R i_cmd held over the hold,
and the output at every step is u + K_e N qd with the speed measured at that step, so i = i_cmd throughout.
A feedforward evaluated at the sample instant and held lags the plan by T_h/2 on average (a feedforward
ramp of slope s held by a zero-order hold is s (T_h - T_c)/2 short of the every-step law over the hold, s T_h/2
of a continuous one). `HoldCompensatedReference` gives the feedforward the reference's mean over the coming
hold instead, and `feedforward_velocity_port` lets the back-EMF feedforward read its speed from it (the P/D
terms keep the reference at the sample instant, where the measurement is; sim/spatial_actuation,
docs/spatial_drives.md).

Needs: estimated_state from a plant whose output ports are live (`use_sampled_output_ports=False`,
as `sim.plant.transfer_plant_config` sets): the integral is a discrete update that reads the plant
during its step; with sampled ports it would pair the next state with this step's reference.

Ports
    inputs
        desired_state        (2n,) [rad, rad/s]   joint-side q_des, qd_des (e.g. TrajectorySource)
        estimated_state      (2n,) [rad, rad/s]   joint-side q, qd (the arm's state output port)
        feedforward_torque   (n,)  [N*m]          joint torque feedforward (only if enabled)
        feedforward_velocity (n,)  [rad/s]        the back-EMF feedforward's desired speed (only with
                                                  feedforward_velocity_port; else desired_state's qd_des)
    output
        voltage_command      (n,)  [V]            to DcMotorWithGear.voltage_command
    state (only if any Ki != 0): discrete z (n,) [rad*s], the motor-side error integral; with hold_period_s
        also the held voltage (n,) [V] and the next sample time (1,) [s].

`primitive_pd_controller(pid)` builds the same law for a controller without integral term from
Drake primitives (MatrixGain, Adder, Saturation: no Python call per step), with the same ports
and the gains read from the JointPidController itself; the co-simulation uses it when it can.

Thesis gains (seed 000, Tables 2.1/4.1): Kp = [29.7, 5.5, 0.9], Ki = [0, 0, 0.45e-5],
Kd = [104, 19.3, 0.45], printed as "Nm", "Nm*s", "Nm/s" on the joint angle error.

Reading them in SI at the joint (tau = Kp e + Kd e_dot, N*m/rad and N*m*s/rad) gives the closed-loop
characteristic polynomial J s^2 + Kd s + Kp with J ~ 0.05 kg m^2 (ch.4 joint 1 incl. N^2 J_rotor):
poles -0.29 and -2080 rad/s. The slow pole ~ Kp/Kd = 0.29 rad/s (both joints: Kd/Kp = 3.5 s) is a
3.5 s time constant, longer than the whole 1.7 s motion: the arm could not follow the plan, while
the thesis reports accurate tracking (section 2.6 conclusions; Fig. 4.12, experiment vs target).
Any common rescaling of Kp and Kd (motor-side angle, volts instead of newton-metres, encoder
counts) keeps that ratio, so the two gains cannot share a time unit. The reading adopted here
(`PidGains.from_thesis`; eq. 2-23 calls the output tau_i, here it is the amplifier's command):

  * the gains act on the MOTOR-SIDE angle error (encoder on the motor shaft, N = 100) and produce
    the amplifier's VOLTAGE command: Kp in V/rad, Ki in V/(rad*s);
  * the derivative is the per-sample difference of the error at a 1 ms DSP period, i.e.
    Kd_SI = Kd * 1e-3 s [V*s/rad].

With the catalogue motors of `dc_motor.py` (static gain c = N eta Kt / R at the joint) the
characteristic polynomial per joint becomes

    J s^2 + (c N Kd_SI + b_emf) s + c N Kp = 0,    b_emf = N^2 eta Kt^2 / R  (back-EMF damping)

At the ch.4 start posture (full mass matrix, catalogue motors) the poles are -142, -387 +- 160j
(damping ratio 0.92) and -901 rad/s; for ch.2 -39, -151, -360 +- 177j, -645, -912 rad/s; the
literal SI reading gives -0.29 rad/s twice. A well-damped, stiff position loop of the kind an
experimenter tunes by hand, consistent with the accurate tracking the thesis shows (simulated: 11
mrad max error on ch.4, 29 mrad on ch.2's third joint, almost all of it the back-EMF velocity lag
b*qd/K; `back_emf_feedforward` removes it). `effective_joint_gains` gives K and D; the tests check
the poles against a numerical linearization of the Drake closed loop (studies/cosim_calibration.py
writes the pole table to out/cosim_calibration.json).

What is assumed rather than read from the thesis: the 1 ms derivative sample (the DSP period is not
given), the motor-side/volt units, and the motors (dc_motor.MOTOR_CATALOG); the damping ratio above
depends on all three (c and b_emf come from the motors). Pass other PidGains to try other readings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake import symbolic
from pydrake.systems.framework import BasicVector, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Multiplexer

from qmt_drake.errors import QmtInputError
from qmt_drake.systems.scalar_ops import FLOAT, SYMBOLIC, symbolic_law

THESIS_DERIVATIVE_SAMPLE_S = 1e-3


@dataclass
class PidGains:
    """Gains acting on the motor-side error, producing volts (SI)."""

    kp_V_per_rad: np.ndarray
    ki_V_per_rad_s: np.ndarray
    kd_V_s_per_rad: np.ndarray

    def __post_init__(self):
        self.kp_V_per_rad = np.atleast_1d(np.asarray(self.kp_V_per_rad, float))
        self.ki_V_per_rad_s = np.atleast_1d(np.asarray(self.ki_V_per_rad_s, float))
        self.kd_V_s_per_rad = np.atleast_1d(np.asarray(self.kd_V_s_per_rad, float))

    @property
    def n(self) -> int:
        return len(self.kp_V_per_rad)

    @classmethod
    def from_thesis(cls, kp, ki, kd, *, derivative_sample_s: float = THESIS_DERIVATIVE_SAMPLE_S):
        """The adopted reading of Table 2.1/4.1 gains (see module docstring)."""
        kp = np.atleast_1d(np.asarray(kp, float))
        ki = np.zeros_like(kp) if ki is None else np.atleast_1d(np.asarray(ki, float))
        return cls(kp, ki, np.atleast_1d(np.asarray(kd, float)) * derivative_sample_s)


def effective_joint_gains(gains: PidGains, motor) -> tuple[np.ndarray, np.ndarray]:
    """Joint-side stiffness [N*m/rad] and damping [N*m*s/rad] of PD + motor (quasi-static armature,
    motoring, unsaturated): K = c N Kp, D = c N Kd + N^2 eta Kt^2 / R with c = N eta Kt / R."""
    N, eta, Kt, R = motor.gear_ratio, motor.efficiency, motor.torque_constant_Nm_per_A, motor.resistance_ohm
    c = N * eta * Kt / R
    return c * N * gains.kp_V_per_rad, c * N * gains.kd_V_s_per_rad + N**2 * eta * Kt**2 / R


class JointPidController(LeafSystem):
    """PID with clamping anti-windup; see the module docstring for the law, ports and units."""

    def __init__(self, gains: PidGains, gear_ratio, voltage_limit_V, *, control_period_s: float = 1e-3,
                 motor=None, back_emf_feedforward: bool = False, torque_feedforward: bool = False,
                 hold_period_s: float | None = None, feedforward_velocity_port: bool = False,
                 current_loop: bool = False):
        """motor: a DcMotorParams, needed for either feedforward (Kt, R, efficiency). hold_period_s [s]: the
        sampled law's period (module docstring), at least control_period_s; None: evaluated every step.
        feedforward_velocity_port: the back-EMF feedforward reads the input feedforward_velocity.
        current_loop (a held law only, needs motor): the held u is the amplifier's current command R i_cmd [V]
        and the output at every step is u + K_e N qd (qd measured that step): a current loop that cancels the
        back EMF, so the motors' current stays i_cmd over the hold (module docstring)."""
        super().__init__()
        n = gains.n
        self._n = n
        self._g = gains
        self._N = np.broadcast_to(np.asarray(gear_ratio, float), (n,)).copy()
        self._Vmax = np.broadcast_to(np.asarray(voltage_limit_V, float), (n,)).copy()
        self._Tc = float(control_period_s)
        if (back_emf_feedforward or torque_feedforward) and motor is None:
            raise QmtInputError("feedforward needs the motor parameters (motor=DcMotorParams)")
        self._ke = None if not back_emf_feedforward else motor.torque_constant_Nm_per_A * self._N
        self._v_per_Nm = None
        if torque_feedforward:
            self._v_per_Nm = motor.resistance_ohm / (self._N * motor.efficiency * motor.torque_constant_Nm_per_A)
        self._pd_gain = np.hstack([np.diag(gains.kp_V_per_rad * self._N), np.diag(gains.kd_V_s_per_rad * self._N)])
        self._xd_in = self.DeclareVectorInputPort("desired_state", 2 * n)
        self._x_in = self.DeclareVectorInputPort("estimated_state", 2 * n)
        self._ff_in = self.DeclareVectorInputPort("feedforward_torque", n) if torque_feedforward else None
        if feedforward_velocity_port and not back_emf_feedforward:
            raise QmtInputError("feedforward_velocity_port without the back-EMF feedforward: nothing reads it")
        self._ffv_in = self.DeclareVectorInputPort("feedforward_velocity", n) if feedforward_velocity_port else None
        self._has_integral = bool(np.any(gains.ki_V_per_rad_s != 0.0))
        self._Th = None if hold_period_s is None else float(hold_period_s)
        if current_loop and (self._Th is None or motor is None or back_emf_feedforward):
            raise QmtInputError("current_loop is a held law's (hold_period_s) with the motor given and no back-EMF "
                                "feedforward (the loop cancels the measured speed's back EMF itself)")
        self._ke_loop = motor.torque_constant_Nm_per_A * self._N if current_loop else None
        if self._Th is not None and not self._Th >= self._Tc:
            raise QmtInputError(f"hold_period_s {self._Th} s is shorter than the control period {self._Tc} s")
        if self._has_integral:
            self._z = self.DeclareDiscreteState(n)
        if self._Th is not None:  # the held voltage and the next sample time, updated at every step
            self._held = self.DeclareDiscreteState(n)
            self._next = self.DeclareDiscreteState(1)
            self._eps = 1e-6 * self._Tc  # sample instants accumulate rounding; the steps are T_c apart
            self.DeclarePeriodicDiscreteUpdateEvent(self._Tc, 0.0, self._update_sampled)
        elif self._has_integral:
            self.DeclarePeriodicDiscreteUpdateEvent(self._Tc, 0.0, self._update_integral)
        self.DeclareVectorOutputPort("voltage_command", n, self._calc_voltage)

    def set_integral(self, context, z_rad_s) -> None:
        """Set the motor-side error integral z [rad*s] in this system's context (a start in equilibrium:
        sim/spatial_start.settle)."""
        context.get_mutable_discrete_state(self._z).SetFromVector(np.asarray(z_rad_s, float))

    def _unsaturated(self, context):
        err = self._xd_in.Eval(context) - self._x_in.Eval(context)
        n = self._n
        e = self._N * err[:n]
        u = self._pd_gain.dot(err)  # Kp N (q_des - q) + Kd N (qd_des - qd), one product
        if self._has_integral:
            u = u + self._g.ki_V_per_rad_s * context.get_discrete_state(self._z).get_value()
        if self._ke is not None:
            u = u + self._ke * (self._xd_in.Eval(context)[n:] if self._ffv_in is None else self._ffv_in.Eval(context))
        if self._ff_in is not None:
            u = u + self._v_per_Nm * self._ff_in.Eval(context)
        return u, e

    def _sampling_now(self, context) -> bool:
        return context.get_time() + self._eps >= context.get_discrete_state(self._next).get_value()[0]

    def _calc_voltage(self, context, output: BasicVector):
        if self._Th is not None and not self._sampling_now(context):  # between samples: the held voltage
            v = context.get_discrete_state(self._held).get_value()
        else:
            u, _ = self._unsaturated(context)
            v = np.minimum(np.maximum(u, -self._Vmax), self._Vmax)
        if self._ke_loop is not None:  # the current loop: + the back EMF of the speed measured at this step
            v = np.minimum(np.maximum(v + self._ke_loop * self._x_in.Eval(context)[self._n:], -self._Vmax), self._Vmax)
        output.SetFromVector(v)

    def _integrated(self, context, u, e, period_s: float):
        """z after one period_s of the error e, clamped (anti-windup) where u saturates and e pushes further."""
        z = context.get_discrete_state(self._z).get_value()
        pushing_out = ((u > self._Vmax) & (e > 0)) | ((u < -self._Vmax) & (e < 0))
        return np.where(pushing_out, z, z + period_s * e)

    def _update_integral(self, context, discrete_state):
        u, e = self._unsaturated(context)
        discrete_state.get_mutable_vector(self._z).SetFromVector(self._integrated(context, u, e, self._Tc))

    def _update_sampled(self, context, discrete_state):
        if not self._sampling_now(context):
            return
        u, e = self._unsaturated(context)
        discrete_state.get_mutable_vector(self._held).SetFromVector(np.minimum(np.maximum(u, -self._Vmax), self._Vmax))
        t_next = context.get_discrete_state(self._next).get_value()[0] + self._Th
        discrete_state.get_mutable_vector(self._next).SetFromVector([t_next])
        if self._has_integral:
            discrete_state.get_mutable_vector(self._z).SetFromVector(self._integrated(context, u, e, self._Th))


HOLD_COMPENSATIONS = ("mean", "midpoint", "none")  # what a held law's feedforward is evaluated on (the first: default)


def hold_offsets(hold_period_s: float, time_step_s: float, mode: str = "mean") -> np.ndarray:
    """The times [s] after a sample instant at which a held feedforward sees the reference (HoldCompensatedReference):
    "mean": the hold's m plant steps j h, j < m (m = ceil(T_h / h)); "midpoint": their middle, (m - 1) h / 2."""
    if mode not in HOLD_COMPENSATIONS[:2]:
        raise QmtInputError(f"hold compensation {mode!r}: choose one of {', '.join(HOLD_COMPENSATIONS[:2])}")
    if not 0 < time_step_s <= hold_period_s:
        raise QmtInputError(f"hold period {hold_period_s} s and plant step {time_step_s} s: need 0 < step <= period")
    m = int(np.ceil(hold_period_s / time_step_s - 1e-6))  # the steps a sample's voltage is held over
    return np.arange(m) * time_step_s if mode == "mean" else np.array([(m - 1) * time_step_s / 2])


class HoldCompensatedReference(LeafSystem):
    """The plan as a feedforward held for hold_period_s = T_h from each sample instant t should see it (module
    docstring); the plant steps time_step_s = h, so the hold spans the m steps t + j h < t + T_h. Outputs
    desired_state (2n) [rad, rad/s] and desired_acceleration (n) [rad/s^2] at time t:

        "mean"      the mean of the reference at the hold's m steps: what the every-step law's feedforward
                    would ask over the hold, averaged (to first order; the torque is not linear in the state).
                    Where the acceleration jumps inside the hold it takes each side's share;
        "midpoint"  the reference at the middle of the hold's steps, t + (m - 1) h / 2 (t + T_h/2 as h -> 0):
                    one side of such a jump for the whole hold.

    pp: the reference positions as a PiecewisePolynomial whose derivative is the speed (CubicHermite), acc: its
    acceleration; both held at their end values beyond it, as Drake evaluates them."""

    def __init__(self, pp, acc, hold_period_s: float, time_step_s: float, mode: str = "mean"):
        super().__init__()
        self._offsets = hold_offsets(hold_period_s, time_step_s, mode)
        self._pp, self._acc = pp.Clone(), acc.Clone()
        n = pp.rows()
        self.DeclareVectorOutputPort("desired_state", 2 * n, self._calc_state)
        self.DeclareVectorOutputPort("desired_acceleration", n, self._calc_acceleration)

    def update_reference(self, pp, acc) -> None:
        """Replace the reference (as TrajectorySource.UpdateTrajectory does): sim/spatial_start.settle solves the
        start with every reference at rest, this one included."""
        self._pp, self._acc = pp.Clone(), acc.Clone()

    def _calc_state(self, context, output: BasicVector):
        ts = context.get_time() + self._offsets
        q = np.mean([self._pp.value(t).ravel() for t in ts], axis=0)
        output.SetFromVector(np.r_[q, np.mean([self._pp.EvalDerivative(t, 1).ravel() for t in ts], axis=0)])

    def _calc_acceleration(self, context, output: BasicVector):
        output.SetFromVector(np.mean([self._acc.value(t).ravel() for t in context.get_time() + self._offsets], axis=0))


def pd_voltage(pid: JointPidController, x_des, x, feedforward_torque=None, ops=FLOAT) -> list:
    """`pid`'s law without the integral, per joint: v = clip(Kp N (q_des - q) + Kd N (qd_des - qd)
    [+ Ke N qd_des] [+ tau_ff R / (N eta Kt)], +-V_max) [V]; x_des, x: the 2n desired / estimated
    states (floats or drake symbolic Expressions with ops=SYMBOLIC, systems.scalar_ops)."""
    if pid._ffv_in is not None:
        raise QmtInputError("the compiled law reads the back-EMF feedforward's speed from desired_state; "
                         "feedforward_velocity_port is the held law's (JointPidController)")
    n = pid._n
    out = []
    for k in range(n):
        u = pid._pd_gain[k, k] * (x_des[k] - x[k]) + pid._pd_gain[k, n + k] * (x_des[n + k] - x[n + k])
        if pid._ke is not None:
            u = u + pid._ke[k] * x_des[n + k]
        if pid._v_per_Nm is not None:
            u = u + pid._v_per_Nm[k] * feedforward_torque[k]
        out.append(ops.clip(u, -pid._Vmax[k], pid._Vmax[k]))
    return out


def pd_law_inputs(pid: JointPidController):
    """Symbolic variables of the PD law's inputs: (x_des (2n), x (2n), feedforward torque (n) or None)."""
    n = pid._n
    x_des = [symbolic.Variable(f"desired_state_{k}") for k in range(2 * n)]
    x = [symbolic.Variable(f"estimated_state_{k}") for k in range(2 * n)]
    ff = [symbolic.Variable(f"feedforward_torque_{k}") for k in range(n)] if pid._v_per_Nm is not None else None
    return x_des, x, ff


def pd_law_diagram(pid: JointPidController, name: str, more_outputs=None, *,
                   host_has_continuous_state: bool = False):
    """A Diagram with JointPidController's input ports (desired_state, estimated_state[,
    feedforward_torque]) whose output voltage_command is `pd_voltage` compiled into a
    SymbolicVectorSystem; more_outputs(voltage, x) -> {port name: expressions} adds laws built on the
    same (symbolic) voltage and estimated state, each its own system (evaluated only when read)."""
    n = pid._n
    x_des, x, ff = pd_law_inputs(pid)
    voltage = pd_voltage(pid, x_des, x, ff, SYMBOLIC)
    laws = {"voltage_command": voltage, **(more_outputs(voltage, x) if more_outputs else {})}
    b = DiagramBuilder()
    widths = [2 * n, 2 * n] + ([n] if ff is not None else [])
    inputs = b.AddNamedSystem("inputs", Multiplexer(widths))
    for k, port in enumerate(("desired_state", "estimated_state", "feedforward_torque")[:len(widths)]):
        b.ExportInput(inputs.get_input_port(k), port)
    for port, expressions in laws.items():
        law = b.AddNamedSystem(port, symbolic_law(x_des + x + (ff or []), expressions,
                                                  host_has_continuous_state=host_has_continuous_state))
        b.Connect(inputs.get_output_port(), law.get_input_port())
        b.ExportOutput(law.get_output_port(), port)
    d = b.Build()
    d.set_name(name)
    return d


def primitive_pd_controller(pid: JointPidController, *, host_has_continuous_state: bool = False):
    """`pid`'s law (`pd_voltage`) compiled into a SymbolicVectorSystem, as a Diagram with
    JointPidController's port names (desired_state, estimated_state[, feedforward_torque] ->
    voltage_command); None when pid has an integral term (its anti-windup is a conditional update).
    Equal to pid's output up to rounding (tests/test_cosim.py)."""
    if pid._has_integral:
        return None
    return pd_law_diagram(pid, "pd_controller", host_has_continuous_state=host_has_continuous_state)
