"""The spatial co-simulation's actuator choice: `ideal` (Drake's InverseDynamicsController with saturated
joint torques, built in sim/spatial_cosim.py) or `dc_motor`, the planar thesis arms' drive on a URDF arm:

    plan --desired_state--> PD law (joint_tracking.pd_voltage, motor-side gains, volts) [+ Ki z: integral,
                            actuators.motor.integral_rate_per_s > 0: the JointPidController with anti-windup]
         [+ K_e N qd_des]                      back-EMF feedforward      (feedforward "back-emf", "full")
         [+ tau_ff R / (N eta k_t)]            inverse-dynamics feedforward ("full"): Drake InverseDynamics of
                                               the arm with the part welded and N^2 J_r, on the plan
         [+ D h qdd_des R / (N eta k_t)]       ("shaped" only: what the implicit loop damping takes over a step,
                                               add_stepping_feedforward; the reference is then the plan shaped
                                               and sampled as the plant integrates it, sim/spatial_reference)
         --voltage--> DC motor + gear per joint (dc_motor.motor_forward: voltage and current limits)
         --joint torque (+ D qd, implicit loop damping)--> MultibodyPlant

The PD law, the motors and the damping add-back are the planar co-simulation's compiled law
(sim/actuation.motor_actuation_law) and its implicit wiring (add_motor_actuation_law); the two
feedforward voltages together are the motor model backwards (dc_motor.motor_inverse) at the desired
speed while motoring, exactly so for a loss-free gear (gear_efficiency 1, the default). The reflected
rotor inertia N^2 J_r is in the simulated plant (and in the feedforward's plant): each joint actuator gets
the scenario's gear ratio and rotor inertia (JointActuator.set_default_gear_ratio / _rotor_inertia).

Motor constants: the scenario's actuators.motor (spatial_motor.py); without it `dc_motor` is refused.
Gains (the scenario has no control section): decentralised, per joint from its diagonal mass-matrix
entry M_jj at the plan's start (reflected inertia and part included), a critically damped
(DAMPING_RATIO) joint loop of natural frequency CLOSED_LOOP_RAD_S, the ideal controller's 30 rad/s
(Kp 900 1/s^2, Kd 60 1/s). A joint whose back-EMF damping b = N^2 eta k_t^2 / R alone exceeds that
loop's damping keeps Kd = 0 and gets the stiffness that makes b critical (K = b^2 / (4 zeta^2 M_jj)):
every joint is critically damped at M_jj. The voltage gains come from joint-side K, D through
joint_tracking.effective_joint_gains (K = c N Kp, D = c N Kd + b, c = N eta k_t / R).

Integral (actuators.motor.integral_rate_per_s, or for_scenario / a sweep's sim.integral_rate_per_s; default 0):
Ki = K * rate [1/s] on the same nominal design, clamped anti-windup (joint_tracking). Its discrete update reads
the plant during the step, so the plant's output ports are made live (prepare_plant; Drake's sampled ports
paired the next state with this step's reference). Control period (for_scenario(control_period_s=), a sweep's
drawn or fixed loop_period_s; default the plant step, the unchanged every-step law): longer than the plant step, the law
is sampled and held (JointPidController hold_period_s); its derivative then acts on held speeds, so only the
motors' back EMF b is folded into the plant. The held feedforwards (back EMF, inverse dynamics, stepping)
are evaluated on the reference's mean over the coming hold's plant steps (hold_compensation "mean", the
default; joint_tracking.HoldCompensatedReference), not at the sample instant, where they lag the plan by T/2;
"midpoint" and "none" (the uncompensated law) for comparison (docs/spatial_drives.md). The P/D terms keep the
reference at the sample instant. A held law's amplifier (`amplifier`, HELD_AMPLIFIERS): "current" (the default)
holds a current command and cancels the back EMF of the speed measured at every plant step (a drive's current loop,
joint_tracking.JointPidController current_loop), so the motors' torque is constant over each hold; nothing is folded
into the plant, and the PD is the 30 rad/s critically damped joint loop (b no longer damps it) slowed for its period
until its discrete poles keep HELD_MIN_DAMPING (systems/held_loop.period_scale, on the mass matrix at the plan's
start). "voltage" holds the voltage (the law before): its current falls over the hold as the joints speed up, which
saws the motors' torque by b qdd (T - h) per hold and lost the UR5 suction box at 4-8 ms (docs/spatial_drives.md).
`explicit` (`simulate --explicit`): nothing folded into the plant,
the law applies the loop's damping itself (plant_damping_Nms).

`add_tracking_logs` / `tracking_report` record the arm state and the plan (both actuators) and, with
motors, the current, and summarise the tracking error along the motion and the largest motor torque
N k_t i [N*m] over the torque limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.multibody.tree import JointActuatorIndex
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.primitives import Adder, Demultiplexer, LogVectorOutput, MatrixGain

from qmt_drake.errors import QmtInputError
from qmt_drake.model.actuator_order import actuator_joint_names
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.sim.actuation import (
    EXPLICIT_MAX_TIME_STEP_S,
    FEEDFORWARD_OPTIONS,
    add_implicit_damping_actuation,
    add_motor_actuation_law,
    motor_actuation_law,
)
from qmt_drake.sim.plant import move_loop_damping_into_plant
from qmt_drake.spatial_motor import MOTOR_KEYS, check_control_period, check_integral_rate
from qmt_drake.systems.dc_motor import DcMotorParams, dc_motors_as_primitives
from qmt_drake.systems.held_loop import HELD_MIN_DAMPING, period_scale
from qmt_drake.systems.joint_tracking import (
    HOLD_COMPENSATIONS,
    HoldCompensatedReference,
    JointPidController,
    PidGains,
    effective_joint_gains,
)

ACTUATORS = ("ideal", "dc_motor")
# the spatial drives' feedforward words: the planar ones, and `shaped` = `full` on the closed-loop-aware reference
# (sim/spatial_reference.closed_loop_reference: the plan slowed where the motors cannot follow it, box-shaped)
SPATIAL_FEEDFORWARD = {**FEEDFORWARD_OPTIONS, "shaped": FEEDFORWARD_OPTIONS["full"]}
CLOSED_LOOP_RAD_S = 30.0  # = sqrt(KP_1_S2) of sim/spatial_cosim's inverse-dynamics controller
DAMPING_RATIO = 1.0  # = KD_1_S / (2 sqrt(KP_1_S2)) there
HELD_AMPLIFIERS = ("current", "voltage")  # what a held law commands (module docstring; the first: default)


def set_drive_inertia(plant, arm_instance, sc) -> None:
    """Before Finalize: each chain joint's actuator gets the scenario's gear ratio N and rotor inertia J_r
    (Drake adds N^2 J_r to the joint's diagonal of the mass matrix)."""
    for i in range(plant.num_actuators()):
        a = plant.get_mutable_joint_actuator(JointActuatorIndex(i))
        if a.model_instance() != arm_instance or a.joint().name() not in sc.joint_names:
            continue
        k = sc.joint_names.index(a.joint().name())
        a.set_default_gear_ratio(float(sc.drive["gear_ratio"][k]))
        a.set_default_rotor_inertia(float(sc.drive["rotor_inertia_kgm2"][k]))


def require_joint_order(plant, arm_instance, joint_names) -> None:
    """The arm's actuators drive `joint_names` in this order (load_arm_plant builds them so, by name);
    anything else would send each motor's torque into another joint."""
    acting = actuator_joint_names(plant, arm_instance)
    if acting != list(joint_names):
        raise RuntimeError(f"the arm's actuators drive {acting}, not the joints {list(joint_names)} in order; "
                           "build the plant with load_arm_plant (a defect, please report it)")


def motor_params_for_spatial(sc) -> DcMotorParams:
    """The scenario's motors (actuators.motor) behind its gears; one-line refusal when not given."""
    m = sc.motor
    if m is None:
        raise QmtInputError(f"scenario '{sc.name}': actuator dc_motor needs actuators.motor with "
                            f"{', '.join(MOTOR_KEYS)} (one number or one per joint); add them to its YAML or use "
                            "actuator ideal")
    return DcMotorParams(torque_constant_Nm_per_A=m.torque_constant_Nm_per_A, resistance_ohm=m.resistance_ohm,
                         gear_ratio=sc.drive["gear_ratio"], voltage_limit_V=m.voltage_limit_V,
                         current_limit_A=m.current_limit_A, efficiency=m.gear_efficiency, names=list(sc.joint_names))


def decentralised_gains(mp: DcMotorParams, joint_inertia_kgm2, integral_rate_per_s=0.0) -> PidGains:
    """Motor-side PID voltage gains (module docstring): every joint critically damped at its inertia,
    and the integral gain Ki = K * integral_rate_per_s [1/s] (zero: a PD law)."""
    M = np.asarray(joint_inertia_kgm2, float)
    n = mp.n
    per_kp, b = effective_joint_gains(PidGains(np.ones(n), np.zeros(n), np.zeros(n)), mp)  # c N [N*m/V*V/rad], b_emf
    D = np.maximum(2.0 * DAMPING_RATIO * CLOSED_LOOP_RAD_S * M, b)
    K = (D / (2.0 * DAMPING_RATIO)) ** 2 / M
    return PidGains(K / per_kp, K * np.broadcast_to(integral_rate_per_s, (n,)) / per_kp, (D - b) / per_kp)


def back_emf_damping(mp: DcMotorParams) -> np.ndarray:
    """The motors' back-EMF damping at the joints, N^2 eta k_t^2 / R [N*m*s/rad] (effective_joint_gains of
    a zero law)."""
    return effective_joint_gains(PidGains(np.zeros(mp.n), np.zeros(mp.n), np.zeros(mp.n)), mp)[1]


@dataclass
class SpatialMotorDrive:
    """What the dc_motor actuator needs, built before the simulated plant (refusals come first)."""

    params: DcMotorParams
    gains: PidGains
    loop_damping_Nms: np.ndarray  # joint-side D of PD + motors, stepped implicitly by the plant
    feedforward: str
    id_plant: object  # continuous arm + welded part + N^2 J_r: the feedforward's inverse dynamics
    plant_params: DcMotorParams | None = None  # the simulated motors when they differ from the law's model (params)
    control_period_s: float | None = None  # the law's sample-and-hold period [s]; None: every plant step
    explicit: bool = False  # True: nothing folded into the plant, the law's damping applied by the law itself
    hold_compensation: str = HOLD_COMPENSATIONS[0]  # a held law's feedforward: the plan's mean over the hold
    amplifier: str = HELD_AMPLIFIERS[0]  # a held law's command: a current (the drive's current loop) or a voltage
    mass_matrix: np.ndarray | None = None  # the arm's at the plan's start [kg m^2]: a held current law's design
    gain_scales: tuple = (1.0, 1.0)  # a sweep's drawn kp_scale, kd_scale on the held current law's gains

    @classmethod
    def for_scenario(cls, sc, q_start_rad, feedforward: str = "full", integral_rate_per_s=None,
                     control_period_s: float | None = None, explicit: bool = False,
                     hold_compensation: str = HOLD_COMPENSATIONS[0],
                     amplifier: str = HELD_AMPLIFIERS[0]) -> SpatialMotorDrive:
        """The drive designed from sc (the nominal model). integral_rate_per_s [1/s]: the PID's Ki / K, one
        number or one per joint; None: the scenario's actuators.motor.integral_rate_per_s (default 0, a PD law).
        control_period_s [s]: the law's sample-and-hold period (check_control_period); None: the plant step.
        explicit: module docstring, `--explicit`. hold_compensation: what a held law's feedforward is evaluated
        on (joint_tracking.HOLD_COMPENSATIONS; module docstring). amplifier: what a held law commands
        (HELD_AMPLIFIERS; module docstring); the every-step law is unchanged by it."""
        if amplifier not in HELD_AMPLIFIERS:
            raise QmtInputError(f"amplifier {amplifier!r}: choose one of {', '.join(HELD_AMPLIFIERS)}")
        if hold_compensation not in HOLD_COMPENSATIONS:
            raise QmtInputError(f"hold compensation {hold_compensation!r}: choose one of {', '.join(HOLD_COMPENSATIONS)}")
        if feedforward not in SPATIAL_FEEDFORWARD:
            raise QmtInputError(f"feedforward {feedforward!r}: choose one of {', '.join(SPATIAL_FEEDFORWARD)}")
        mp = motor_params_for_spatial(sc)
        plant, H, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, carried=sc.body.as_dict(),
                                     effort_limit_Nm=sc.torque_limit_Nm,
                                     velocity_limit_rad_s=sc.velocity_limit_rad_s, finalize=False)
        set_drive_inertia(plant, H.model_instance(), sc)
        plant.Finalize()
        ctx = plant.CreateDefaultContext()
        plant.SetPositions(ctx, np.asarray(q_start_rad, float))
        rate = sc.motor.integral_rate_per_s if integral_rate_per_s is None else check_integral_rate(
            integral_rate_per_s, "sim", mp.n, mp.names)
        M = plant.CalcMassMatrix(ctx)
        gains = decentralised_gains(mp, np.diag(M), rate)
        return cls(mp, gains, effective_joint_gains(gains, mp)[1], feedforward, plant,
                   control_period_s=check_control_period(control_period_s),
                   explicit=bool(explicit), hold_compensation=hold_compensation, amplifier=amplifier,
                   mass_matrix=M)

    def prepare_plant(self, plant, arm_instance, sc) -> None:
        """Before the simulated plant's Finalize: reflected inertia, and the loop damping in the joints
        (move_loop_damping_into_plant and the motor wiring go by actuator order: it must be the joints')."""
        require_joint_order(plant, arm_instance, sc.joint_names)
        set_drive_inertia(plant, arm_instance, sc)
        h = plant.time_step()
        check_control_period(self.control_period_s, h)
        check_explicit_step(self.explicit, h)
        move_loop_damping_into_plant(plant, arm_instance, self.plant_damping_Nms(h))
        if self.has_discrete_law(h):
            # the law's discrete update (the integral, the hold) reads the plant during its step: with Drake's
            # sampled output ports it saw the NEXT state against this step's reference (sim/plant.py), and
            # integrated about h qd of error per step (measured: 2 mrad on the Panda's nominal shaped run at 5 1/s)
            plant.SetUseSampledOutputPorts(False)

    def sampled(self, time_step_s: float) -> bool:
        """True when the law is sampled and held at a period longer than the plant step."""
        return self.control_period_s is not None and self.control_period_s > time_step_s * (1.0 + 1e-9)

    def current_held(self, time_step_s: float) -> bool:
        """True when the law is held behind a current amplifier (module docstring)."""
        return self.sampled(time_step_s) and self.amplifier == "current"

    def law_gains(self, time_step_s: float) -> PidGains:
        """The gains the law runs with: `gains`; held behind a current amplifier, the 30 rad/s critically damped
        joint loop (K = w^2 M_jj, D = 2 zeta w M_jj; no back EMF) slowed by systems/held_loop.period_scale for the
        hold's plant steps, times gain_scales, with the integral rate of `gains` (Ki / Kp)."""
        if not self.current_held(time_step_s):
            return self.gains
        if self.mass_matrix is None:
            raise QmtInputError("a held current law is designed on the arm's mass matrix at the plan's start: build the drive with SpatialMotorDrive.for_scenario(sc, q_start_rad, ...), or give mass_matrix=")
        mp, Mj = self.params, np.diag(self.mass_matrix)
        per_kp = effective_joint_gains(PidGains(np.ones(mp.n), np.zeros(mp.n), np.zeros(mp.n)), mp)[0]  # c N
        K, D = CLOSED_LOOP_RAD_S ** 2 * Mj, 2.0 * DAMPING_RATIO * CLOSED_LOOP_RAD_S * Mj
        m = int(np.ceil(self.control_period_s / time_step_s - 1e-6))  # the plant steps a sample is held over
        try:
            s = period_scale(self.mass_matrix, K, D, time_step_s, m)
        except ValueError:
            raise QmtInputError(f"control period {self.control_period_s * 1e3:g} ms: no joint loop slowed for it keeps "
                                f"damping {HELD_MIN_DAMPING} held; choose a shorter period") from None
        kp, kd = (float(x) for x in self.gain_scales)
        rate = self.gains.ki_V_per_rad_s / self.gains.kp_V_per_rad
        return PidGains(kp * K * s * s / per_kp, kp * rate * K * s * s / per_kp, kd * D * s / per_kp)

    def has_discrete_law(self, time_step_s: float) -> bool:
        """True when the law has discrete state of its own (the integral, the hold): it runs as JointPidController."""
        return bool(np.any(self.gains.ki_V_per_rad_s != 0.0)) or self.sampled(time_step_s)

    def plant_damping_Nms(self, time_step_s: float) -> np.ndarray:
        """The joint damping folded into the plant (stepped implicitly, added back by the law): the loop's
        D (PD + back EMF) when the law acts at every step; the back EMF alone when the law is sampled (its
        derivative acts on the sampled speed, held: not a damping of the plant's own step); none explicitly."""
        if self.explicit or self.current_held(time_step_s):  # (a current loop cancels the back EMF)
            return np.zeros(self.params.n)
        if self.sampled(time_step_s):
            return back_emf_damping(self.params)
        return self.loop_damping_Nms

    def add_to(self, builder, plant, arm_instance, desired_state_port, desired_acceleration_port, time_step_s,
               reference=None):
        """Wire law, motors and feedforward into the builder (after Finalize); returns the applied
        motor signals system (joint_torque, voltage, current, motor_torque, electrical_power). reference: the
        (positions, acceleration) PiecewisePolynomials behind the two ports, which a held law's compensated
        feedforward evaluates ahead (HoldCompensatedReference; needed only then)."""
        mp, n = self.params, self.params.n
        require_joint_order(plant, arm_instance, mp.names)  # the motors' torques go to the actuators in this order
        opts = SPATIAL_FEEDFORWARD[self.feedforward]
        sampled, D = self.sampled(time_step_s), self.plant_damping_Nms(time_step_s)
        current = self.current_held(time_step_s)  # the current loop cancels the measured speed's back EMF itself
        back_emf = opts.get("back_emf_feedforward", False) and not current
        ff_state, ff_acc, ahead = desired_state_port, desired_acceleration_port, None
        if sampled and self.hold_compensation != "none" and (back_emf or opts.get("inverse_dynamics_feedforward")):
            if reference is None:
                raise ValueError("a held law's compensated feedforward needs the reference polynomials (reference=)")
            ahead = builder.AddNamedSystem("hold_compensated_reference", HoldCompensatedReference(
                *reference[:2], self.control_period_s, time_step_s, self.hold_compensation))
            ff_state, ff_acc = ahead.GetOutputPort("desired_state"), ahead.GetOutputPort("desired_acceleration")
        pid = JointPidController(self.law_gains(time_step_s), mp.gear_ratio, mp.voltage_limit_V, control_period_s=time_step_s,
                                 motor=mp, back_emf_feedforward=back_emf,
                                 torque_feedforward=opts.get("inverse_dynamics_feedforward", False),
                                 hold_period_s=self.control_period_s if sampled else None,
                                 feedforward_velocity_port=ahead is not None and back_emf, current_loop=current)
        pm = mp if self.plant_params is None else self.plant_params  # the motors simulated (a sweep draws them)
        # a PD law at every step is one compiled system with the motors; a PID or a sampled law runs as the
        # Python controller (the integral and the held voltage are discrete states) driving the motors as
        # Drake primitives; so does the explicit law (one wiring, nothing folded into the plant)
        compiled = None if sampled or self.explicit else motor_actuation_law(pid, pm, D)  # None with an integral
        law = builder.AddNamedSystem("motor_actuation" if compiled is not None else "controller", compiled or pid)
        state = plant.get_state_output_port(arm_instance)
        split = builder.AddNamedSystem("arm_state_split", Demultiplexer([n, n]))
        builder.Connect(state, split.get_input_port())
        builder.Connect(desired_state_port, law.GetInputPort("desired_state"))
        builder.Connect(state, law.GetInputPort("estimated_state"))
        if ahead is not None and back_emf:
            ff_split = builder.AddNamedSystem("feedforward_state_split", Demultiplexer([n, n]))
            builder.Connect(ff_state, ff_split.get_input_port())
            builder.Connect(ff_split.get_output_port(1), law.GetInputPort("feedforward_velocity"))
        if opts.get("inverse_dynamics_feedforward"):
            inv = builder.AddNamedSystem("inverse_dynamics", InverseDynamics(self.id_plant))
            inv._qmt_keep_alive = self.id_plant  # (Drake's system points at it without owning it: sim/actuation.py)
            builder.Connect(ff_state, inv.get_input_port_estimated_state())
            builder.Connect(ff_acc, inv.get_input_port_desired_acceleration())
            ff = inv.get_output_port_generalized_force()
            if self.feedforward == "shaped" and np.any(D):  # + D h qdd_des: what the implicit damping takes
                ff = add_stepping_feedforward(builder, ff, ff_acc, D, time_step_s)
            builder.Connect(ff, law.GetInputPort("feedforward_torque"))
        if compiled is not None:
            return add_motor_actuation_law(builder, plant, arm_instance, law, split.get_output_port(1),
                                           D, time_step_s, pm)
        motors = builder.AddNamedSystem("motors", dc_motors_as_primitives(pm))
        builder.Connect(law.GetOutputPort("voltage_command"), motors.GetInputPort("voltage_command"))
        builder.Connect(split.get_output_port(1), motors.GetInputPort("joint_velocity"))
        return add_implicit_damping_actuation(builder, plant, arm_instance, motors, split.get_output_port(1),
                                              D, time_step_s, pm)


