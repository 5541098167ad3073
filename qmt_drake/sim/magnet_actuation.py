"""How an actuator kind drives the magnet co-simulation: the `MagnetActuation` an actuator plug-in
holds (actuators.ActuatorPlugin.magnet_actuation) and the two the core registers.

    DcMotorActuation      dc_motor_gear: PID on the motor voltages, the catalogue DC motors behind the
                          URDF's gears, the loop's damping stepped implicitly (default) or explicitly
    IdealTorqueActuation  ideal: a joint-side PD torque source, its damping stepped implicitly

`build_transfer_diagram` and the runner ask `magnet_actuation_of(scenario)` (the scenario's actuator
plug-in's) what to check and what to build instead of branching on the actuator, so a new actuator
kind brings its own actuation without editing sim/. build_transfer_diagram calls, in order,
`loop_scheme` (refuses options the actuator cannot take, says whether the loop is stepped
implicitly), `setup` (gains; the joint damping moved into the plant before it is finalised) and `add`
(the systems between the reference and the plant's actuation input, with what they deliver); the
runner calls `feedforward_keywords` and `check` before any planning.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from pydrake.systems.primitives import ConstantVectorSource, Demultiplexer

from qmt_drake.config.registry import actuator_entry
from qmt_drake.errors import QmtInputError
from qmt_drake.sim.actuation import (
    FEEDFORWARD_OPTIONS,
    add_ideal_torque_actuation,
    add_implicit_damping_actuation,
    add_motor_actuation_law,
    ideal_joint_gains,
    motor_actuation_law,
    motor_params_for,
    pid_gains_for,
)
from qmt_drake.systems.dc_motor import DcMotorParams, DcMotorWithGear, dc_motors_as_primitives
from qmt_drake.systems.joint_tracking import (
    JointPidController,
    effective_joint_gains,
    primitive_pd_controller,
)


@dataclass(frozen=True)
class ActuationOptions:
    """The build_transfer_diagram keywords that say how the actuators are built (see its docstring);
    an actuation refuses (one line) those it cannot take."""

    implicit_loop_damping: bool | None = None
    motor_inductance: bool = False
    back_emf_feedforward: bool = False
    inverse_dynamics_feedforward: bool = False
    primitive_controller: bool = True
    motor_params: DcMotorParams | None = None


@dataclass(frozen=True)
class ActuationSetup:
    """What `MagnetActuation.setup` decided before the plant is finalised: loop_damping [N*m*s/rad]
    per joint, moved into the plant's joints (implicit stepping; None: the actuators drive the
    plant explicitly); motor_params, the motors reported in TransferDiagram.motor_params (None: no
    motors); gains, the actuation's own gains for `add`."""

    loop_damping: np.ndarray | None
    motor_params: DcMotorParams | None = None
    gains: Any = None


@dataclass(frozen=True)
class ActuationSite:
    """Where `MagnetActuation.add` wires in: the builder, the plant (finalised) and the arm's model
    instance, its joint count n, the reference's desired_state (2n) and the arm's state (2n) output
    ports, and the plant's step [s]."""

    builder: Any
    plant: Any
    arm_instance: Any
    n: int
    desired_state: Any
    arm_state: Any
    time_step_s: float


@dataclass(frozen=True)
class ActuationPorts:
    """What `MagnetActuation.add` built: delivered, the system whose joint_torque, motor_torque,
    current and electrical_power outputs are reported (and monitored); controller, the system with a
    voltage_command output (None: no voltages); motors (None: no motor system); feedforward_input, the
    input the inverse-dynamics feedforward torque [N*m] goes to (with inverse_dynamics_feedforward;
    otherwise None)."""

    delivered: Any
    controller: Any = None
    motors: Any = None
    feedforward_input: Any = None


