"""One entry from an arm's plain data to its planning model: the plant, its chain joints and the chain
(the batched hand state and inverse dynamics every planner and limit term reads).

    arm = build_arm_model(ArmData(urdf, "tool0", lock_joints={}), carried, gear_ratio=None, ...)
    arm.chain.evaluate(q, qd, qdd)     # SpatialChain (a URDF arm) or PlanarChain (planar=True)

Backends:
- planar=True (the thesis arms, seed 001): model/arm.ArmModel.from_urdf's PlanarChain, the same object
  those arms have always used, so their numbers stay bit for bit;
- otherwise: SpatialChain over model/urdf_check.load_arm_plant's plant (the locked joints, the joints'
  limits checked against the URDF), with the carried part and the reflected rotor inertia N^2 J_r of the
  drive (model/urdf_check.drive_parameters: the URDF's drake:gear_ratio / drake:rotor_inertia unless given).

The name is build_arm_model, not a second class called ArmModel: model/arm.ArmModel is the planar arms'
model (and this module's planar backend); one name for two types would mislead.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from qmt_drake.errors import QmtInputError
from qmt_drake.model.arm import ArmModel
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.model.urdf_check import drive_parameters, load_arm_plant


@dataclass(frozen=True)
class ArmData:
    """An arm as plain data: its URDF, the link the hand is fixed to, the joints fixed (joint -> value, rad
    or m), and the joint-side limits a scenario gives instead of the URDF's (None: the URDF's)."""

    urdf: Path
    hand_frame: str
    lock_joints: dict = field(default_factory=dict)
    effort_limit_Nm: np.ndarray | None = None
    velocity_limit_rad_s: np.ndarray | None = None


@dataclass
class BuiltArm:
    """What build_arm_model makes: plant (finalized, continuous), hand (its Frame), joint_names (the chain,
    base first), drive (gear_ratio, rotor_inertia_kgm2, reflected_inertia_kgm2 (n,), `given`; planar: None)
    and chain (SpatialChain or PlanarChain)."""

    plant: Any
    hand: Any
    joint_names: list
    drive: dict | None
    chain: Any

    @property
    def n_dof(self) -> int:
        return len(self.joint_names)


def build_arm_model(arm: ArmData, carried=None, *, gear_ratio=None, rotor_inertia_kgm2=None,
                    drive_required: bool = True, planar: bool = False, where: str = "actuators",
                    gravity_m_s2=None) -> BuiltArm:
    """The arm's plant and chain (module docstring). carried: a CarriedBody (spatial; its `as_dict()`) or a
    Drake SpatialInertia about the hand frame (planar). gear_ratio / rotor_inertia_kgm2: one per chain joint
    (motor side), refused in one line naming `where` when their count is not the joints'."""
    if planar:
        model = ArmModel.from_urdf(arm.urdf, hand_frame=arm.hand_frame, carried_inertia=carried,
                                   require_gear_ratio=drive_required, gravity_m_s2=gravity_m_s2)
        if model.planar is None:
            raise QmtInputError(f"{arm.urdf}: the joints do not turn about parallel axes along a world axis, so "
                                "the arm has no planar model; load it as a spatial arm")
        return BuiltArm(model.plant, model.hand_frame, list(model.joint_names), None, model.planar)
    plant, hand, names = load_arm_plant(arm.urdf, arm.hand_frame, lock_joints=arm.lock_joints,
                                        effort_limit_Nm=arm.effort_limit_Nm,
                                        velocity_limit_rad_s=arm.velocity_limit_rad_s)
    n = len(names)
    for key, v in (("gear_ratio", gear_ratio), ("rotor_inertia_kgm2", rotor_inertia_kgm2)):
        if v is not None and np.shape(v) != (n,):
            raise QmtInputError(f"{where}.{key} has {np.size(v)} entries; give {n}, one per joint {names}")
    drive = drive_parameters(arm.urdf, names, gear_ratio=gear_ratio, rotor_inertia_kgm2=rotor_inertia_kgm2,
                             source=str(arm.urdf), required=drive_required)
    chain = SpatialChain(plant, hand, reflected_inertia_kgm2=drive["reflected_inertia_kgm2"],
                         carried=None if carried is None else carried.as_dict())
    return BuiltArm(plant, hand, list(names), drive, chain)
