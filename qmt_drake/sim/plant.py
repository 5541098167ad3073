"""The transfer plant: the arm from the scenario's URDF plus the payload on its 6-DOF joint to the hand
(systems.payload: its coordinates are its pose in the hand frame), in contact with the hand.

`transfer_plant_config(time_step_s)` is the ONE place the plant settings the co-simulation systems
rely on are chosen; user code that composes the systems by hand calls it (or `add_transfer_plant`)
too:

    time_step                 discrete plant [s] (2 ms with implicit loop damping, 1 ms explicit)
    discrete_contact_approximation = "lagged"  (kLagged: the point contacts of the seated part are
                              stable at ms steps; NOTES.md)
    contact_model = "point"   the payload's ring of spheres against the hand's face box
    use_sampled_output_ports = False   the plant's output ports show the CURRENT state. With sampled
                              ports (Drake's default) the discrete-update systems that read the
                              plant during a step (TransferMonitor, the PID's integral) saw the next
                              state paired with this step's reference: wrong tracking errors and
                              slips, no error raised.

A scenario's `simulation.plant` fields (config/simulation.py) replace these where it gives them.

`add_transfer_plant` adds and configures that plant, the arm and the payload; `finalize_transfer_plant`
finalises it and sets the plant's DEFAULT state to the plan's start (arm at q_start at rest, the
payload seated on the face), so a fresh default context of any diagram holding it is ready to
simulate. `set_initial_state` sets the same state in an existing context.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.multibody.tree import JointActuatorIndex

from qmt_drake.config.simulation import NO_SIMULATION, PlantSettings
from qmt_drake.errors import QmtInputError
from qmt_drake.model.arm import add_arm
from qmt_drake.sim.sim_settings import plant_config, simulation_of
from qmt_drake.systems.payload import (
    PayloadSpec,
    add_payload,
    allow_contact,
    payload_joint,
    seated_pose_in_hand,
)


def transfer_plant_config(time_step_s: float, settings: PlantSettings = NO_SIMULATION.plant) -> MultibodyPlantConfig:
    """The MultibodyPlantConfig every transfer diagram uses (module docstring: why each setting), with the
    scenario's `simulation.plant` fields (`settings`) over it and the step time_step_s [s] (already resolved:
    sim/sim_settings.time_step_of)."""
    if isinstance(time_step_s, bool) or not (isinstance(time_step_s, (int, float)) and time_step_s > 0):
        raise QmtInputError(f"plant time step must be a positive number of seconds, got {time_step_s!r}")
    base = MultibodyPlantConfig(time_step=float(time_step_s), discrete_contact_approximation="lagged",
                                contact_model="point", use_sampled_output_ports=False)
    return plant_config(base, settings, time_step=float(time_step_s))


@dataclass
class TransferPlant:
    """Handles of a transfer plant (see add_transfer_plant)."""

    plant: object
    scene_graph: object
    arm_instance: object
    hand_body: object
    payload_body: object
    payload_spec: PayloadSpec
    n_dof: int
    payload_joint: object = None  # set by finalize_transfer_plant


def add_transfer_plant(builder, scenario, time_step_s: float, *, payload_spec: PayloadSpec | None = None,
                       n_dof_expected: int | None = None) -> TransferPlant:
    """Add the configured plant + scene graph to `builder`, parse the scenario's arm and add the
    payload (the scenario's payload body and hand contact data unless payload_spec is given).
    The plant is NOT finalised: add joint damping etc., then call `finalize_transfer_plant`.
    n_dof_expected (a plan's joint count) is checked against the arm: one-line QmtInputError."""
    plant, scene_graph = AddMultibodyPlant(transfer_plant_config(time_step_s, simulation_of(scenario).plant), builder)
    plant.mutable_gravity_field().set_gravity_vector(np.asarray(scenario.world.gravity_m_s2, float))
    arm = add_arm(plant, scenario.urdf_path)
    n = sum(plant.get_joint(j).num_velocities() for j in plant.GetJointIndices(arm))
    if n_dof_expected is not None and int(n_dof_expected) != n:
        raise QmtInputError(f"plan has {int(n_dof_expected)} joints but scenario '{scenario.name}' arm "
                            f"({scenario.urdf_path.name}) has {n}; use a plan made for this scenario")
    if not plant.HasBodyNamed(scenario.hand_frame, arm):
        raise QmtInputError(f"scenario '{scenario.name}': the co-simulation seats the payload on a link; "
                            f"arm.hand_frame '{scenario.hand_frame}' is not a link of {scenario.urdf_path.name}")
    hand = plant.GetBodyByName(scenario.hand_frame, arm)
    spec = payload_spec or PayloadSpec.for_scenario(scenario)
    payload = add_payload(plant, spec, hand)
    return TransferPlant(plant, scene_graph, arm, hand, payload, spec, n)


def finalize_transfer_plant(tp: TransferPlant, q_start) -> None:
    """Finalize and make the plan's start the plant's default state: the arm at q_start [rad] at
    rest, the payload seated on the hand's face (`seated_pose_in_hand`) at rest."""
    plant = tp.plant
    plant.Finalize()
    allow_contact(plant, tp.scene_graph, tp.hand_body, tp.payload_body)
    plant.SetDefaultPositions(tp.arm_instance, np.asarray(q_start, float).reshape(-1))
    tp.payload_joint = payload_joint(plant, tp.payload_body)
    tp.payload_joint.SetDefaultPose(seated_pose_in_hand())


def set_initial_state(plant, plant_context, arm_instance, hand_body, payload_body, q_start) -> None:
    """In an existing plant context: arm at q_start at rest, payload seated at rest."""
    plant.SetPositions(plant_context, arm_instance, q_start)
    plant.SetVelocities(plant_context, arm_instance, np.zeros(len(q_start)))
    joint = payload_joint(plant, payload_body)
    joint.SetPose(plant_context, seated_pose_in_hand())
    joint.set_angular_velocity(plant_context, np.zeros(3))
    joint.set_translational_velocity(plant_context, np.zeros(3))


def move_loop_damping_into_plant(plant, arm_instance, loop_damping) -> None:
    """Before Finalize: add loop_damping [N*m*s/rad] (one per actuator, in actuator order) to the
    actuated joints' damping, which the discrete plant steps implicitly, and lift the actuators'
    effort limits (the motor model limits the torque; the actuation input now also carries D*qd)."""
    actuators = [JointActuatorIndex(i) for i in range(plant.num_actuators())
                 if plant.get_joint_actuator(JointActuatorIndex(i)).model_instance() == arm_instance]
    for d, index in zip(loop_damping, actuators):
        actuator = plant.get_mutable_joint_actuator(index)
        joint = plant.get_mutable_joint(actuator.joint().index())
        joint.set_default_damping(joint.default_damping() + float(d))
        actuator.set_effort_limit(float("inf"))
