"""DC motors with a gear reducer (harmonic drive), one per joint, as one Drake LeafSystem.

Model, per joint i (motor side unless noted; SI units throughout)

    v      = clip(v_cmd, -V_max, V_max)                      terminal voltage [V]
    w_m    = N * qd                                           motor speed [rad/s], qd joint speed
    quasi-static armature (default, L -> 0):
        i  = clip((v - Ke * w_m) / R, -I_max, I_max)          current [A]
    with inductance (optional continuous state i):
        L di/dt = v - R i - Ke w_m,   output current clipped to +-I_max
    tau_m  = Kt * i                                           motor torque [N*m]
    tau_j  = N * eta * tau_m      if tau_m * qd >= 0 (motor drives the load)
           = N * tau_m / eta_b    otherwise (load back-drives the gear)      joint torque [N*m]

eta is the forward (motoring) efficiency. The back-driving efficiency eta_b defaults to 1
(no loss): a torque gain that jumps from eta to 1/eta at zero speed made the stiff 1 ms
position loop chatter at rest (a limit cycle at the Nyquist rate), so only the motoring loss
is modelled unless `back_drive_efficiency` is set.

Smooth efficiency (optional, `efficiency_blend_speed_rad_s` = w_b > 0, joint side): the switch
above still makes a load held against gravity (tau_m of one sign, qd dithering about zero) see
its joint torque jump by the factor 1/(eta eta_b) each time qd changes sign. With w_b the gain
moves continuously from the back-driven to the motoring value over |qd| ~ w_b:
    tau_j  = N tau_m (1/eta_b + (eta - 1/eta_b) s),   s = (1 + tanh(sign(tau_m) qd / w_b)) / 2
(s = 1 motoring, 0 back-driven, 1/2 at rest: the mean of the two gains), a regularised
(tanh) version of the switch, like the usual regularisation of Coulomb friction at zero speed.
Beyond a few w_b the model equals the switched one (|s - step| < 2.5e-3 at 3 w_b). None (the
default) keeps the switched model, which every study so far used.
    P_el   = v * i                                            electrical power [W]

Ke = Kt in SI (V*s/rad = N*m/A). The rotor inertia is NOT in this system: it stays in the plant as
the joint actuator's reflected inertia (drake:rotor_inertia, drake:gear_ratio in the URDF).

`motor_signals_from_joint_torque` inverts the model: given the joint torque a motor actually
delivered and the joint speed, it returns the terminal voltage, current, motor torque and
electrical power that go with it (quasi-static armature). `AppliedMotorSignals` is that inverse as a
LeafSystem; the co-simulation uses it when the loop's velocity feedback is stepped implicitly
(sim/actuation.py, `implicit_loop_damping`), where the torque applied over a step is known only after it.

Current-command mode (`command="current"`, an ideal current amplifier): the input is the current;
it is clipped to +-I_max and to what the supply can push against the back EMF,
(+-V_max - Ke w_m) / R, and the terminal voltage is v = R i + Ke w_m.

Needs: joint_velocity from the arm's state (a Demultiplexer of the plant's state port) and
joint_torque into the plant's actuation input. Driving a discrete plant directly (explicitly) with
the thesis's stiff gains is stable only at steps <= 1 ms; at larger steps wire it through
`sim.actuation.add_implicit_damping_actuation` (and `sim.plant.move_loop_damping_into_plant`
before Finalize).

Ports
    inputs
        voltage_command   (n,) [V]      commanded terminal voltage (clipped to +-V_max); named
                                        current_command (n,) [A] in current-command mode
        joint_velocity    (n,) [rad/s]  joint-side speed, for the back EMF
    outputs
        joint_torque      (n,) [N*m]    torque at the joint, to MultibodyPlant actuation
        motor_torque      (n,) [N*m]    motor-side electromagnetic torque Kt*i
        current           (n,) [A]      armature current
        electrical_power  (n,) [W]      v*i (negative when regenerating)

Motor parameters (`MOTOR_CATALOG`) are small coreless DC motors of the class the thesis used with
1/100 harmonic drives (seed 000 gives only rotor inertia, gear ratio and rated torque, no motor
model). The numbers are catalogue values of maxon RE-series / Faulhaber SR-series motors as written
in the manufacturers' printed catalogues (maxon "Program 2012/13", Faulhaber "DC-Micromotors");
they were written from those catalogue tables, not re-read from a datasheet in this repository, so
treat them as representative of the class, not as the thesis's motors. Each is checked for internal
consistency in the tests (stall torque = Kt*V/R, no-load speed = V/Ke).
Harmonic drive efficiency 0.7: Harmonic Drive CSF/CSG-14, ratio 100, catalogue efficiency curve at
rated torque and 1000-2000 rpm input is about 0.65-0.75.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from pydrake import symbolic
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Multiplexer, PassThrough

from qmt_drake.catalog import HARMONIC_DRIVE_EFFICIENCY, MOTOR_CATALOG, MotorDatasheet, motor_for_rated_torque  # noqa: F401 (re-exported)
from qmt_drake.errors import QmtInputError
from qmt_drake.systems.scalar_ops import FLOAT, SYMBOLIC, symbolic_law


@dataclass
class DcMotorParams:
    """Per-joint parameter arrays (length n), motor side, SI."""

    torque_constant_Nm_per_A: np.ndarray
    resistance_ohm: np.ndarray
    gear_ratio: np.ndarray
    voltage_limit_V: np.ndarray
    current_limit_A: np.ndarray
    efficiency: np.ndarray
    inductance_H: np.ndarray | None = None  # None: quasi-static armature
    back_drive_efficiency: float = 1.0
    efficiency_blend_speed_rad_s: float | None = None  # None: switched gain; > 0: smooth (docstring)
    names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        for k in ("torque_constant_Nm_per_A", "resistance_ohm", "gear_ratio", "voltage_limit_V",
                  "current_limit_A", "efficiency", "inductance_H"):
            if k != "inductance_H" or self.inductance_H is not None:
                setattr(self, k, np.atleast_1d(np.asarray(getattr(self, k), dtype=float)))
        if self.torque_constant_Nm_per_A.ndim != 1:
            raise QmtInputError(f"DcMotorParams.torque_constant_Nm_per_A has shape "
                                f"{self.torque_constant_Nm_per_A.shape}; give one number per joint")
        n = self.n
        for k in ("resistance_ohm", "gear_ratio", "voltage_limit_V", "current_limit_A", "efficiency", "inductance_H"):
            if getattr(self, k) is not None and getattr(self, k).shape != (n,):
                raise QmtInputError(f"DcMotorParams.{k} has shape {getattr(self, k).shape}, expected ({n},)")
        # a zero, negative or NaN inductance or back-drive efficiency ran without a word: an armature current
        # that grows without bound, a gear that makes energy when driven backwards
        if self.inductance_H is not None and not np.all(np.isfinite(self.inductance_H) & (self.inductance_H > 0)):
            raise QmtInputError(f"DcMotorParams.inductance_H {self.inductance_H.tolist()} must be finite and positive "
                                "for every joint (or None: the quasi-static armature)")
        eta_b = np.asarray(self.back_drive_efficiency, dtype=float)
        if not np.all(np.isfinite(eta_b) & (eta_b > 0) & (eta_b <= 1)):
            raise QmtInputError(f"DcMotorParams.back_drive_efficiency {self.back_drive_efficiency!r} must be in (0, 1]")
        for k in ("torque_constant_Nm_per_A", "resistance_ohm", "gear_ratio", "voltage_limit_V", "current_limit_A"):
            v = getattr(self, k)  # a zero or negative resistance divided its way into inf/NaN torques, silently
            finite = k not in ("voltage_limit_V", "current_limit_A")  # (an unlimited supply: inf)
            if not np.all(v > 0) or (finite and not np.all(np.isfinite(v))):
                raise QmtInputError(f"DcMotorParams.{k} {v.tolist()} must be {'finite and ' if finite else ''}positive "
                                    "for every joint")
        if not np.all((self.efficiency > 0) & (self.efficiency <= 1)):
            raise QmtInputError(f"DcMotorParams.efficiency {self.efficiency.tolist()} (the gearbox's) must be in "
                                "(0, 1] for every joint")
        blend = self.efficiency_blend_speed_rad_s
        if blend is not None and not (np.isfinite(blend) and blend > 0):
            raise QmtInputError(f"DcMotorParams.efficiency_blend_speed_rad_s {blend!r} must be finite and positive "
                                "(or None for the switched gain)")

    @property
    def n(self) -> int:
        return len(self.torque_constant_Nm_per_A)

    @classmethod
    def from_datasheets(cls, sheets: list[MotorDatasheet], gear_ratio, *,
                        efficiency: float = HARMONIC_DRIVE_EFFICIENCY,
                        with_inductance: bool = False) -> DcMotorParams:
        return cls(
            torque_constant_Nm_per_A=[s.torque_constant_Nm_per_A for s in sheets],
            resistance_ohm=[s.resistance_ohm for s in sheets],
            gear_ratio=np.broadcast_to(np.asarray(gear_ratio, float), (len(sheets),)).copy(),
            voltage_limit_V=[s.nominal_voltage_V for s in sheets],
            current_limit_A=[s.max_current_A for s in sheets],
            efficiency=[efficiency] * len(sheets),
            inductance_H=[s.inductance_H for s in sheets] if with_inductance else None,
            names=[s.name for s in sheets],
        )

    @classmethod
    def for_rated_torques(cls, rated_torque_Nm, gear_ratio, **kw) -> DcMotorParams:
        """Pick one catalogue motor per joint from the thesis's rated motor torques [N*m]."""
        return cls.from_datasheets([motor_for_rated_torque(t) for t in np.atleast_1d(rated_torque_Nm)],
                                   gear_ratio, **kw)

    def joint_torque_per_volt_stall(self) -> np.ndarray:
        """Static gain N*eta*Kt/R [N*m/V] at zero speed (motoring)."""
        return self.gear_ratio * self.efficiency * self.torque_constant_Nm_per_A / self.resistance_ohm