class MagnetActuation(Protocol):
    """How one actuator kind drives the magnet co-simulation (module docstring)."""

    def feedforward_keywords(self, scenario: Any, feedforward: str) -> dict:
        """build_transfer_diagram keywords of a FEEDFORWARD_OPTIONS key (refused in one line if not taken)."""

    def check(self, scenario: Any, *, implicit_loop_damping: bool | None) -> None:
        """Refuse (one line) a scenario or loop scheme it cannot simulate, before any planning."""

    def loop_scheme(self, scenario: Any, options: ActuationOptions) -> bool:
        """Whether the loop is stepped implicitly (refuses, one line, options it cannot take)."""

    def setup(self, scenario: Any, options: ActuationOptions, implicit_loop_damping: bool) -> ActuationSetup:
        """Gains and the joint damping moved into the plant (before it is finalised)."""

    def add(self, site: ActuationSite, scenario: Any, setup: ActuationSetup,
            options: ActuationOptions) -> ActuationPorts:
        """The systems from the reference to the plant's actuation input."""


class DcMotorActuation:
    """actuator.kind dc_motor_gear: the scenario's PID gains on the motor voltages, its catalogue
    motors behind the URDF's gears (sim/actuation.py); also what a scenario whose actuator has no
    magnet actuation meets, whose checks then refuse it naming dc_motor_gear."""

    def feedforward_keywords(self, scenario: Any, feedforward: str) -> dict:
        return dict(FEEDFORWARD_OPTIONS[feedforward])

    def check(self, scenario: Any, *, implicit_loop_damping: bool | None) -> None:
        motor_params_for(scenario)
        pid_gains_for(scenario)

    def loop_scheme(self, scenario: Any, options: ActuationOptions) -> bool:
        implicit = options.implicit_loop_damping
        if implicit is None:
            implicit = not options.motor_inductance
        if implicit and options.motor_inductance:
            raise QmtInputError("implicit_loop_damping needs the quasi-static armature; with motor_inductance=True "
                                "pass implicit_loop_damping=False and time_step_s <= 1e-3")
        return implicit

    def setup(self, scenario: Any, options: ActuationOptions, implicit_loop_damping: bool) -> ActuationSetup:
        gains = pid_gains_for(scenario)
        mp = options.motor_params or motor_params_for(scenario, with_inductance=options.motor_inductance)
        loop_damping = effective_joint_gains(gains, mp)[1] if implicit_loop_damping else None
        return ActuationSetup(loop_damping, mp, gains)

    def add(self, site: ActuationSite, scenario: Any, setup: ActuationSetup,
            options: ActuationOptions) -> ActuationPorts:
        builder, mp, loop_damping = site.builder, setup.motor_params, setup.loop_damping
        assert mp is not None
        pid = JointPidController(setup.gains, mp.gear_ratio, mp.voltage_limit_V, control_period_s=site.time_step_s,
                                 motor=mp, back_emf_feedforward=options.back_emf_feedforward,
                                 torque_feedforward=options.inverse_dynamics_feedforward)
        # With implicit loop damping, a PD law (no integral) and quasi-static motors, controller, motors
        # and damping add-back are one compiled law (sim.actuation.motor_actuation_law); otherwise the
        # controller (a PD law as Drake primitives, or the Python PID) and the motors (primitives, or
        # the LeafSystem whose armature current is a continuous state with inductance) run apart.
        law = motor_actuation_law(pid, mp, loop_damping) \
            if (options.primitive_controller and loop_damping is not None) else None
        if law is not None:
            ctrl = motors = builder.AddNamedSystem("motor_actuation", law)
        else:
            prim = primitive_pd_controller(pid, host_has_continuous_state=bool(options.motor_inductance)) \
                if options.primitive_controller else None
            ctrl = builder.AddNamedSystem("controller", prim or pid)
            motors = builder.AddNamedSystem("motors", DcMotorWithGear(mp) if mp.inductance_H is not None
                                            else dc_motors_as_primitives(mp))
        split = builder.AddNamedSystem("arm_state_split", Demultiplexer([site.n, site.n]))
        feedforward_input = ctrl.GetInputPort("feedforward_torque") if options.inverse_dynamics_feedforward else None
        builder.Connect(site.desired_state, ctrl.GetInputPort("desired_state"))
        builder.Connect(site.arm_state, ctrl.GetInputPort("estimated_state"))
        builder.Connect(site.arm_state, split.get_input_port())
        if law is None:
            builder.Connect(ctrl.GetOutputPort("voltage_command"), motors.GetInputPort("voltage_command"))
            builder.Connect(split.get_output_port(1), motors.GetInputPort("joint_velocity"))
        # What the motors deliver: their own outputs when stepped explicitly; with implicit loop
        # damping, the torque applied over the last step, read back through the motor model.
        delivered = motors
        if law is not None:
            delivered = add_motor_actuation_law(builder, site.plant, site.arm_instance, law, split.get_output_port(1),
                                                loop_damping, site.time_step_s, mp)
        elif loop_damping is None:
            builder.Connect(motors.GetOutputPort("joint_torque"), site.plant.get_actuation_input_port(site.arm_instance))
        else:
            delivered = add_implicit_damping_actuation(builder, site.plant, site.arm_instance, motors,
                                                       split.get_output_port(1), loop_damping, site.time_step_s, mp)
        return ActuationPorts(delivered, ctrl, motors, feedforward_input)


