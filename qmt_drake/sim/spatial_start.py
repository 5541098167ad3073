"""The spatial co-simulation's start in its own plant's static equilibrium (issue 29).

A real arm starts a move already holding the part at the pick pose: its controller has settled there. A
sweep case simulates a DRAWN plant (motors, payload) under the NOMINAL law and feedforward, so a run started
at rest at the plan's first pose q0 with the law's default state is not in equilibrium: the arm jumps in the
first milliseconds and the hold check sees that jump (docs/robustness.md, "start artifacts"). `settle` sets
the drive's free start state so that the torque the drive applies at t = 0 with the reference AT REST (the
plan's first pose, zero speed and acceleration: the plan's own start acceleration is the move's, not the
hold's) equals the static torque of the simulated plant:

- a joint whose law has an integral (the dc_motor PID, Ki > 0): its integral state z [rad*s], the arm at q0
  (no tracking error at the start: the integral carries the load, as it would after settling);
- a joint without one (the ideal inverse-dynamics controller, a dc_motor PD law): its position, the law's
  settled pose q* where its proportional term balances the load the nominal feedforward misses (a PD law
  holds a load with a steady error; the plan's reference still starts at q0, so that error is the
  tracking error at t = 0).

The static torque (`static_torque`) is the simulated plant's: minus its gravity generalized forces on the
arm's joints (everything on the arm's tree, a contact hand's jointed part included) plus, for each free
body the hand carries (the weld hand's part, the tray's cup), J^T of its weight at its centre of mass, J the
Jacobian of that point fixed in the hand frame. Solved by Newton on the drive's actual torque (the diagram's
actuation input of the arm: motors, gears, current and voltage limits, saturation), a finite-difference
Jacobian; a drive that cannot hold the load at rest (saturated) keeps its closest state and the run shows it.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.model.actuator_order import actuator_joint_names
from qmt_drake.systems.joint_tracking import JointPidController

NEWTON_ITERATIONS = 12
RESIDUAL_TOL_NM = 1e-9  # x (1 + the largest static torque) [N*m]
Q_STEP_RAD = 1e-6  # the finite-difference step of a joint position
Z_STEP_V = 1e-2  # the finite-difference step of an integral state, as the voltage it adds [V]
SEAT_STEP = 1e-9  # the finite-difference step of a welded part's seat offset [m, rad]
SEAT_TOL_M_S = 1e-9  # the welded part's largest speed after the first step [m/s, rad/s]


def arm_velocity_indices(plant, arm, joint_names) -> np.ndarray:
    """The plant's velocity indices of the named arm joints (in the given order)."""
    return np.array([plant.GetJointByName(n, arm).velocity_start() for n in joint_names])


def arm_position_indices(plant, arm, joint_names) -> np.ndarray:
    """The plant's position indices of the named arm joints (in the given order)."""
    return np.array([plant.GetJointByName(n, arm).position_start() for n in joint_names])


def static_torque(plant, pctx, arm, H, joint_names) -> np.ndarray:
    """The joint torques [N*m] (joint_names order) holding the simulated plant at rest in its present pose:
    -gravity on the arm's joints plus J^T of every carried free body's weight (module docstring)."""
    v_idx = arm_velocity_indices(plant, arm, joint_names)
    tau = -plant.CalcGravityGeneralizedForces(pctx)[v_idx]
    g = plant.gravity_field().gravity_vector()
    X_WH = H.CalcPoseInWorld(pctx)
    for index in plant.GetFloatingBaseBodies():
        body = plant.get_body(index)
        if body.model_instance() == arm:
            continue
        p_WC = plant.EvalBodyPoseInWorld(pctx, body) @ body.CalcCenterOfMassInBodyFrame(pctx)
        J = plant.CalcJacobianTranslationalVelocity(pctx, JacobianWrtVariable.kV, H, X_WH.inverse() @ p_WC,
                                                    plant.world_frame(), plant.world_frame())
        tau = tau - J[:, v_idx].T @ (body.get_mass(pctx) * g)
    return tau


def _at_rest(src, src_a, q0, ahead=None) -> None:
    """The reference sources (TrajectorySource of the state, of the acceleration) told to hold q0 at rest, and
    the held law's compensated reference (joint_tracking.HoldCompensatedReference, which evaluates the
    plan itself) with them."""
    rest_q, rest_a = PiecewisePolynomial(np.asarray(q0, float).reshape(-1, 1)), PiecewisePolynomial(np.zeros((len(q0), 1)))
    src.UpdateTrajectory(rest_q)
    src_a.UpdateTrajectory(rest_a)
    if ahead is not None:
        ahead.update_reference(rest_q, rest_a)