def add_stepping_feedforward(builder, torque_port, desired_acceleration_port, loop_damping_Nms, time_step_s):
    """torque + D h qdd_des [N*m]: with the loop damping D stepped implicitly the arm receives
    tau_motor(x_n) - D (qd_{n+1} - qd_n) over a step (sim/actuation.add_implicit_damping_actuation), i.e. D h qdd
    less than the feedforward asked for; this gives it back on the reference. Returns the sum's port."""
    n = len(loop_damping_Nms)
    gain = builder.AddNamedSystem("stepping_feedforward", MatrixGain(np.diag(np.asarray(loop_damping_Nms) * time_step_s)))
    total = builder.AddNamedSystem("feedforward_sum", Adder(2, n))
    builder.Connect(desired_acceleration_port, gain.get_input_port())
    builder.Connect(torque_port, total.get_input_port(0))
    builder.Connect(gain.get_output_port(), total.get_input_port(1))
    return total.get_output_port()


def check_explicit_step(explicit: bool, time_step_s: float | None) -> None:
    """One line for an explicit law above EXPLICIT_MAX_TIME_STEP_S (the planar --explicit's bound; None: 1 ms)."""
    if explicit and time_step_s is not None and time_step_s > EXPLICIT_MAX_TIME_STEP_S * (1 + 1e-9):
        raise QmtInputError(f"--explicit at a {time_step_s * 1e3:g} ms step: the explicit motor loop is known stable up "
                            f"to {EXPLICIT_MAX_TIME_STEP_S * 1e3:g} ms; lower --time-step-ms or drop --explicit")