class MotorJoint(NamedTuple):
    """One joint's motor and gear constants (SI, motor side unless noted), as the per-joint laws take them."""

    voltage_limit_V: float
    resistance_ohm: float
    back_emf_per_joint_speed: float  # Ke N [V*s/rad]
    current_limit_A: float
    torque_constant_Nm_per_A: float
    gear_ratio: float
    efficiency: float
    back_drive_efficiency: float
    blend_speed_rad_s: float | None


def motor_joints(params: DcMotorParams) -> list[MotorJoint]:
    p = params
    return [MotorJoint(*(float(x) for x in row), p.efficiency_blend_speed_rad_s) for row in zip(
        p.voltage_limit_V, p.resistance_ohm, p.torque_constant_Nm_per_A * p.gear_ratio, p.current_limit_A,
        p.torque_constant_Nm_per_A, p.gear_ratio, p.efficiency, np.broadcast_to(p.back_drive_efficiency, (p.n,)))]


def gear_gain(tau_m, qd, efficiency, back_drive_efficiency, blend_speed_rad_s=None, ops=FLOAT):
    """tau_j / (N tau_m) for one joint: eta while motoring (tau_m qd >= 0), 1/eta_b while
    back-driven; with blend_speed_rad_s the smooth blend of the module docstring. Floats, or drake
    symbolic Expressions with ops=SYMBOLIC (systems.scalar_ops)."""
    if blend_speed_rad_s is None:
        return ops.where(tau_m * qd >= 0.0, lambda: efficiency, lambda: 1.0 / back_drive_efficiency)
    x = ops.where(tau_m >= 0.0, lambda: qd / blend_speed_rad_s, lambda: -qd / blend_speed_rad_s)
    s = 0.5 * (1.0 + ops.tanh(x))
    return 1.0 / back_drive_efficiency + (efficiency - 1.0 / back_drive_efficiency) * s