class IdealTorqueActuation:
    """actuator.kind ideal: control.kp / kd read as joint-side PD torque gains (no motors; an ideal
    gear for the motor-side torques reported), the damping stepped implicitly, so any step is stable
    (sim/actuation.add_ideal_torque_actuation)."""

    def feedforward_keywords(self, scenario: Any, feedforward: str) -> dict:
        """No back EMF: 'full' is the inverse dynamics alone, 'back-emf' is refused."""
        if feedforward == "back-emf":
            raise QmtInputError(f"--feedforward back-emf needs DC motors; scenario '{scenario.name}' has "
                                f"actuator.kind {scenario.actuator.kind}: use none or full")
        kw = dict(FEEDFORWARD_OPTIONS[feedforward])
        kw.pop("back_emf_feedforward", None)
        return kw

    def check(self, scenario: Any, *, implicit_loop_damping: bool | None) -> None:
        ideal_joint_gains(scenario)
        if implicit_loop_damping is False:
            raise QmtInputError(f"--explicit drives DC motors explicitly; scenario '{scenario.name}' has "
                                f"actuator.kind {scenario.actuator.kind} (always stepped implicitly): drop --explicit")

    def loop_scheme(self, scenario: Any, options: ActuationOptions) -> bool:
        if options.motor_inductance or options.back_emf_feedforward or options.implicit_loop_damping is False:
            raise QmtInputError(f"scenario '{scenario.name}' has actuator.kind {scenario.actuator.kind} (no motors): "
                                "drop the motor options (inductance, back-EMF feedforward, explicit motor loop)")
        return True

    def setup(self, scenario: Any, options: ActuationOptions, implicit_loop_damping: bool) -> ActuationSetup:
        kp, kd = ideal_joint_gains(scenario)
        return ActuationSetup(kd, None, kp)

    def add(self, site: ActuationSite, scenario: Any, setup: ActuationSetup,
            options: ActuationOptions) -> ActuationPorts:
        builder = site.builder
        split = builder.AddNamedSystem("arm_state_split", Demultiplexer([site.n, site.n]))
        builder.Connect(site.arm_state, split.get_input_port())
        delivered, feedforward_input = add_ideal_torque_actuation(
            builder, site.plant, site.arm_instance, site.desired_state, site.arm_state, split.get_output_port(1),
            setup.gains, setup.loop_damping, scenario.gear_ratio, site.time_step_s)
        if not options.inverse_dynamics_feedforward:  # the feedforward input is an Adder port: zero unless fed
            zero = builder.AddNamedSystem("no_feedforward", ConstantVectorSource(np.zeros(site.n)))
            builder.Connect(zero.get_output_port(), feedforward_input)
            feedforward_input = None
        return ActuationPorts(delivered, feedforward_input=feedforward_input)


DC_MOTOR_ACTUATION = DcMotorActuation()
IDEAL_TORQUE_ACTUATION = IdealTorqueActuation()


def magnet_actuation_of(scenario: Any) -> MagnetActuation:
    """The magnet actuation of the scenario's actuator plug-in; without an actuator section, or for a
    kind that has none, the DC motors', whose checks refuse it in one line naming dc_motor_gear."""
    entry = actuator_entry(scenario)
    actuation = None if entry is None else getattr(entry, "magnet_actuation", None)
    return DC_MOTOR_ACTUATION if actuation is None else actuation
