"""The one run of every co-simulation: `CoSim` (what a build made) and `run(cosim) -> dict`.

Every co-simulation kind (the planar magnet and tray arms, the spatial weld, contact and tray hands,
seed 001's energy-time arm) is built by its parts into a `CoSim` (sim/cosim.build_cosim composes them
per scenario) and run here: the one place that makes a Drake `Simulator`. A kind gives three steps:

    start(sim)          the initial state on the simulator's context (and a recording's start)
    advance(sim)        simulate to the end (the kind's own chunks and checks: the weld's release,
                        the magnet's divergence guard), timed as the run's wall clock
    finish(sim, wall_s) the kind's typed result (TransferResult, TrayResult, Execution, or a dict)

and `summarize(result)` turns that result into the summary dict in the one outcome vocabulary
(qmt_drake/outcome.py): "outcome", "held", and the kind's own facts. `run` keeps the typed result in
cosim.result and the simulator in cosim.simulator (its context holds the loggers' data). The scenario's
`simulation.simulator` fields (cosim.simulator_settings) are applied to the Simulator before `start`.

This module imports nothing of the project: every kind's module can run through it without a circle.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pydrake.systems.analysis import ApplySimulatorConfig, ExtractSimulatorConfig, Simulator


@dataclass
class CoSim:
    """A built co-simulation. diagram: the Drake Diagram (its default context at the plan's start where
    the kind allows; `start` sets the rest); plant: its MultibodyPlant; ports: named output ports (the
    diagram's exported ones where it exports them); loggers: named VectorLogSinks; monitor: what
    classifies the run after it (the logged hold check, the tray's log, the transfer monitor; None:
    the kind's finish reads the loggers); handles: the kind's own record (TransferDiagram, TrayDiagram,
    ...), whose attributes a CoSim also answers (cosim.t_final_s = cosim.handles.t_final_s)."""

    kind: str
    diagram: Any
    plant: Any
    start: Callable[[Simulator], None]
    advance: Callable[[Simulator], None]
    finish: Callable[[Simulator, float], Any]
    summarize: Callable[[Any], dict]
    ports: dict = field(default_factory=dict)
    loggers: dict = field(default_factory=dict)
    monitor: Any = None
    handles: Any = None
    simulator: Any = None
    result: Any = None
    # the scenario's simulation.simulator (config/simulation.SimulatorSettings, plain data); None or nothing
    # given: the Simulator as made
    simulator_settings: Any = None

    def __getattr__(self, name: str) -> Any:
        # only called for names the dataclass does not have: the kind's record answers them
        handles = self.__dict__.get("handles")
        if handles is None or name.startswith("__"):
            raise AttributeError(name)
        return getattr(handles, name)


def run(cosim: CoSim) -> dict:
    """Simulate `cosim` to its end and return its summary dict (module docstring); one run per CoSim."""
    if cosim.simulator is not None:
        raise RuntimeError(f"this {cosim.kind} co-simulation has run already; build it again to run it again")
    # Free the reference cycles of earlier diagrams (pydrake's port <-> system cycles) before this
    # run allocates: left to the automatic collector they piled up in a long-lived process and
    # slowed every later run by up to 50% (studies/bench_cosim_floor.py). The young generations
    # hold them; collecting those costs ~1.5 ms.
    gc.collect(1)
    sim = Simulator(cosim.diagram)
    given = cosim.simulator_settings.given() if cosim.simulator_settings is not None else {}
    if given:  # only the scenario's fields over the Simulator as made (sim/sim_settings.py: why)
        cfg = ExtractSimulatorConfig(sim)
        for k, v in given.items():
            setattr(cfg, k, v)
        ApplySimulatorConfig(cfg, sim)
    cosim.simulator = sim
    cosim.start(sim)
    t_wall = time.perf_counter()
    cosim.advance(sim)
    wall = time.perf_counter() - t_wall
    cosim.result = cosim.finish(sim, wall)
    return cosim.summarize(cosim.result)