def motor_forward(command_V, qd, joint: MotorJoint, ops=FLOAT, armature_current_A=None):
    """One joint driven by a terminal-voltage command [V] at joint speed qd [rad/s]: (v [V], i [A],
    tau_m [N*m], tau_j [N*m], P_el [W]) of the module docstring's model (quasi-static armature, or
    the given armature current with inductance). Floats, or symbolic Expressions with ops=SYMBOLIC."""
    j = joint
    v = ops.clip(command_V, -j.voltage_limit_V, j.voltage_limit_V)
    i = (v - j.back_emf_per_joint_speed * qd) / j.resistance_ohm if armature_current_A is None else armature_current_A
    i = ops.clip(i, -j.current_limit_A, j.current_limit_A)
    tau_m = j.torque_constant_Nm_per_A * i
    gain = gear_gain(tau_m, qd, j.efficiency, j.back_drive_efficiency, j.blend_speed_rad_s, ops)
    return v, i, tau_m, tau_m * (j.gear_ratio * gain), v * i


def motor_inverse(tau_j, qd, joint: MotorJoint, ops=FLOAT):
    """One joint, the model backwards: (v [V], i [A], tau_m [N*m], P_el [W]) of a motor delivering
    tau_j [N*m] at qd [rad/s] (tau_m has the sign of tau_j: the gain is positive; no limits)."""
    j = joint
    tau_m = tau_j / (j.gear_ratio * gear_gain(tau_j, qd, j.efficiency, j.back_drive_efficiency, j.blend_speed_rad_s,
                                                ops))
    i = tau_m / j.torque_constant_Nm_per_A
    v = j.resistance_ohm * i + j.torque_constant_Nm_per_A * j.gear_ratio * qd
    return v, i, tau_m, v * i


