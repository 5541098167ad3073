"""The fastest time scale at which a spatial plan is carried in the co-simulation.

A plan resting on a limit (TOPP-RA's is time-optimal) leaves no margin for the closed loop's
tracking error, so the co-simulation (sim/spatial_cosim) may lose the part that the planners'
sampled check says is held. `carried_search` plays the plan k times slower (TimeScaled: positions,
hence every task pose, unchanged) and bisects k in [1, k_max] (timescale.search_scale, the co-simulation as its predicate) for the smallest k whose
co-simulation carries the part; `carried_plan` turns its answer into a SpatialPlan (re-checked at
the re-check rate, task poses checked again by Drake FK). Used by `qmt-drake plan SPATIAL --carried`
and by studies/spatial_benchmark.py (one implementation).
"""

from __future__ import annotations

import time

from qmt_drake.carried_cells import (
    REL_TOL,
    carried_at_every_cell,
    check_spatial_cells,
    resolve_cells,
    spatial_cell_runner,
    spatial_default_cell,
)
from qmt_drake.errors import QmtInputError
from qmt_drake.margin_runs import spatial_half_step
from qmt_drake.planners.spatial_plan_io import SpatialPlan, make_spatial_plan
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.timescale import search_scale


def carried_search(sc, plan: SpatialPlan, *, k_max: float = 2.5, iterations: int = 7, try_planned: bool = True,
                   progress=None, actuator: str = "ideal", feedforward: str = "full", half_step: bool = True,
                   cells=None, cells_rel_tol: float = REL_TOL) -> dict:
    """Bisection on the time scale k (module docstring). Returns {'chosen': smallest carried k found
    (None if not carried even at k_max), 'lost_below': the largest k tried that was lost (None if the
    plan is carried as planned), 'cosim': the chosen k's co-simulation result, 'points': every k tried
    with its outcome, 'k_max', 'iterations', 'wall_s'}. try_planned: co-simulate k = 1 first (the plan as planned).
    actuator, feedforward: the co-simulation's ('ideal', or 'dc_motor' with feedforward none / back-emf /
    full: sim/spatial_cosim.simulate_spatial; `qmt-drake plan --carried --carried-feedforward F`).
    half_step: co-simulate the chosen scale once more at half the plant step and report it as
    'half_step' (margin_runs.spatial_half_step: verdict_at_half_step, slip_at_half_step,
    flips_at_half_step); a flip is reported, the choice is not changed.
    cells: None (the default: the one cell above), 'all' or (time_step_s, approximation) pairs: the chosen
    scale is then run at every cell and, if a cell loses it, raised to the smallest scale carried at every
    cell that runs, to cells_rel_tol (carried_cells.carried_at_every_cell); 'chosen' is that scale,
    'every_cell' the per-cell tables, every_cell['chosen_at_default_cell'] the default cell's choice."""
    say = progress or (lambda _m: None)
    todo = None
    if cells is not None:  # checked before any run
        default = spatial_default_cell(sc)
        todo = resolve_cells(cells, default[0])
        check_spatial_cells(todo)
    points, results, t0 = [], {}, time.perf_counter()

    def carried(k: float) -> bool:
        r = simulate_spatial(sc, TimeScaled(plan.trajectory, k) if k != 1.0 else plan.trajectory, actuator=actuator,
                             feedforward=feedforward)
        results[k] = r
        points.append({"time_scale": k, "duration_s": plan.duration_s * k, "outcome": r["outcome"],
                       "max_grip_ratio_while_held": r["max_grip_ratio_while_held"]})
        say(f"{sc.name} {plan.method} x{k:.4f}: T = {plan.duration_s * k:.4f} s, {r['outcome']}")
        return r["held"]

    def done(chosen, lost_below, every=None):
        if every is not None and every["raised"]:
            chosen, lost_below = every["time_scale"], every["lost_below"]
            if chosen is not None and chosen not in results:
                carried(chosen)  # the raised scale at the default cell: the result's 'cosim'
        check = None
        if half_step and chosen is not None:
            check = spatial_half_step(sc, TimeScaled(plan.trajectory, chosen) if chosen != 1.0 else plan.trajectory,
                                      actuator=actuator, feedforward=feedforward)
            say(f"{sc.name} {plan.method} x{chosen:.4f} at half the step ({check['half_step_s'] * 1e3:g} ms): "
                f"{check['verdict_at_half_step']}" + (" (the verdict FLIPS)" if check["flips_at_half_step"] else ""))
        return {"chosen": chosen, "half_step": check, "lost_below": lost_below, "cosim": results.get(chosen if chosen else lost_below),
                "k_max": float(k_max), "iterations": int(iterations), "points": points, "actuator": actuator,
                **({"feedforward": feedforward} if actuator != "ideal" else {}),  # ideal: always full
                **({} if every is None else {"every_cell": every}), "wall_s": time.perf_counter() - t0}

    found = carried_bisection(carried, float(k_max), iterations, try_planned)
    lost = {"end": None, "no_hold": found.hi}.get(found.status, found.lo)  # the largest k tried that was lost
    every = None
    if todo is not None and found.holding is not None:
        say(f"{sc.name} {plan.method} x{found.holding:.4f} at {len(todo)} cells")
        every = carried_at_every_cell(spatial_cell_runner(sc, plan.trajectory, actuator=actuator, feedforward=feedforward),
                                      found.holding, todo, k_max=float(k_max), rel_tol=cells_rel_tol,
                                      default_cell=default, progress=say)
    return done(found.holding, lost, every)


def carried_bisection(carried, k_max: float, iterations: int, try_planned: bool):
    """The spatial variant of the one search (timescale.search_scale) with the co-simulation as predicate:
    k = 1 first (if try_planned), then k_max, then `iterations` arithmetic bisection steps."""
    return search_scale(carried, 1.0, k_max, steps=iterations, ends=("lo", "hi") if try_planned else ("hi",))


def carried_plan(sc, plan: SpatialPlan, search: dict) -> SpatialPlan:
    """`plan` played search['chosen'] times slower as a SpatialPlan named '<method>-carried', re-checked
    (gravity does not slow down, so a slower plan is not assumed to hold: it is measured); the search
    goes to info['carried_search']. QmtInputError (one line) when the search found no carried scale."""
    k = search["chosen"]
    if k is None:
        where = " at some plant step / contact approximation" if search.get("every_cell") else ""
        raise QmtInputError(f"--carried: the {plan.method} plan is lost in the co-simulation{where} even "
                            f"{search['k_max']:g}x slower; raise --carried-max-scale")
    traj = TimeScaled(plan.trajectory, k) if k != 1.0 else plan.trajectory
    times = plan.pose_times_s * k
    lost = search["lost_below"]
    info = dict(plan.info, carried_search=dict(search, margin=None if lost is None else k / lost - 1.0))
    return make_spatial_plan(sc, f"{plan.method}-carried", traj, times, planning_s=plan.planning_s + search["wall_s"],
                             raw_duration_s=plan.raw_duration_s, hold_scale=plan.hold_scale * k, info=info)
