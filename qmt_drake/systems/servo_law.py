"""The Dynamixel position loop compiled: the same per-period law as DynamixelPositionServo (firmware
PID + feedforward on quantised pulses, anti-windup, PWM limit; systems/dynamixel_servo.py) written
once as a symbolic update and run by a discrete SymbolicVectorSystem in C++, with no Python call per
servo period.

    CompiledServo(sheets, gains, control_period_s)   a Diagram with the Python system's ports:
        inputs  goal_position (n) [rad], joint_position (n) [rad]
        outputs voltage_command (n) [V], pwm (n) [-], position_error (n) [rad]

State, per joint, as the Python system's: integral of the error [pulse*samples], previous error
[pulses], PWM, previous goal [pulses], previous goal velocity [pulses/sample]. Pulse quantisation is
floor(x + 0.5), as in the Python law; tests/test_servo_law.py checks the two give the same run.
"""

from __future__ import annotations

import numpy as np
from pydrake import symbolic
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, Multiplexer, SymbolicVectorSystem

from qmt_drake.catalog import PULSES_PER_RAD, PWM_FULL_SCALE, ServoGains
from qmt_drake.errors import QmtInputError


def _pulses(angle, quantize: bool):
    x = angle * PULSES_PER_RAD
    return symbolic.floor(x + 0.5) if quantize else x


def servo_update(sheets, gains: ServoGains, quantize: bool = True):
    """(state variables, input variables, next-state expressions, output expressions) of n servos."""
    n = len(sheets)
    kpp, kpi, kpd = (k.tolist() for k in gains.firmware())
    kff1, kff2 = (k.tolist() for k in gains.feedforward())
    x = [symbolic.Variable(f"x{i}") for i in range(5 * n)]
    u = [symbolic.Variable(f"u{i}") for i in range(2 * n)]  # goal (n), measured position (n)
    nxt = [symbolic.Expression(0.0)] * (5 * n)
    for k in range(n):
        g = _pulses(u[k], quantize)
        e = g - _pulses(u[n + k], quantize)
        v = g - x[3 * n + k]
        acc = v - x[4 * n + k]
        if kpi[k] > 0:  # anti-windup: the integral term alone stays within the PWM limit
            cap = PWM_FULL_SCALE / kpi[k]
            integral = symbolic.min(symbolic.max(x[k] + e, -cap), cap)
        else:
            integral = symbolic.Expression(0.0)
        pwm = kpp[k] * e + kpi[k] * integral + kpd[k] * (e - x[n + k]) + kff1[k] * v + kff2[k] * acc
        nxt[k], nxt[n + k] = integral, e
        nxt[2 * n + k] = symbolic.min(symbolic.max(pwm, -PWM_FULL_SCALE), PWM_FULL_SCALE)
        nxt[3 * n + k], nxt[4 * n + k] = g, v
    v_per_pwm = [s.supply_voltage_V / PWM_FULL_SCALE for s in sheets]
    out = ([x[2 * n + k] * v_per_pwm[k] for k in range(n)] + [x[2 * n + k] + 0.0 for k in range(n)]
           + [x[n + k] / PULSES_PER_RAD for k in range(n)])
    return x, u, nxt, out


class CompiledServo:
    """n Dynamixel position loops as a Diagram of Drake primitives (module docstring). `system` is
    the Diagram to add to a builder; `gains`, `sheets`, `period_s` as the Python system's."""

    def __init__(self, sheets, gains: ServoGains, *, control_period_s: float, quantize: bool = True) -> None:
        sheets = tuple(sheets)
        n = len(sheets)
        if not control_period_s > 0:
            raise QmtInputError(f"servo control period must be positive, got {control_period_s} s")
        self.sheets, self.gains, self.period_s, self._n, self._quantize = sheets, gains, float(control_period_s), n, quantize
        x, u, nxt, out = servo_update(sheets, gains, quantize)
        b = DiagramBuilder()
        mux = b.AddNamedSystem("inputs", Multiplexer([n, n]))
        self.law = b.AddNamedSystem("servo_law", SymbolicVectorSystem(state=x, input=u, dynamics=nxt, output=out,
                                                                       time_period=self.period_s))
        demux = b.AddNamedSystem("outputs", Demultiplexer([n, n, n]))
        b.Connect(mux.get_output_port(0), self.law.get_input_port(0))
        b.Connect(self.law.get_output_port(0), demux.get_input_port(0))
        b.ExportInput(mux.get_input_port(0), "goal_position")
        b.ExportInput(mux.get_input_port(1), "joint_position")
        for i, name in enumerate(("voltage_command", "pwm", "position_error")):
            b.ExportOutput(demux.get_output_port(i), name)
        self.system = b.Build()
        self.system.set_name("servos")

    def state_at_rest(self, integral, error_pulses, pwm, goal_rad) -> np.ndarray:
        """As DynamixelPositionServo.state_at_rest."""
        x = np.ravel(goal_rad) * PULSES_PER_RAD
        g = np.floor(x + 0.5) if self._quantize else x
        return np.concatenate([np.ravel(integral), np.ravel(error_pulses), np.ravel(pwm), g, np.zeros(self._n)])

    def set_state(self, root_context, state) -> None:
        self.law.GetMyMutableContextFromRoot(root_context).SetDiscreteState(np.asarray(state, float))