def motor_signals_from_joint_torque(params: DcMotorParams, joint_torque_Nm, joint_velocity_rad_s):
    """(v [V], i [A], tau_m [N*m], P_el [W]) arrays of motors that deliver joint_torque_Nm at
    joint_velocity_rad_s: tau_m = tau_j / (N eta) while motoring (tau_j * qd >= 0), tau_j * eta_b / N
    while back-driven (or the smooth gain, `gear_gain`); i = tau_m / Kt; v = R i + Ke N qd (quasi-static armature; L di/dt,
    ~0.1-0.2 ms, is left out); P_el = v i. No limit is applied: the result says what the motors had
    to do."""
    tau = np.broadcast_to(np.asarray(joint_torque_Nm, float), (params.n,)).tolist()
    qd = np.broadcast_to(np.asarray(joint_velocity_rad_s, float), (params.n,)).tolist()
    rows = [motor_inverse(t, w, j) for t, w, j in zip(tau, qd, motor_joints(params))]
    return tuple(np.array(col) for col in zip(*rows))


class AppliedMotorSignals(LeafSystem):
    """Motor-side signals of a joint torque the motors delivered (`motor_signals_from_joint_torque`).

    Ports
        inputs
            applied_joint_torque  (n,) [N*m]    torque the motors delivered at the joints
            joint_velocity        (n,) [rad/s]  joint-side speed
        outputs
            joint_torque      (n,) [N*m]  the input, passed through
            voltage           (n,) [V]    terminal voltage R i + Ke N qd
            motor_torque      (n,) [N*m]  Kt i
            current           (n,) [A]
            electrical_power  (n,) [W]    v i
    """

    def __init__(self, params: DcMotorParams):
        super().__init__()
        self.params = params
        n = params.n
        self._n = n
        self._joints = motor_joints(params)
        self._tau_in = self.DeclareVectorInputPort("applied_joint_torque", n)
        self._qd_in = self.DeclareVectorInputPort("joint_velocity", n)
        self.DeclareVectorOutputPort("joint_torque", n, lambda c, o: o.SetFromVector(self._tau_in.Eval(c)))
        for k, name in enumerate(("voltage", "current", "motor_torque", "electrical_power")):
            self.DeclareVectorOutputPort(name, n, lambda c, o, k=k: o.SetFromVector(
                [row[k] for row in self._rows_now(c)]))

    def _rows_now(self, context) -> list[tuple]:
        # Plain floats per joint, recomputed per output (the monitor reads two per step): without a
        # cache entry, one Python call and one array allocation fewer per output evaluation.
        return [motor_inverse(t, w, j) for t, w, j in zip(self._tau_in.Eval(context).tolist(),
                                                           self._qd_in.Eval(context).tolist(), self._joints)]