def check_drive(sc, actuator: str, feedforward: str, explicit: bool = False, time_step_s: float | None = None) -> None:
    """One-line QmtInputError for an unknown actuator or feedforward, a feedforward other than 'full' or
    'shaped' (the shaped reference) on the ideal actuator (its inverse-dynamics controller has the full one
    built in), explicit on the ideal actuator (no motor loop to step), or dc_motor without the scenario's
    motor constants; builds nothing (the CLI asks before planning)."""
    if actuator not in ACTUATORS:
        raise QmtInputError(f"actuator {actuator!r}: choose one of {', '.join(ACTUATORS)}")
    if feedforward not in SPATIAL_FEEDFORWARD:
        raise QmtInputError(f"feedforward {feedforward!r}: choose one of {', '.join(SPATIAL_FEEDFORWARD)}")
    if actuator == "ideal" and feedforward not in ("full", "shaped"):
        raise QmtInputError(f"feedforward {feedforward!r} applies to actuator dc_motor; the ideal actuator's "
                            "inverse-dynamics controller always has the full feedforward (or 'shaped': on the "
                            "shaped reference)")
    check_explicit_step(explicit, time_step_s)
    if explicit and actuator != "dc_motor":
        raise QmtInputError("--explicit steps the DC drive's loop damping in its law instead of the plant; the ideal "
                            "actuator has no motor loop: add --actuator dc_motor or drop --explicit")
    if actuator == "dc_motor":
        motor_params_for_spatial(sc)  # (the feedforward's own choices: SpatialMotorDrive.for_scenario)


