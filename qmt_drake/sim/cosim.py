"""One co-simulation build path: `build_cosim(scenario, plan, **options) -> CoSim` and `run(cosim) -> dict`.

    cosim = build_cosim(scenario, plan, time_scale=1.0)   # the Drake Diagram and its handles
    summary = run(cosim)                                   # summary["outcome"], ... (qmt_drake/outcome.py)

build_cosim composes the scenario's parts, each adding itself to the kind's DiagramBuilder:

    hands   magnet contact (planar: sim/magnet_hand.add_magnet_hand; spatial: spatial_contact_hand.ContactHand),
            suction contact (ContactHand), breakable weld (spatial_cosim.WeldHand), tray contact (spatial:
            spatial_tray_hand.TrayCupHand; the CRANE-X7's tray and bottle: tray/cosim.build_tray_diagram)
    drives  DC motor + gear + PID (planar: sim/magnet_actuation; spatial: SpatialMotorDrive.add_to), ideal
            inverse dynamics (spatial_cosim.add_ideal_controller; energy/execute's), Dynamixel servos
            (tray/cosim.build_tray_diagram)

per scenario kind (four assemblies): a planar transfer scenario through its hand plug-in's build_cosim
(hands.py: the magnet hand's closed loop, sim/diagram.build_transfer_diagram; the tray's servos and bottle,
tray/cosim.build_tray_diagram), a spatial one through spatial_cosim.assemble (one assembly for its three
hand parts and two drives), an energy-time one through energy/execute.build_execution_cosim. `run`
(sim/cosim_run.py) is the one place a Simulator is made; every kind's `simulate` goes through it.

Options: time_scale (replay time_scale times slower), record_path (a Meshcat HTML replay), time_step_s
(the plant step [s]; None: the kind's default), feedforward and, for planar magnet arms,
implicit_loop_damping; spatial: actuator ('ideal' or 'dc_motor'), export (export the named ports, for
composition in user code; api.build_diagram sets it). A run option given here overrides the scenario's
`simulation:` section (config/simulation.py: Drake's plant and simulator settings), which overrides the
kind's default (sim/sim_settings.py).
"""

from __future__ import annotations

from typing import Any

from qmt_drake.config.scenario import Scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import energy_cosim, hand_plugin
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.cosim_run import CoSim, run
from qmt_drake.sim.spatial_cosim import build_spatial_cosim
from qmt_drake.spatial_task import SpatialScenario

__all__ = ["CoSim", "build_cosim", "run"]

SPATIAL_OPTIONS = ("time_scale", "record_path", "time_step_s", "actuator", "feedforward", "export", "controller_sc",
                   "contact", "grip")


def build_cosim(scenario: Any, plan: Any, **options: Any) -> CoSim:
    """The co-simulation of `plan` on `scenario` (module docstring), built, not run."""
    if isinstance(scenario, SpatialScenario):
        unknown = sorted(set(options) - set(SPATIAL_OPTIONS))
        if unknown:
            raise QmtInputError(f"{unknown[0]}: not an option of the spatial co-simulation; use "
                                f"{', '.join(SPATIAL_OPTIONS)}")
        time_scale = options.pop("time_scale", 1.0)
        traj = plan.trajectory if time_scale == 1.0 else TimeScaled(plan.trajectory, time_scale)
        if options.get("actuator") is None:
            options["actuator"] = "ideal"
        if options.get("feedforward") is None:
            options["feedforward"] = "full"
        return build_spatial_cosim(scenario, traj, **options)
    if isinstance(scenario, Scenario):
        return hand_plugin(scenario).build_cosim(scenario, plan, **options)
    return energy_cosim(plan, **options)