class DcMotorWithGear(LeafSystem):
    """n DC motors with gears; see the module docstring for the model, ports and units."""

    def __init__(self, params: DcMotorParams, command: str = "voltage"):
        super().__init__()
        if command not in ("voltage", "current"):
            raise QmtInputError(f"command must be 'voltage' or 'current', got {command!r}")
        if command == "current" and params.inductance_H is not None:
            raise QmtInputError("current-command mode uses the quasi-static armature (inductance_H=None)")
        self._current_mode = command == "current"
        self.params = p = params
        n = p.n
        self._n = n
        self._Kt = p.torque_constant_Nm_per_A
        self._R = p.resistance_ohm
        self._N = p.gear_ratio
        self._eta = p.efficiency
        self._Vmax = p.voltage_limit_V
        self._Imax = p.current_limit_A
        self._L = p.inductance_H
        self._Ke_N = self._Kt * self._N  # back EMF per joint speed [V*s/rad] (Ke = Kt in SI)
        self._blend = p.efficiency_blend_speed_rad_s
        self._eta_b = float(p.back_drive_efficiency)
        self._joints = motor_joints(p)
        self._v_in = self.DeclareVectorInputPort(f"{command}_command", n)
        self._qd_in = self.DeclareVectorInputPort("joint_velocity", n)
        if self._L is not None:
            self.DeclareContinuousState(n)
        # Each output evaluates the model itself: per plant step only joint_torque is read, and a
        # cache entry would add a Python call and an array allocation per step.
        self.DeclareVectorOutputPort("joint_torque", n, lambda c, o: o.SetFromVector(self._signal(c, 3)))
        self.DeclareVectorOutputPort("motor_torque", n, lambda c, o: o.SetFromVector(self._signal(c, 2)))
        self.DeclareVectorOutputPort("current", n, lambda c, o: o.SetFromVector(self._signal(c, 1)))
        self.DeclareVectorOutputPort("electrical_power", n, lambda c, o: o.SetFromVector(self._signal(c, 4)))

    # --- model -----------------------------------------------------------------------------
    def _voltage(self, context) -> np.ndarray:
        return np.minimum(np.maximum(self._v_in.Eval(context), -self._Vmax), self._Vmax)

    def DoCalcTimeDerivatives(self, context, derivatives):
        if self._L is None:
            return
        v = self._voltage(context)
        i = context.get_continuous_state_vector().CopyToVector()
        i_dot = (v - self._R * i - self._Ke_N * self._qd_in.Eval(context)) / self._L
        # Current limit as a hard stop of the state (the amplifier's current loop).
        i_dot = np.where((i >= self._Imax) & (i_dot > 0), 0.0, i_dot)
        i_dot = np.where((i <= -self._Imax) & (i_dot < 0), 0.0, i_dot)
        derivatives.get_mutable_vector().SetFromVector(i_dot)

    def _signals(self, context) -> list[float]:
        """[v (n), i (n), tau_m (n), tau_j (n), P_el (n)] as plain floats.

        Per joint in plain floats: for the 2-3 joints here this is several times faster than numpy
        on tiny arrays, and it runs once per plant step."""
        cmd = self._v_in.Eval(context).tolist()
        qd = self._qd_in.Eval(context).tolist()
        i_state = context.get_continuous_state_vector().CopyToVector().tolist() if self._L is not None else None
        n = self._n
        out = [0.0] * (5 * n)
        for k, joint in enumerate(self._joints):
            if self._current_mode:
                v_max, r, ke_n = joint.voltage_limit_V, joint.resistance_ohm, joint.back_emf_per_joint_speed
                emf = ke_n * qd[k]
                i = min(max(cmd[k], (-v_max - emf) / r), (v_max - emf) / r)
                i = min(max(i, -joint.current_limit_A), joint.current_limit_A)
                v = r * i + emf
                tau_m = joint.torque_constant_Nm_per_A * i
                tau_j = tau_m * (joint.gear_ratio * gear_gain(tau_m, qd[k], joint.efficiency,
                                                              joint.back_drive_efficiency, joint.blend_speed_rad_s))
                p_el = v * i
            else:
                v, i, tau_m, tau_j, p_el = motor_forward(cmd[k], qd[k], joint, FLOAT,
                                                         None if i_state is None else i_state[k])
            out[k], out[n + k], out[2 * n + k], out[3 * n + k], out[4 * n + k] = v, i, tau_m, tau_j, p_el
        return out

    def _signal(self, context, k: int) -> list[float]:
        n = self._n
        return self._signals(context)[k * n:(k + 1) * n]


