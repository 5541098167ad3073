"""A Dynamixel X-series servo's firmware position loop as a Drake LeafSystem (seed 002's CRANE-X7).

Model (ROBOTIS e-Manual, X-series control table, "Position PID Gain (80, 82, 84)"): in position
control mode the firmware runs a discrete PID on the position error in encoder pulses
(4096 pulses/rev, "Resolution" in the specifications) and writes a PWM command:

    e[k]   = goal_position_pulse - present_position_pulse          (integers)
    pwm[k] = K_PP e[k] + K_PI sum_{j<=k} e[j] + K_PD (e[k] - e[k-1]),   clipped to +-PWM_LIMIT
    K_PP = P / 128,  K_PI = I / 65536,  K_PD = D / 16                  (the constants include the
                                                                        sampling time)
    v[k]   = pwm[k] / 885 * V_supply                                (PWM Limit(36) default 885 = 100 %)

with the profile and feed-forward terms off (Profile Velocity = 0, FF gains 0: the defaults). The
goal position is held between updates. The integral is clamped so that its term alone cannot
exceed the PWM limit (anti-windup is not documented; this is an assumption).

Sampling period: the e-Manual does not state the position loop's rate. CONTROL_PERIOD_S = 1 ms is
an ASSUMPTION; the study sweeps it (studies/crane_tray.py) because the D gain's effect scales
with 1/period.

The motor behind the PWM is the project's DcMotorWithGear (dc_motor.py) with parameters from the
servo's datasheet (`ServoDatasheet.motor_params`): at supply V the datasheet gives the stall torque
tau_s, stall current I_s and no-load speed w0 at the output shaft. With tau_j = N eta Kt i and
back EMF Kt N qd (dc_motor.py):
    R = V / I_s,   Kt = V / (w0 N),   eta = tau_s / (I_s V / w0)
(eta lumps gear efficiency and friction: 0.63 for the XM540-W270, 0.72 for the XM430-W350), and the
current is clipped to the control table's default Current Limit(38) x 2.69 mA. By default the
co-simulation uses the lossless equivalent with the same torque-speed line (`motor_params`).

Datasheet values (ROBOTIS e-Manual specifications, at 12.0 V, the recommended supply):
- XM540-W270 (emanual.robotis.com/docs/en/dxl/x/xm540-w270, read via search): gear ratio 272.5:1,
  stall torque 10.6 N m at 4.4 A, no-load speed 30 rev/min; Current Limit default 2047 (5.51 A).
- XM430-W350 (emanual.robotis.com/docs/en/dxl/x/xm430-w350; checked against the page's source,
  github.com/ROBOTIS-GIT/emanual docs/en/dxl/x/xm430-w350.md): gear ratio 353.5:1, stall torque
  4.1 N m at 12.0 V and 2.3 A, no-load speed 46 rev/min; Current Limit(38) initial value 1193 x
  about 2.69 mA (3.21 A).

Ports (n servos)
    inputs
        goal_position     (n,) [rad]   goal position (joint angle) written to the servo
        joint_position    (n,) [rad]   the joint's true angle (quantised to pulses inside)
    outputs
        voltage_command   (n,) [V]     PWM duty times the supply voltage, to DcMotorWithGear
        pwm               (n,) [-]     PWM command in control-table units (+-885 = +-100 %)
        position_error    (n,) [rad]   goal minus measured position at the last update
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from qmt_drake.catalog import (  # noqa: F401 (the servo datasheets and units, re-exported)
    CONTROL_PERIOD_S,
    CRANE_X7_PLANAR_SERVOS,
    CURRENT_UNIT_A,
    PULSES_PER_RAD,
    PULSES_PER_REV,
    PWM_FULL_SCALE,
    RPM,
    SEED_GAINS_AFTER,
    SEED_GAINS_BEFORE,
    SERVO_CATALOG,
    XM430_W350,
    XM540_W270,
    ServoDatasheet,
    ServoGains,
)
from qmt_drake.errors import QmtInputError
from qmt_drake.systems.dc_motor import DcMotorParams


def motor_params(sheets, *, lossless_equivalent: bool = True,
                 efficiency_blend_speed_rad_s: float | None = None) -> DcMotorParams:
    """DcMotorParams for the servos' motors.

    lossless_equivalent=True (default): eta = 1 and R = Ke V / tau_s, which reproduces the
    datasheet's straight torque-speed line (stall torque at zero speed, no-load speed at zero
    torque) exactly; the current is scaled by I_s_model / I_s_datasheet and the current limit with
    it, so the torque at the limit is kept. Why: DcMotorWithGear applies eta only while motoring,
    and with eta = 0.63 the torque holding the arm against gravity jumps by 1/eta whenever the
    joint speed changes sign: at the hold the 1 ms loop chattered (joint speeds +-0.02 rad/s
    flipping every few ms, the bottle's normal force swinging 0.42-0.62 N).
    lossless_equivalent=False: R = V / I_s, eta = tau_s / (Ke I_s) (stall current exact, with the
    motoring/back-driving asymmetry); efficiency_blend_speed_rad_s makes that asymmetry continuous
    at zero speed (dc_motor.py, smooth efficiency)."""
    if lossless_equivalent:
        r = [s.back_emf_V_s_per_rad * s.supply_voltage_V / s.stall_torque_Nm for s in sheets]
        i_limit = [s.current_limit_A * (s.supply_voltage_V / ri) / s.stall_current_A for s, ri in zip(sheets, r)]
        eta = [1.0] * len(sheets)
    else:
        r = [s.resistance_ohm for s in sheets]
        i_limit = [s.current_limit_A for s in sheets]
        eta = [s.efficiency for s in sheets]
    return DcMotorParams(
        torque_constant_Nm_per_A=[s.back_emf_V_s_per_rad / s.gear_ratio for s in sheets],
        resistance_ohm=r,
        gear_ratio=[s.gear_ratio for s in sheets],
        voltage_limit_V=[s.supply_voltage_V for s in sheets],
        current_limit_A=i_limit,
        efficiency=eta,
        names=[s.model for s in sheets],
        efficiency_blend_speed_rad_s=efficiency_blend_speed_rad_s,
    )




class DynamixelPositionServo(LeafSystem):
    """n Dynamixel position loops; see the module docstring for the model, ports and units."""

    def __init__(self, sheets, gains: ServoGains, *, control_period_s: float = CONTROL_PERIOD_S,
                 quantize: bool = True):
        super().__init__()
        sheets = tuple(sheets)
        n = len(sheets)
        if not control_period_s > 0:
            raise QmtInputError(f"servo control period must be positive, got {control_period_s} s")
        for name in ("p", "i", "d"):
            if len(getattr(gains, name)) != n:
                raise QmtInputError(f"servo gains {name.upper()} has {len(getattr(gains, name))} entries "
                                    f"for {n} servos")
        self.sheets, self.gains, self.period_s, self._n = sheets, gains, float(control_period_s), n
        self._kpp, self._kpi, self._kpd = (k.tolist() for k in gains.firmware())
        self._kff1, self._kff2 = (k.tolist() for k in gains.feedforward())
        self._v_per_pwm = [s.supply_voltage_V / PWM_FULL_SCALE for s in sheets]
        self._quantize = quantize
        self._goal = self.DeclareVectorInputPort("goal_position", n)
        self._pos = self.DeclareVectorInputPort("joint_position", n)
        # state: [integral of e (pulse*samples) | previous e (pulses) | pwm | previous goal (pulses) |
        #         previous goal velocity (pulses/sample)]: the last two feed the feedforward terms
        self._state = self.DeclareDiscreteState(5 * n)
        self.DeclarePeriodicDiscreteUpdateEvent(self.period_s, 0.0, self._update)
        self.DeclareStateOutputPort("state", self._state)
        self.DeclareVectorOutputPort("voltage_command", n, self._voltage, {self.discrete_state_ticket(self._state)})
        self.DeclareVectorOutputPort("pwm", n, lambda c, o: o.SetFromVector(
            c.get_discrete_state(self._state).value()[2 * n:3 * n]), {self.discrete_state_ticket(self._state)})
        self.DeclareVectorOutputPort("position_error", n, lambda c, o: o.SetFromVector(
            np.asarray(c.get_discrete_state(self._state).value()[n:2 * n]) / PULSES_PER_RAD),
            {self.discrete_state_ticket(self._state)})

    def _pulses(self, angle_rad: float) -> float:
        x = angle_rad * PULSES_PER_RAD
        return float(math.floor(x + 0.5)) if self._quantize else x

    def _update(self, context, discrete_state):
        n = self._n
        x = context.get_discrete_state(self._state).value().tolist()
        goal = self._goal.Eval(context).tolist()
        pos = self._pos.Eval(context).tolist()
        out = [0.0] * (5 * n)
        for k in range(n):
            g = self._pulses(goal[k])
            e = g - self._pulses(pos[k])
            # target velocity and acceleration of the streamed goal (profile off: the goal itself is
            # the target trajectory), in pulses per sample and per sample^2
            v = g - x[3 * n + k]
            acc = v - x[4 * n + k]
            integral = x[k] + e
            if self._kpi[k] > 0:  # anti-windup: the integral term alone stays within the PWM limit
                cap = PWM_FULL_SCALE / self._kpi[k]
                integral = min(max(integral, -cap), cap)
            else:
                integral = 0.0
            pwm = (self._kpp[k] * e + self._kpi[k] * integral + self._kpd[k] * (e - x[n + k])
                   + self._kff1[k] * v + self._kff2[k] * acc)
            out[k], out[n + k], out[2 * n + k] = integral, e, min(max(pwm, -PWM_FULL_SCALE), PWM_FULL_SCALE)
            out[3 * n + k], out[4 * n + k] = g, v
        discrete_state.get_mutable_vector(self._state).SetFromVector(out)

    def _voltage(self, context, output: BasicVector):
        pwm = context.get_discrete_state(self._state).value()[2 * self._n:3 * self._n]
        output.SetFromVector([p * v for p, v in zip(pwm.tolist(), self._v_per_pwm)])

    def state_at_rest(self, integral, error_pulses, pwm, goal_rad) -> np.ndarray:
        """The discrete state of a loop at rest at goal_rad: the given integral, error [pulses] and
        PWM, the goal as the previous goal and no goal velocity (no feedforward kick)."""
        g = [self._pulses(x) for x in np.ravel(goal_rad)]
        return np.concatenate([np.ravel(integral), np.ravel(error_pulses), np.ravel(pwm), g, np.zeros(self._n)])

    def set_state(self, root_context, state) -> None:
        """Set this system's discrete state inside a diagram's root context."""
        self.GetMyMutableContextFromRoot(root_context).SetDiscreteState(np.asarray(state, float))

    def reset_at(self, context, goal_rad, position_rad) -> None:
        """Start without a derivative or feedforward kick: previous error = the current error, previous
        goal = the goal at rest, no integral."""
        g = [self._pulses(x) for x in np.ravel(goal_rad)]
        e = [gk - self._pulses(p) for gk, p in zip(g, np.ravel(position_rad))]
        context.SetDiscreteState(self._state, np.concatenate([np.zeros(self._n), e, np.zeros(self._n), g,
                                                              np.zeros(self._n)]))
