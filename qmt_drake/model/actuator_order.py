"""Actuators mapped to joints by name, never by index.

Drake creates a URDF's actuators in the order of its `<transmission>` elements, and skips a
transmission it does not support (a differential wrist, say) without an actuator; a model
instance's actuation input takes its actuators in that order. Controllers and motor models here
write one torque per joint in the joint order (the chain's order, the order of the plant's
velocities). Two guards keep the two orders apart:

- `actuator_specs` / `add_actuators_in_order` (model/urdf_check.load_arm_plant): when Drake's actuators
  are not one per chain joint in chain order, the URDF is parsed again without its transmissions and
  the actuators are added in chain order, each with what Drake made of its transmission (name, effort
  limit, gear ratio, rotor inertia, PD gains; a joint without one gets `<joint>_actuator`, unlimited
  effort), so a plant built there has u = tau (Drake's RemoveJointActuator would leave the removed
  ones counted by num_actuators(), which InverseDynamicsController refuses);
- `joint_to_actuation_matrix` (after Finalize): the (n_actuators, n_joints) 0/1 matrix P with
  u = P tau, built from the actuators' joint names; `connect_joint_torques` wires a joint-order torque
  port into the instance's actuation input through P (directly when P is the identity).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.primitives import MatrixGain

from qmt_drake.errors import QmtInputError


def actuator_joint_names(plant, model) -> list[str]:
    """The joints of `model`'s actuators, in the order of its actuation input port (before Finalize too,
    when Drake's per-instance list is still empty)."""
    return [a.joint().name() for a in _actuators(plant, model)]


def _actuators(plant, model) -> list:
    acts = (plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices())
    return [a for a in acts if a.model_instance() == model]


def actuator_specs(plant, model, joint_names, source: str = "URDF") -> list:
    """Per joint of `joint_names`: (name, effort limit, gear ratio, rotor inertia, PD gains or None) of
    the actuator Drake made for it, or None when it has none. Actuators of other joints are refused."""
    names = list(joint_names)
    acts = {a.joint().name(): a for a in _actuators(plant, model)}
    extra = [j for j in acts if j not in names]
    if extra:
        raise QmtInputError(f"{source}: joints {extra} have actuators but are not on the arm's chain; lock them "
                            "(lock_joints) or name a hand frame after them")
    return [None if acts.get(j) is None else
            (acts[j].name(), acts[j].effort_limit(), acts[j].default_gear_ratio(), acts[j].default_rotor_inertia(),
             acts[j].get_controller_gains() if acts[j].has_controller() else None) for j in names]


def add_actuators_in_order(plant, model, joint_names, specs) -> None:
    """Before Finalize, on a plant parsed without transmissions: one actuator per joint of `joint_names`,
    in that order, with actuator_specs' properties (None: `<joint>_actuator`, unlimited effort)."""
    for j, spec in zip(joint_names, specs):
        name, effort, gear, rotor, gains = spec or (f"{j}_actuator", float("inf"), None, None, None)
        a = plant.AddJointActuator(name, plant.GetJointByName(j, model), effort)
        if gear is not None:
            a.set_default_gear_ratio(gear)
            a.set_default_rotor_inertia(rotor)
        if gains is not None:
            a.set_controller_gains(gains)


def joint_to_actuation_matrix(plant, model, joint_names) -> np.ndarray:
    """(n_actuators, n_joints) P with u = P tau, tau one torque per joint of `joint_names`, u the
    actuation input of `model`; by the actuators' joint names. A joint without an actuator is refused."""
    names = list(joint_names)
    starts = [plant.GetJointByName(j, model).velocity_start() for j in names]
    if starts != sorted(starts):  # tau's order is the plant's velocity order (controllers, inverse dynamics)
        raise RuntimeError(f"joints {names} are not in the plant's velocity order; a defect, please report it")
    acting = actuator_joint_names(plant, model)
    missing = [j for j in names if j not in acting]
    if missing:
        raise QmtInputError(f"joints {missing} have no actuator in the plant (Drake skipped their <transmission>?); "
                            "give each a SimpleTransmission or let load_arm_plant add one")
    P = np.zeros((len(acting), len(names)))
    for a, j in enumerate(acting):
        if j in names:
            P[a, names.index(j)] = 1.0
    return P


def connect_joint_torques(builder, plant, model, joint_names, torque_port) -> None:
    """Connect a port carrying one torque per joint of `joint_names` [N*m] to `model`'s actuation input,
    through joint_to_actuation_matrix (no gain system when it is the identity)."""
    P = joint_to_actuation_matrix(plant, model, joint_names)
    if P.shape[0] == P.shape[1] and np.array_equal(P, np.eye(P.shape[0])):
        builder.Connect(torque_port, plant.get_actuation_input_port(model))
        return
    gain = builder.AddNamedSystem("joint_torque_to_actuators", MatrixGain(P))
    builder.Connect(torque_port, gain.get_input_port())
    builder.Connect(gain.get_output_port(), plant.get_actuation_input_port(model))