def spatial_drive(sc, q_start_rad, actuator: str, feedforward: str, explicit: bool = False) -> SpatialMotorDrive | None:
    """None for `ideal`, the dc_motor drive otherwise (check_drive's refusals first)."""
    check_drive(sc, actuator, feedforward, explicit)
    return None if actuator == "ideal" else SpatialMotorDrive.for_scenario(sc, q_start_rad, feedforward,
                                                                           explicit=explicit)


def add_tracking_logs(builder, arm_state_port, desired_state_port, period_s: float, motors=None) -> dict:
    """Loggers of the arm state, the plan's desired state and (motors) the applied current, every period_s."""
    logs = {"arm_state": LogVectorOutput(arm_state_port, builder, period_s),
            "desired_state": LogVectorOutput(desired_state_port, builder, period_s)}
    if motors is not None:
        logs["current"] = LogVectorOutput(motors.GetOutputPort("current"), builder, period_s)
    return logs


def tracking_report(logs: dict, root_context, motion_end_s: float, sc, drive: SpatialMotorDrive | None) -> dict:
    """Tracking error |q_des - q| [rad] along the motion (t <= motion_end_s) and its signed value at the
    end of the run; with motors, the largest |N k_t i| over the joint torque limit, the largest and the
    final current [A]."""
    q = logs["arm_state"].FindLog(root_context)
    d = logs["desired_state"].FindLog(root_context)
    n = sc.n_dof
    err = np.abs(d.data()[:n] - q.data()[:n])
    during = q.sample_times() <= motion_end_s + 1e-9
    out = {"max_tracking_error_rad": float(err[:, during].max()),
           "max_tracking_error_per_joint_rad": err[:, during].max(axis=1).tolist(),
           "rms_tracking_error_rad": float(np.sqrt(np.mean(err[:, during] ** 2))),
           "final_tracking_error_rad": (d.data()[:n, -1] - q.data()[:n, -1]).tolist()}  # signed, q_des - q
    if drive is not None:
        i = logs["current"].FindLog(root_context).data()
        mp = drive.params
        tau_m = (mp.gear_ratio * mp.torque_constant_Nm_per_A)[:, None] * np.abs(i)
        out["max_motor_torque_over_limit"] = float((tau_m / np.asarray(sc.torque_limit_Nm)[:, None]).max())
        out["max_current_A"] = np.abs(i).max(axis=1).tolist()
        out["final_current_A"] = i[:, -1].tolist()
    return out
