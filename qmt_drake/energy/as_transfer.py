"""Seed 001's vertical arm as a joint-space transfer: the spatial planners (toppra, toppra-drake, ruckig,
trajopt, family_optimum, ga) plan a minimum-time motion of an energy-time scenario under its joint-torque
limits (issue 27 item 6: "a minimum-time plan of the vertical arm under its joint-torque limits is
meaningful").

    sc = transfer_scenario_of(E)        # an EnergyArmScenario (a spatial_task.SpatialScenario)
    plan = registry.plan(E, "toppra")   # the energy-time row of a transfer method: the spatial planner on sc

The adapter turns the experiment into what the spatial planners take, so they run unchanged:
- the arm: the experiment's URDF (models/three_link_vertical_ohsaka.urdf), hand frame `tip` (the welded
  tip point mass), no carried part (a CarriedBody of zero mass) and no hand: `terms()` is the joint torques
  alone (no suction, magnet or tray row: nothing is held that could be lost);
- the task: two poses, X(0) and X(T) in the arm's x-z plane (X2 up = world z, y = 0), at joint postures
  fixed here, not by the spatial IK: the start is the experiment's own (lowest centre of gravity,
  energy/kinematics.lowest_cog_posture); the end the posture reaching X(T) with the least joint travel
  from it (kinematics.self_motion_samples, 1/4-degree samples, then Gauss-Newton on the moving joints to
  1e-12 m; the joints that family.moving_joints keeps still stay at their start angles). The face axis is
  the hand frame's y axis, the joints' own axis: its world direction never changes, so the orientation
  half of a task pose always holds;
- the limits: limits.joint_torque_Nm (the YAML's; an experiment without them is refused in one line),
  the URDF's joint speed limit (100 rad/s), and acceleration / jerk bounds the torque limits imply, so
  that they never bind before the torque rows: a_i = 2 max over the straight joint path of
  sum_j |M^-1_ij| (tau_max,j + |g_j|) (the largest acceleration the torques can give at rest, doubled),
  jerk_i = a_i / 10 ms (at 1 ms Ruckig fails to synchronise the joints). An ideal torque source has no speed, acceleration or jerk limit of its own; the
  plan's re-check names the binding limit (joint torque).
The motion time of a fixed-T experiment (ohsaka-fig2's 4.6 s) is the energy-time planner's: a minimum-time
plan ignores it (said in the plan's info).

The plan is of the spatial kind (its file reads back with `load_transfer_plan(path, E)`);
`qmt-drake simulate ohsaka-fig3 --plan P.json` runs it in the energy-time execution (energy/execute.py:
the vertical arm under Drake's inverse-dynamics controller) through `PlanFamily`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from qmt_drake.energy.dynamics import OHSAKA_URDF
from qmt_drake.energy.experiments import Experiment
from qmt_drake.energy.kinematics import self_motion_samples, tip_position
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.contact_wrench import CarriedBody
from qmt_drake.limits.motor_torque import MotorTorqueTerm
from qmt_drake.model.arm_model import ArmData, build_arm_model
from qmt_drake.model.spatial_ik import SpatialIK
from qmt_drake.model.urdf_check import urdf_joint_limits
from qmt_drake.plan import Plan
from qmt_drake.planners import registry
from qmt_drake.retime import load_plan_file
from qmt_drake.spatial_task import SpatialScenario

HAND_FRAME = "tip"
FACE_AXIS = np.array([0.0, 1.0, 0.0])  # the joints' axis (-y) up to sign: its world direction is constant
CHECK_RATE_HZ = 1000.0  # the planners' sampling; the re-check samples at 10x (spatial_task.RECHECK_FACTOR)
JERK_RISE_S = 1e-2  # jerk bound = acceleration bound / this [s] (Ruckig fails to synchronise the joints at 1 ms)
END_TOL_M = 1e-12


@dataclass
class EnergyArmScenario(SpatialScenario):
    """The energy-time arm as a spatial scenario (module docstring): no hand, the joint torques its only
    limit term beyond the joint speed/acceleration bounds."""

    experiment: Experiment | None = None

    def hand_term(self, grip=None):
        raise QmtInputError(f"{self.name}: seed 001's vertical arm carries no part and has no hand; there is no "
                            "hand term")

    def terms(self, grip=None) -> list:
        arm = SimpleNamespace(gear_ratio=self.drive["gear_ratio"], joint_names=self.joint_names,
                              gravity_does_no_work=False)
        return [MotorTorqueTerm(arm, self.torque_limit_Nm / self.drive["gear_ratio"])]


def _x3(X2) -> np.ndarray:
    """A plane point (X1, X2) of seed 001 (X2 up) as a world point: x = X1, y = 0, z = X2."""
    return np.array([float(X2[0]), 0.0, float(X2[1])])


def end_posture(E: Experiment) -> np.ndarray:
    """The end posture (module docstring): least joint travel from the start, on X(T), still joints kept."""
    P = E.problem()
    theta0, XT = P.theta0, P.XT
    Q = self_motion_samples(P.arm, XT)
    d = np.mod(Q - theta0 + np.pi, 2 * np.pi) - np.pi  # each joint the short way round
    moving = np.ones(len(theta0), bool) if E.moving_joints is None else np.isin(np.arange(len(theta0)), E.moving_joints)
    if E.moving_joints is not None:  # a still joint: samples that move it are out
        d = np.where(np.all(np.abs(d[:, ~moving]) < np.radians(1.0), axis=1)[:, None], d, np.inf)
    k = int(np.argmin(np.sum(np.abs(d), axis=1)))
    if not np.isfinite(d[k]).all():
        raise QmtInputError(f"{E.name}: X(T) cannot be reached moving only joints "
                            f"{[j + 1 for j in np.flatnonzero(moving)]}")
    q = theta0 + np.where(moving, d[k], 0.0)
    for _ in range(50):  # Gauss-Newton on the moving joints (minimum-norm step)
        tip, J = P.arm.chain.tip_position_and_jacobian(q)
        r = tip - XT
        if np.linalg.norm(r) < END_TOL_M:
            break
        q[moving] -= np.linalg.pinv(J[:, moving]) @ r
    miss = float(np.linalg.norm(tip_position(P.arm, q) - XT))
    if miss > 1e-9:
        raise QmtInputError(f"{E.name}: no end posture reaches X(T) (closest {miss:.3g} m away)")
    return q


def _implied_acceleration(plant, q_line: np.ndarray, torque_Nm: np.ndarray) -> np.ndarray:
    """(n,) 2 max over q_line of sum_j |M^-1_ij| (tau_max,j + |g_j|): what the torques give at rest, doubled
    (Drake's mass matrix and gravity forces of the arm's plant; its only joints are the chain's)."""
    ctx = plant.CreateDefaultContext()
    out = np.zeros(plant.num_velocities())
    for q in q_line:
        plant.SetPositions(ctx, q)
        M = plant.CalcMassMatrix(ctx)
        g = plant.CalcGravityGeneralizedForces(ctx)
        out = np.maximum(out, np.abs(np.linalg.inv(M)) @ (torque_Nm + np.abs(g)))
    return 2.0 * out


def transfer_scenario_of(E: Experiment) -> EnergyArmScenario:
    """The energy-time experiment E as a spatial scenario (module docstring); one line if it has no
    joint-torque limits."""
    if E.torque_limit_Nm is None:
        raise QmtInputError(f"{E.name}: a minimum-time plan needs the joints' torque limits; give "
                            "limits: joint_torque_Nm: [...] (one per joint, N m) in the scenario")
    P = E.problem()
    urdf = Path(P.arm.urdf_path or OHSAKA_URDF)
    n = P.arm.n_dof
    tau = np.asarray(E.torque_limit_Nm, float)
    built = build_arm_model(ArmData(urdf, HAND_FRAME, {}, tau, None), CarriedBody(0.0), gear_ratio=np.ones(n),
                            rotor_inertia_kgm2=np.zeros(n), drive_required=False, where=f"{E.name}: arm")
    names = list(built.joint_names)
    ik = SpatialIK(built.plant, built.hand, face_axis=FACE_AXIS, name=E.name)
    q_poses = np.array([P.theta0, end_posture(E)])
    poses = np.array([_x3(P.X0), _x3(P.XT)])
    normal = ik.pose(q_poses[0])[1] @ FACE_AXIS
    for q, p in zip(q_poses, poses):  # the planar kinematics against Drake's (URDF frames, X2 = world z)
        ep, ea = ik.errors(q, p, normal=normal)
        if ep > 1e-9 or ea > 1e-9:
            raise QmtInputError(f"{E.name}: the arm's URDF does not move its tip in the x-z plane as seed 001's "
                                f"planar model does (error {ep:.3g} m, {ea:.3g} rad); it cannot be planned as a transfer")
    accel = _implied_acceleration(built.plant, np.linspace(q_poses[0], q_poses[1], 21), tau)
    vel = urdf_joint_limits(urdf, names)["velocity_limit_rad_s"]
    normals = np.array([normal, normal])
    sc = EnergyArmScenario(
        name=E.name, path=Path(E.source_path) if E.source_path else urdf, urdf=urdf, hand_frame=HAND_FRAME,
        lock_joints={}, joint_names=names, plant=built.plant, ik=ik, chain=built.chain, body=CarriedBody(0.0),
        grip=None, velocity_limit_rad_s=np.asarray(vel, float), acceleration_limit_rad_s2=accel,
        jerk_limit_rad_s3=accel / JERK_RISE_S, torque_limit_Nm=tau, drive=built.drive, face_normal=normal,
        poses_m=poses, q_poses_rad=q_poses, path_points_m=poses, q_path_rad=q_poses, path_pose_index=np.arange(2),
        check_rate_hz=CHECK_RATE_HZ, hand_kind="none", face_axis=FACE_AXIS, pose_normals=normals,
        path_normals=normals, uncertainty={}, experiment=E)
    return sc


def plan_transfer(E: Experiment, *, method: str, seed: int = 0, progress=None, **options) -> Plan:
    """The spatial planner `method` on transfer_scenario_of(E): its spatial-kind Plan, noted as E's."""
    sc = transfer_scenario_of(E)
    row = registry.find(registry.SPATIAL, method)
    own = {"seed": seed, "progress": progress, "method": row.name}
    plan = row.function(sc, **{k: own[k] for k in row.passes}, **options)
    note = "a minimum-time plan of seed 001's arm under its joint-torque limits (energy/as_transfer.py)"
    if E.fixed_T_s is not None:
        note += f"; the experiment's fixed T = {E.fixed_T_s} s is the energy-time planner's, not used here"
    plan.extra["energy_time_arm"] = note
    return plan


def load_transfer_plan(path, E: Experiment) -> Plan:
    """A spatial-kind plan file of E's arm (module docstring) or a retimed path of it (`qmt-drake retime`),
    rebuilt and checked against E's transfer."""
    return load_plan_file(path, transfer_scenario_of(E))


def file_kind(path) -> str | None:
    """The `scenario_kind` a plan file states (None: unreadable or none; plan_files.load_plan says why)."""
    try:
        return json.loads(Path(path).read_text()).get("scenario_kind")
    except (OSError, ValueError, AttributeError):
        return None


class PlanFamily:
    """What the energy-time execution (energy/execute.build_execution_cosim) reads of a Fourier family,
    for any plan: sample(x, t) -> (q, qd, qdd), unpack(x)[2] = T, n. `x` is ignored (the plan is the motion)."""

    def __init__(self, plan: Plan) -> None:
        self.plan, self.n = plan, plan.n_dof

    def sample(self, x, t):
        t = np.clip(np.asarray(t, float), 0.0, self.plan.motion_time_s)
        return self.plan.sample(t)

    def unpack(self, x):
        return None, None, self.plan.motion_time_s

