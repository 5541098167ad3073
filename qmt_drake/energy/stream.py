"""The energy-time arm as a target of `qmt-drake export` (qmt_drake/export.py): its joint names (the URDF's
moving joints, in the plant's order, the plan's columns), its check rate, and the stream's check: the joint
torques (gravity included, energy/dynamics.inverse_dynamics_with_gravity) over the YAML's joint torque limits
(limits.joint_torque_Nm: ours, not the paper's, which states none; the energy-time optimum is not planned
under them, the front's time-optimal end is). Sampled only, at the check rate: no refinement between the
samples (the dict says so)."""

from __future__ import annotations

import math

import numpy as np
from pydrake.multibody.tree import JointIndex

from qmt_drake.energy.dynamics import inverse_dynamics_with_gravity, make_plant
from qmt_drake.energy.experiments import Experiment
from qmt_drake.errors import QmtInputError

CHECK_RATE_HZ = 10_000.0  # as a planar scenario's re-check


class EnergyStreamTarget:
    """export's view of an energy-time Experiment (module docstring)."""

    recheck_rate_hz = CHECK_RATE_HZ

    def __init__(self, E: Experiment) -> None:
        if E.torque_limit_Nm is None:
            raise QmtInputError(f"scenario {E.name}: no joint torque limit (limits.joint_torque_Nm; seed 001 states "
                                "none), so a stream has no limit to be re-checked against; add one to a copy of "
                                "the YAML file")
        self.E, self.name = E, E.name
        plant = make_plant(str(E.arm.urdf_path))
        joints = [plant.get_joint(JointIndex(i)) for i in range(plant.num_joints())]
        self.joint_names = [j.name() for j in joints if j.num_velocities() > 0]
        self.limit_Nm = np.asarray(E.torque_limit_Nm, float)

    def stream_check(self, traj, rate_hz: float) -> dict:
        n = max(int(math.ceil(traj.duration_s * rate_hz)), 2)
        q, qd, qdd = traj.sample(np.linspace(0.0, traj.duration_s, n + 1))
        tau = inverse_dynamics_with_gravity(q, qd, qdd, self.E.arm, derivatives=False)
        r = np.abs(tau).max(axis=0) / self.limit_Nm
        out = {f"joint_torque[{name}]": float(v) for name, v in zip(self.joint_names, r)}
        binding = max(out, key=out.get)
        return {**out, "max": out[binding], "binding": binding, "sampled_only": True,
                "note": "limits.joint_torque_Nm is the YAML's (not the paper's): the energy-time optimum is not "
                        "planned under it, the time-optimal end of the front is"}