def settle(root, plant, arm, H, src, src_a, reference, q0, seat, controller=None, ki_V_per_rad_s=None,
           welded_part=None, ahead=None) -> dict:
    """Set the drive's start state in root (the simulator's context, at t = 0) so that the arm, the part
    seated (seat(pctx): the hand's seat at the present pose), starts in static equilibrium (module
    docstring). controller: the dc_motor law when it runs as a JointPidController, ki_V_per_rad_s its integral
    gains (actuator order; a zero: that joint settles by its position); None: no integral. welded_part: the
    weld hand's free part (`seat_welded_part`), or None. ahead: the held law's compensated reference
    (HoldCompensatedReference) if the diagram has one: put at rest with the sources and restored.
    Returns {"residual_Nm": the largest |applied - static| left [N*m], "q_start_rad": the arm's start pose
    (actuator order), "part_speed_after_step": the welded part's largest speed after one step, or None}."""
    pctx = plant.GetMyMutableContextFromRoot(root)
    names = actuator_joint_names(plant, arm)  # the actuation input's order
    q_idx = arm_position_indices(plant, arm, names)
    ki, cctx = np.zeros(len(names)), None
    if isinstance(controller, JointPidController) and ki_V_per_rad_s is not None and np.any(ki_V_per_rad_s):
        ki = np.broadcast_to(np.asarray(ki_V_per_rad_s, float), (len(names),))
        cctx = controller.GetMyMutableContextFromRoot(root)
    by_z = ki != 0.0
    z = np.zeros(len(names))
    q = plant.GetPositions(pctx)[q_idx].copy()
    actuation = plant.get_actuation_input_port(arm)
    pp, acc = reference[:2]
    _at_rest(src, src_a, q0, ahead)
    root.SetTime(root.get_time())  # the sources' outputs recomputed (their cached values depend on time only)

    def apply(p):
        z[by_z], q[~by_z] = p[by_z], p[~by_z]
        x = plant.GetPositions(pctx)
        x[q_idx] = q
        plant.SetPositions(pctx, x)
        seat(pctx)
        if cctx is not None:
            controller.set_integral(cctx, z)

    def residual(p):
        apply(p)
        return actuation.Eval(pctx) - static_torque(plant, pctx, arm, H, names)

    p = np.where(by_z, z, q)
    step = np.where(by_z, Z_STEP_V / np.where(by_z, ki, 1.0), Q_STEP_RAD)
    try:
        r = residual(p)
        best = (np.abs(r).max(), p.copy())
        tol = RESIDUAL_TOL_NM * (1.0 + np.abs(static_torque(plant, pctx, arm, H, names)).max())
        for _ in range(NEWTON_ITERATIONS):
            if best[0] <= tol:
                break
            J = np.column_stack([(residual(p + step[j] * np.eye(len(p))[j]) - r) / step[j] for j in range(len(p))])
            p = p - np.linalg.lstsq(J, r, rcond=None)[0]
            r = residual(p)
            if np.abs(r).max() < best[0]:
                best = (np.abs(r).max(), p.copy())
        apply(best[1])
        seat_speed = None if welded_part is None else seat_welded_part(plant, pctx, H, welded_part)
    finally:
        src.UpdateTrajectory(pp)
        src_a.UpdateTrajectory(acc)
        if ahead is not None:
            ahead.update_reference(pp, acc)
        root.SetTime(root.get_time())
    return {"residual_Nm": float(best[0]), "q_start_rad": q.copy(), "part_speed_after_step": seat_speed}


def velocities_after_step(plant, pctx) -> np.ndarray:
    """All the discrete plant's generalized velocities after one step from pctx (its inputs evaluated through
    the diagram), whether its output ports are sampled (the step is then an unrestricted update) or live."""
    if plant.IsDifferenceEquationSystem()[0]:
        return plant.EvalUniquePeriodicDiscreteUpdate(pctx).value()[plant.num_positions():].copy()
    scratch = plant.CreateDefaultContext()
    plant.CalcForcedUnrestrictedUpdate(pctx, scratch.get_mutable_state())
    return plant.GetVelocities(scratch)


def seat_welded_part(plant, pctx, H, part) -> float:
    """The weld hand's part seated where its weld constraint already carries its weight: SAP's weld is a stiff
    regularised constraint, so a part seated exactly on the hand frame sinks in the first steps while the
    constraint force builds up, and the hold check (the part's own acceleration) sees a start transient (+0.008
    on the nominal UR5 suction part). Solved by Newton on the part's velocity after one plant step, its pose
    offset in H (6, small) the unknowns; returns the largest part speed left after that step."""
    X_WH = H.CalcPoseInWorld(pctx)
    v0 = part.floating_velocities_start_in_v()

    def speed_after_step(x):
        plant.SetFreeBodyPose(pctx, part, X_WH @ RigidTransform(RollPitchYaw(x[:3]), x[3:]))
        return velocities_after_step(plant, pctx)[v0:v0 + 6]

    x = np.zeros(6)
    r = speed_after_step(x)
    best = (np.abs(r).max(), x.copy())
    for _ in range(NEWTON_ITERATIONS):
        if best[0] <= SEAT_TOL_M_S:
            break
        J = np.column_stack([(speed_after_step(x + SEAT_STEP * e) - r) / SEAT_STEP for e in np.eye(6)])
        x = x - np.linalg.lstsq(J, r, rcond=None)[0]
        r = speed_after_step(x)
        if np.abs(r).max() < best[0]:
            best = (np.abs(r).max(), x.copy())
    speed_after_step(best[1])
    return float(best[0])