def _per_joint_laws_diagram(name: str, params: DcMotorParams, law, input_names: tuple[str, str], outputs: dict,
                            host_has_continuous_state: bool, pass_through_first: str | None = None):
    """A Diagram of Drake primitives: its two (n,) inputs (input_names) feed, per joint, the scalar
    law(input_0, input_1, MotorJoint, SYMBOLIC), whose results' entries outputs {port name: index}
    are each compiled into their own stateless SymbolicVectorSystem (evaluating one output computes
    nothing else); pass_through_first exports the first input again under that name."""
    n = params.n
    u = [symbolic.Variable(f"{input_names[0]}_{k}") for k in range(n)]
    qd = [symbolic.Variable(f"{input_names[1]}_{k}") for k in range(n)]
    rows = [law(a, w, joint, SYMBOLIC) for a, w, joint in zip(u, qd, motor_joints(params))]
    b = DiagramBuilder()
    inputs = b.AddNamedSystem("inputs", Multiplexer([n, n]))
    b.ExportInput(inputs.get_input_port(0), input_names[0])
    b.ExportInput(inputs.get_input_port(1), input_names[1])
    for out_name, k in outputs.items():
        system = b.AddNamedSystem(out_name, symbolic_law(u + qd, [row[k] for row in rows],
                                                         host_has_continuous_state=host_has_continuous_state))
        b.Connect(inputs.get_output_port(), system.get_input_port())
        b.ExportOutput(system.get_output_port(), out_name)
    if pass_through_first is not None:
        through = b.AddNamedSystem("pass_through", PassThrough(n))
        b.ConnectInput(input_names[0], through.get_input_port())
        b.ExportOutput(through.get_output_port(), pass_through_first)
    diagram = b.Build()
    diagram.set_name(name)
    return diagram


def dc_motors_as_primitives(params: DcMotorParams, *, host_has_continuous_state: bool = False):
    """DcMotorWithGear in its default mode (voltage command, quasi-static armature; switched or
    blended gear efficiency) as a Diagram of Drake primitives with the same ports: the model's one
    formula (`motor_forward`) compiled into SymbolicVectorSystems, no Python per step.
    host_has_continuous_state: see scalar_ops.symbolic_law."""
    if params.inductance_H is not None:
        raise QmtInputError("dc_motors_as_primitives models the quasi-static armature; use DcMotorWithGear with "
                         "inductance_H")
    return _per_joint_laws_diagram(
        "motors", params, motor_forward, ("voltage_command", "joint_velocity"),
        {"joint_torque": 3, "motor_torque": 2, "current": 1, "electrical_power": 4}, host_has_continuous_state)


def applied_motor_signals_as_primitives(params: DcMotorParams, *, host_has_continuous_state: bool = False):
    """AppliedMotorSignals (`motor_inverse`) as a Diagram of Drake primitives with the same ports."""
    return _per_joint_laws_diagram(
        "applied_motor_signals", params, motor_inverse, ("applied_joint_torque", "joint_velocity"),
        {"voltage": 0, "current": 1, "motor_torque": 2, "electrical_power": 3}, host_has_continuous_state,
        pass_through_first="joint_torque")
