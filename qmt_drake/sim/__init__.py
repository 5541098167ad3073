"""Co-simulation of a planned transfer (plan -> PID -> DC motors with gears -> arm -> magnet -> payload).

    plant.py        transfer_plant_config (the plant settings every system relies on), add_transfer_plant,
                    finalize_transfer_plant (default state = plan start, payload seated), set_initial_state
    magnet_hand.py  coil current (given or calibrated from the thesis's slip boundary), magnet wiring
    actuation.py    motors and gains from the scenario, implicit loop damping, feedforward, step limits
    magnet_actuation.py  what each actuator kind checks and builds (its plug-in's MagnetActuation:
                    DC motors with PID, ideal torque sources); the diagram and the runner ask it
    reference.py    the plan as time-scaled Drake trajectories; GenesPlan
    diagram.py      build_transfer_diagram -> TransferDiagram (default context ready to simulate)
    runner.py       run_diagram, simulate_transfer -> TransferResult, run_transfer_simulate (JSON summary)
    posthoc.py      the monitor's summary from per-step C++ logs after the run (step_logs=True)
    cosim.py        build_cosim(scenario, plan) -> CoSim for every kind, and run (cosim_run.py: the one Simulator)

The names below are re-exported so user code can `from qmt_drake.sim import ...`.
"""

from qmt_drake.sim.actuation import (
                                     EXPLICIT_MAX_TIME_STEP_S,
                                     EXPLICIT_TIME_STEP_S,
                                     FEEDFORWARD_OPTIONS,
                                     IMPLICIT_TIME_STEP_S,
                                     add_ideal_torque_actuation,
                                     add_implicit_damping_actuation,
                                     add_inverse_dynamics_feedforward,
                                     check_time_step,
                                     default_time_step_s,
                                     explicit_step_known_unstable,
                                     ideal_joint_gains,
                                     motor_params_for,
                                     pid_gains_for,
)
from qmt_drake.sim.diagram import TransferDiagram, build_transfer_diagram
from qmt_drake.sim.magnet_actuation import (
                                     DC_MOTOR_ACTUATION,
                                     IDEAL_TORQUE_ACTUATION,
                                     ActuationOptions,
                                     ActuationPorts,
                                     ActuationSetup,
                                     ActuationSite,
                                     MagnetActuation,
                                     magnet_actuation_of,
)
from qmt_drake.sim.magnet_hand import (
                                     MAGNET_EFFECTIVE_GAP_M,
                                     add_magnet_hand,
                                     calibrated_coil_current_A,
                                     coil_current_for,
                                     hold_lever_m,
                                     magnet_hand_of,
                                     magnet_params_for,
)
from qmt_drake.sim.plant import (
                                     TransferPlant,
                                     add_transfer_plant,
                                     finalize_transfer_plant,
                                     move_loop_damping_into_plant,
                                     set_initial_state,
                                     transfer_plant_config,
)
from qmt_drake.sim.reference import GenesPlan, check_time_scale, plan_start, reference_trajectories
from qmt_drake.sim.runner import (
                                     HELD_SLIP_LIMIT_M,
                                     TransferResult,
                                     check_simulation_inputs,
                                     feedforward_keywords,
                                     logged_series,
                                     make_result,
                                     planned_peak_moment_Nm,
                                     planned_peak_motor_torque_Nm,
                                     run_diagram,
                                     run_transfer_simulate,
                                     simulate_transfer,
)

__all__ = [n for n in dir() if not n.startswith("_")]
