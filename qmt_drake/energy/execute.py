"""Run a planned seed-001 trajectory on a Drake co-simulation of the vertical arm, with gravity.

Diagram (continuous-time MultibodyPlant of models/three_link_vertical_ohsaka.urdf, gravity -z):

    TrajectorySource(q_d, qd_d) --desired_state--------> InverseDynamicsController --generalized_force-->
    TrajectorySource(qdd_d)     --desired_acceleration-> (kp, ki, kd; own plant   plant.actuation (N m)
    plant.state ------------------estimated_state------>  copy, gravity included)

Actuators: ideal torque sources (gear ratio 1, no rotor inertia, no saturation: the paper models
none and states no torque limit); the URDF's 1000 N m effort limit is never reached and is
reported beside the peak torque. The controller computes
    tau = M(q) (qdd_d + kp (q_d - q) + kd (qd_d - qd) + ki int(q_d - q)) + C(q, qd) + g(q),
i.e. the planned torque as feedforward, PID on the error, and gravity compensation. Gains are in
acceleration units: natural frequency 30 rad/s, damping 1 (kp = 900 1/s^2, kd = 60 1/s), ki = 0.

The reference is sampled exactly from the Fourier family at 5 kHz and linearly interpolated
(FirstOrderHold), and held at theta_T after T. Outputs (ports logged every 0.5 ms): t (s), q, qd
(rad, rad/s), applied torque (N m), and the planned torque at the same times.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, MatrixGain, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.config.simulation import NO_SIMULATION, Simulation
from qmt_drake.energy.as_transfer import PlanFamily
from qmt_drake.energy.dynamics import OHSAKA_URDF, inverse_dynamics_with_gravity
from qmt_drake.errors import QmtInputError
from qmt_drake.model.actuator_order import joint_to_actuation_matrix
from qmt_drake.model.arm import add_urdf
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD, transfer_outcome
from qmt_drake.plan import ENERGY_PLAN_KIND
from qmt_drake.recording import add_meshcat_visualizer, make_headless_meshcat, save_recording, start_recording
from qmt_drake.sim.cosim_run import CoSim, run
from qmt_drake.sim.sim_settings import simulation_of


@dataclass
class Execution:
    t_s: np.ndarray
    q_rad: np.ndarray
    q_des_rad: np.ndarray
    tau_Nm: np.ndarray
    tau_plan_Nm: np.ndarray
    T_s: float
    recording: Path | None

    @property
    def max_tracking_error_rad(self) -> float:
        return float(np.max(np.abs(self.q_rad - self.q_des_rad)))

    @property
    def peak_torque_Nm(self) -> np.ndarray:
        return np.max(np.abs(self.tau_Nm), axis=0)

    def summary(self) -> dict:
        during = self.t_s <= self.T_s
        return {"T_s": self.T_s, "max_tracking_error_rad": self.max_tracking_error_rad,
                "max_tracking_error_during_motion_rad": float(np.max(np.abs(self.q_rad - self.q_des_rad)[during])),
                "final_error_rad": float(np.max(np.abs(self.q_rad[-1] - self.q_des_rad[-1]))),
                "peak_torque_Nm": self.peak_torque_Nm,
                "peak_planned_torque_Nm": np.max(np.abs(self.tau_plan_Nm), axis=0),
                "max_torque_minus_plan_Nm": float(np.max(np.abs(self.tau_Nm - self.tau_plan_Nm)[during])),
                "effort_limit_Nm": 1000.0,
                "recording": str(self.recording) if self.recording else None}


def build_execution_cosim(family, x, settle_s: float = 0.3, wn_rad_s: float = 30.0, zeta: float = 1.0,
                          recording_path: str | Path | None = None, initial_error_rad=None,
                          urdf: str | Path = OHSAKA_URDF, summarize=None,
                          simulation: Simulation = NO_SIMULATION) -> CoSim:
    """The diagram of the module docstring as a CoSim (cosim_run.run); its result an Execution
    (summarised by Execution.summary, or `summarize`). simulation: the scenario's `simulation` section
    (config/simulation.py): plant.time_step > 0 makes the simulated plant discrete at that step (the
    controller's model stays continuous), its simulator fields replace the run's (accuracy: the 1e-6 here)."""
    T = float(family.unpack(x)[2])
    n = family.n
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, simulation.plant.time_step or 0.0)
    arm = add_urdf(plant, urdf)
    plant.Finalize()
    ctrl_plant = MultibodyPlant(0.0)
    add_urdf(ctrl_plant, urdf)
    ctrl_plant.Finalize()

    t = np.linspace(0.0, T, int(np.ceil(T * 5000)) + 1)
    q, qd, qdd = family.sample(x, t)
    t_ext = np.append(t, T + settle_s + 1.0)
    q_ext = np.vstack([q, q[-1]])
    qd_ext = np.vstack([qd, 0 * qd[-1]])
    qdd_ext = np.vstack([qdd, 0 * qdd[-1]])
    xs = builder.AddNamedSystem("desired_state", TrajectorySource(
        PiecewisePolynomial.FirstOrderHold(t_ext, np.hstack([q_ext, qd_ext]).T)))
    acc = builder.AddNamedSystem("desired_acceleration", TrajectorySource(
        PiecewisePolynomial.FirstOrderHold(t_ext, qdd_ext.T)))
    kp = np.full(n, wn_rad_s ** 2)
    kd = np.full(n, 2 * zeta * wn_rad_s)
    ctl = builder.AddNamedSystem("controller", InverseDynamicsController(
        ctrl_plant, kp, np.zeros(n), kd, True))
    builder.Connect(plant.get_state_output_port(), ctl.get_input_port_estimated_state())
    builder.Connect(xs.get_output_port(), ctl.get_input_port_desired_state())
    builder.Connect(acc.get_output_port(), ctl.get_input_port_desired_acceleration())
    _connect_by_name(builder, plant, arm, ctl.get_output_port_control())
    log_x = LogVectorOutput(plant.get_state_output_port(), builder, 5e-4)
    log_u = LogVectorOutput(ctl.get_output_port_control(), builder, 5e-4)
    log_d = LogVectorOutput(xs.get_output_port(), builder, 5e-4)
    vis = meshcat = None
    if recording_path is not None:
        meshcat = make_headless_meshcat()
        # the vertical arm spans +-0.7 m in x-z: look at it from -y
        meshcat.SetCameraPose(np.array([0.0, -2.2, 0.2]), np.array([0.0, 0.0, 0.0]))
        vis = add_meshcat_visualizer(builder, scene_graph, meshcat)
    diagram = builder.Build()

    def start(sim) -> None:
        pctx = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
        plant.SetPositions(pctx, q[0] + (0 if initial_error_rad is None else np.asarray(initial_error_rad)))
        plant.SetVelocities(pctx, np.zeros(n))
        if simulation.simulator.accuracy is None:  # the scenario's accuracy is applied by cosim_run.run
            sim.get_mutable_integrator().set_target_accuracy(1e-6)
        sim.Initialize()
        if vis is not None:
            start_recording(vis)

    def finish(sim, wall) -> Execution:
        ctx = sim.get_context()
        rec = None if vis is None else save_recording(vis, meshcat, recording_path)
        X = log_x.FindLog(ctx).data().T
        U = log_u.FindLog(ctx).data().T
        Dd = log_d.FindLog(ctx).data().T
        ts = log_x.FindLog(ctx).sample_times()
        qp, qdp, qddp = family.sample(x, ts)
        tau_plan = inverse_dynamics_with_gravity(qp, qdp, qddp, derivatives=False)
        return Execution(ts, X[:, :n], Dd[:, :n], U, tau_plan, T, rec)

    return CoSim("energy_time", diagram, plant, start, lambda sim: sim.AdvanceTo(T + settle_s), finish,
                 summarize or (lambda ex: ex.summary()), monitor=None,
                 ports={"desired_state": xs.get_output_port(), "arm_state": plant.get_state_output_port(),
                        "joint_torque": ctl.get_output_port_control()},
                 loggers={"arm_state": log_x, "joint_torque": log_u, "desired_state": log_d},
                 simulator_settings=simulation.simulator)


def _connect_by_name(builder, plant, arm, torque_port) -> None:
    """The controller's generalized forces (the plant's velocity order, one per joint) into the actuators
    by their joints' names (model/actuator_order); the plant's own actuation port when the orders agree
    (the arm is the plant's only actuated instance)."""
    joints = [plant.get_joint(j).name() for j in plant.GetJointIndices(arm) if plant.get_joint(j).num_velocities()]
    P = joint_to_actuation_matrix(plant, arm, joints)
    if P.shape[0] != P.shape[1] or not np.array_equal(P, np.eye(len(joints))):
        gain = builder.AddNamedSystem("joint_torque_to_actuators", MatrixGain(P))
        builder.Connect(torque_port, gain.get_input_port())
        torque_port = gain.get_output_port()
    builder.Connect(torque_port, plant.get_actuation_input_port())


def execute(family, x, settle_s: float = 0.3, wn_rad_s: float = 30.0, zeta: float = 1.0,
            recording_path: str | Path | None = None, initial_error_rad=None,
            urdf: str | Path = OHSAKA_URDF) -> Execution:
    """Run family(x) on the co-simulation (build_execution_cosim, the one run); its Execution."""
    cosim = build_execution_cosim(family, x, settle_s, wn_rad_s, zeta, recording_path, initial_error_rad, urdf)
    run(cosim)
    return cosim.result


def _plan_summary(plan, summary: dict) -> dict:
    # the one outcome vocabulary: nothing can be lost (the tip mass is welded), so carried = reached the goal
    outcome = transfer_outcome(None, False, summary["final_error_rad"], ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
    summary.update(scenario=plan.scenario.name, method=plan.method, motion_time_s=plan.motion_time_s,
                   outcome=outcome, held=outcome == "carried", final_goal_error_rad=summary["final_error_rad"],
                   reached_goal=bool(summary["final_error_rad"] <= ARRIVAL_TOLERANCE_DC_MOTOR_RAD),
                   arrival_tolerance_rad=ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
    return summary


MAX_TIME_STEP_S = 10e-3  # a discrete plant's largest step: the 30 rad/s inverse-dynamics loop stays resolved


def check_time_step(time_step_s, name: str = "time_step_s", per_s: float = 1.0) -> float | None:
    """A run's plant step [s] for seed 001's arm (None: the scenario's section, else continuous); one line naming
    `name` (given in units of 1/per_s s, e.g. per_s=1e3 for --time-step-ms) outside (0, MAX_TIME_STEP_S]."""
    if time_step_s is None:
        return None
    ok = isinstance(time_step_s, (int, float)) and not isinstance(time_step_s, bool) and np.isfinite(time_step_s)
    if not (ok and 0.0 < time_step_s <= MAX_TIME_STEP_S):
        shown = f"{time_step_s * per_s:g}" if ok else repr(time_step_s)
        raise QmtInputError(f"{name} {shown}: the energy-time execution takes a plant step in "
                            f"(0, {MAX_TIME_STEP_S * per_s:g}] {'ms' if per_s == 1e3 else 's'} (default: a continuous plant)")
    return float(time_step_s)


def _stepped(simulation: Simulation, time_step_s: float | None) -> Simulation:
    """The scenario's section with the run's plant step (None: the section's own, else continuous)."""
    if time_step_s is None:
        return simulation
    return dataclasses.replace(simulation, plant=dataclasses.replace(simulation.plant, time_step=float(time_step_s)))


def _with_step(summary: dict, simulation: Simulation) -> dict:
    summary["time_step_s"] = simulation.plant.time_step  # None: a continuous plant (error-controlled integrator)
    return summary


def build_plan_execution_cosim(plan, record_path: str | Path | None = None, time_step_s: float | None = None) -> CoSim:
    """`plan` (an energy-time Plan) as a CoSim: its summary is Execution.summary with the scenario, the method,
    the motion time [s], whether the arm reached the goal (outcome.py's arrival tolerance [rad]) and the
    outcome word: seed 001 carries nothing that can be lost, so it is carried (goal reached) or
    unfinished. Another kind's plan: QmtInputError."""
    if getattr(plan, "scenario_kind", None) != ENERGY_PLAN_KIND or plan.problem is None:
        raise QmtInputError(f"a {getattr(plan, 'scenario_kind', type(plan).__name__)} plan cannot run in the "
                            "energy-time execution; plan this energy-time scenario first")
    sim = _stepped(simulation_of(plan.scenario), check_time_step(time_step_s))
    return build_execution_cosim(plan.problem.family, plan.x, recording_path=record_path,
                                 summarize=lambda ex: _with_step(_plan_summary(plan, ex.summary()), sim),
                                 simulation=sim)


def execute_plan(plan, record_path: str | Path | None = None, time_step_s: float | None = None) -> dict:
    """`plan` executed by build_plan_execution_cosim and the one run: its summary dict. time_step_s [s]: the
    plant step (a run option over the scenario's simulation.plant.time_step; None and no section: continuous)."""
    return run(build_plan_execution_cosim(plan, record_path, time_step_s))


def execute_transfer_plan(plan, record_path: str | Path | None = None, time_step_s: float | None = None) -> dict:
    """A transfer planner's plan of seed 001's arm (energy/as_transfer.py: a spatial-kind plan) executed by the
    same co-simulation (its samples as the reference, the scenario's URDF): the summary of execute_plan."""
    if getattr(plan.scenario, "experiment", None) is None:
        raise QmtInputError(f"a {plan.scenario_kind} plan of {plan.scenario.name} is not a plan of seed 001's arm; "
                            "plan this energy-time scenario first")
    sim = _stepped(simulation_of(plan.scenario.experiment), check_time_step(time_step_s))
    return run(build_execution_cosim(PlanFamily(plan), None, recording_path=record_path, urdf=plan.scenario.urdf,
                                     summarize=lambda ex: _with_step(_plan_summary(plan, ex.summary()), sim),
                                     simulation=sim))


def plot_execution(ex: Execution, path, title: str = "") -> None:
    # lazy: plots only; start-up time, headless runs never load it
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(2, 1, figsize=(6, 5), sharex=True)
    for i in range(ex.q_rad.shape[1]):
        axs[0].plot(ex.t_s, np.degrees(ex.q_rad[:, i] - ex.q_des_rad[:, i]), label=f"joint {i + 1}")
        axs[1].plot(ex.t_s, ex.tau_Nm[:, i], label=f"applied {i + 1}")
        axs[1].plot(ex.t_s, ex.tau_plan_Nm[:, i], "k:", lw=0.8)
    for ax in axs:
        ax.axvline(ex.T_s, color="0.6", lw=0.8)
        ax.legend(fontsize=7)
    axs[0].set_ylabel("q - q_des (deg)")
    axs[1].set_ylabel("torque (N m); dotted: plan")
    axs[1].set_xlabel("t (s)")
    axs[0].set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    plt.close(fig)
