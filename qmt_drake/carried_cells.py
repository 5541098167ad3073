"""A fastest-carried answer carried at every plant step and contact approximation (issue 29, item 4).

A fastest-carried search (planners/spatial_carried.carried_search; sweep/robust.plan_fastest_carried for
the planar and tray scenarios) bisects the time scale at ONE cell: the plant step and Drake discrete
contact approximation its co-simulation uses by default. Its answer sits on the verdict's threshold, so
at another cell it may flip (docs/margins.md: crane-tray TOPP-RA x1.02388 slips at 'similar' 1, 0.5 and
0.25 ms and at 'lagged' 0.25 ms). `carried_at_every_cell` takes the chosen scale k0 and the cells:

- a list of (time_step_s [s], approximation) pairs, or "all": the steps h, h/2, h/4 (h: the search's own
  step) x each of Drake's approximations (tamsi, sap, similar, lagged). A cell whose plant Drake refuses
  to build (TAMSI has no weld constraint: the spatial weld hands) is 'n/a' with Drake's reason and does
  not count; a co-simulation that fails (QmtSimulationError) counts as lost ('failed').
- k0 is run at every cell. If every cell that runs carries the part, k0 stands. Otherwise the scale is
  raised: from k0 by x`RAISE_FACTOR` steps until the lost cells carry it (at most k_max), then geometric
  bisection until hi / lo - 1 <= rel_tol (default `REL_TOL`, 0.2 %); each try runs the cells lost so far,
  the latest loss first, and stops at the first loss. The answer is then run at every cell: a cell lost
  only there (the verdict need not be monotone in the scale at every cell) joins the lost ones and the
  raise goes on from that answer. Every run is memoised by (scale, step, approximation).

The result carries the per-cell tables at k0 and at the answer: outcome, the deciding quantity of the
verdict's margin (qmt_drake/margin.py), its threshold and ratio, and the slip. Cost: one co-simulation
per cell at k0 (12 for "all", runs at h/4 about 4x those at h), and when raised about 4-8 tries of the
lost cells plus the answer's full table.

`spatial_cell_runner` and `transfer_cell_runner` are the runs (time_scale, time_step_s, approximation)
-> cell; `carried_transfer_plan_every_cell` applies the search to a planar / tray fastest-carried Plan.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable

from qmt_drake.errors import QmtInputError, QmtSimulationError
from qmt_drake.hands import hand_plugin
from qmt_drake.margin_runs import spatial_margin, spatial_plant_options
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.cosim_run import run as run_cosim
from qmt_drake.sim.plant import transfer_plant_config
from qmt_drake.sim.sim_settings import APPROXIMATION_ENUMS, simulation_of, time_step_of
from qmt_drake.sim.spatial_contact_hand import ContactHand
from qmt_drake.sim.spatial_cosim import WeldHand, build_spatial_cosim, spatial_time_step
from qmt_drake.sim.spatial_tray_hand import TrayCupHand
from qmt_drake.sweep.robust import time_scaled_plan
from qmt_drake.timescale import Grow, search_scale

APPROXIMATIONS = tuple(APPROXIMATION_ENUMS)  # tamsi, sap, similar, lagged (Drake's names)
STEP_FACTORS = (1.0, 0.5, 0.25)  # "all": the search's step h, h/2, h/4
RAISE_FACTOR = 1.02  # the raise's growth step from the chosen scale
REL_TOL = 0.002  # the raise's final bracket, relative


def cell_key(time_step_s: float, approximation: str) -> str:
    return f"{time_step_s * 1e3:g} ms {approximation}"


def parse_cells(text: str, flag: str = "--carried-cells") -> str | list[tuple[float, str]]:
    """The CLI's cells: 'all', or MS:APPROXIMATION[,MS:APPROXIMATION...] (the plant step in ms), e.g.
    '0.5:sap,0.25:lagged'. One-line QmtInputError otherwise."""
    text = str(text).strip()
    if text == "all":
        return "all"
    cells = []
    for item in text.split(","):
        ms, sep, approx = item.strip().partition(":")
        try:
            step = float(ms) * 1e-3
        except ValueError:
            step = math.nan
        if not sep or not math.isfinite(step) or step <= 0 or approx not in APPROXIMATIONS:
            raise QmtInputError(f"{flag} {text!r}: give 'all' or MS:APPROXIMATION pairs separated by commas (a "
                                f"positive step in ms, the approximation one of {', '.join(APPROXIMATIONS)}), "
                                "e.g. 1:sap,0.5:lagged")
        cells.append((step, approx))
    return check_cells(cells, flag)


def check_cells(cells, where: str = "cells") -> str | list[tuple[float, str]]:
    """`cells` as given to a search: 'all' or a non-empty list of (time_step_s > 0, approximation) pairs,
    duplicates dropped; one-line QmtInputError otherwise."""
    if isinstance(cells, str) and cells == "all":
        return "all"
    bad = QmtInputError(f"{where} {cells!r}: give 'all' or a list of (time_step_s, approximation) pairs, the "
                        f"step a positive number of seconds, the approximation one of {', '.join(APPROXIMATIONS)}")
    if isinstance(cells, str) or not hasattr(cells, "__iter__"):
        raise bad
    out: list[tuple[float, str]] = []
    for c in cells:
        if not (isinstance(c, (tuple, list)) and len(c) == 2 and isinstance(c[0], (int, float))
                and not isinstance(c[0], bool) and math.isfinite(c[0]) and c[0] > 0 and c[1] in APPROXIMATIONS):
            raise bad
        if (float(c[0]), c[1]) not in out:
            out.append((float(c[0]), c[1]))
    if not out:
        raise bad
    return out


def resolve_cells(cells, time_step_s: float) -> list[tuple[float, str]]:
    """The cells to run: 'all' expanded at the search's step time_step_s [s] (module docstring)."""
    cells = check_cells(cells)
    if cells == "all":
        return [(time_step_s * f, a) for f in STEP_FACTORS for a in APPROXIMATIONS]
    return list(cells)


def _name(approximation) -> str:
    """Drake's name of an approximation given as a name or as its enum."""
    return next((k for k, v in APPROXIMATION_ENUMS.items() if approximation in (k, v)), str(approximation))


def spatial_default_cell(sc) -> tuple[float, str]:
    """(step [s], approximation) of the spatial co-simulation's defaults: the scenario's simulation.plant,
    else the hand's own (sim/spatial_cosim.assemble: the hand's, then the section's)."""
    hand = TrayCupHand if sc.hand_kind == "tray" else ContactHand if sc.hand_physics == "contact" else WeldHand
    given = simulation_of(sc).plant.discrete_contact_approximation
    return spatial_time_step(sc, None), _name(given or hand.approximation)


def transfer_default_cell(sc) -> tuple[float, str]:
    """(step [s], approximation) a transfer (planar magnet or tray) carried search runs at: the hand's default
    step (margin_runs.search_half_step's) and the transfer plant's approximation (sim/plant; the tray's
    plant starts from the same lagged and takes the scenario's section alike)."""
    h = float(time_step_of(None, sc, hand_plugin(sc).replay_cost.default_step_s))
    return h, str(transfer_plant_config(h, simulation_of(sc).plant).discrete_contact_approximation)


def _cell(summary: dict, margin: dict, slip_m) -> dict:
    return {"outcome": summary["outcome"], "held": bool(summary["held"]), "quantity": margin.get("quantity"),
            "value": margin.get("value"), "threshold": margin.get("threshold"), "ratio": margin.get("ratio"),
            "slip_m": None if slip_m is None else float(slip_m), "max_tilt_rad": summary.get("max_tilt_rad"),
            "sim_wall_s": summary.get("sim_wall_s")}


def _guarded(build, summarize) -> dict:
    """Build (Drake's refusal: 'n/a' with its reason), run (a QmtSimulationError: 'failed', lost), summarise."""
    try:
        cosim = build()
    except QmtSimulationError as exc:
        return {"outcome": "failed", "held": False, "error": str(exc).strip().splitlines()[0][:300]}
    except RuntimeError as exc:  # e.g. TAMSI and a weld constraint: this plant cannot be built
        return {"outcome": "n/a", "held": None, "error": str(exc).strip().splitlines()[0][:300]}
    try:
        return summarize(run_cosim(cosim))
    except QmtSimulationError as exc:
        return {"outcome": "failed", "held": False, "error": str(exc).strip().splitlines()[0][:300]}


def spatial_cell_runner(sc, trajectory, *, actuator: str = "ideal", feedforward: str = "full"):
    """run(time_scale, time_step_s, approximation) -> a cell of `trajectory` played time_scale times slower
    in the spatial co-simulation (simulate_spatial's run, its step and approximation as run options)."""
    def run(k: float, h: float, a: str) -> dict:
        traj = trajectory if k == 1.0 else TimeScaled(trajectory, k)
        opts = spatial_plant_options(h, a)
        return _guarded(lambda: build_spatial_cosim(sc, traj, actuator=actuator, feedforward=feedforward, **opts),
                        lambda r: _cell(r, spatial_margin(sc, r), r.get("final_slide_m")))
    return run


def _checked(check, cells, where: str) -> None:
    """check(h, a) for each cell; its one-line refusal named by `where` and the cell (a run option's
    own flag name, e.g. --time-step-ms, dropped: the cell is the input here)."""
    for h, a in cells:
        try:
            check(h, a)
        except QmtInputError as exc:
            reason = str(exc)
            if reason.startswith("--"):
                reason = reason.partition(": ")[2] or reason
            raise QmtInputError(f"{where}: the cell {cell_key(h, a)}: {reason}") from None


def check_spatial_cells(cells, where: str = "cells") -> None:
    """Each cell's step and approximation checked before any run (margin_runs.spatial_plant_options: one line)."""
    _checked(spatial_plant_options, cells, where)


def transfer_cell_runner(sc, plan, *, feedforward: str = "full"):
    """run(time_scale, time_step_s, approximation) -> a cell of `plan` on a transfer scenario (the hand's
    co-simulation, its build_cosim, as the carried search's predicate runs it; the tray's servos take no
    DC-motor feedforward). The approximation goes in as the scenario's simulation.plant field (a copy of
    the scenario per approximation; the step is the run's option)."""
    hand = hand_plugin(sc)
    ff = "none" if hand.kind == "tray" else feedforward
    scenarios: dict[str, object] = {}

    def run(k: float, h: float, a: str) -> dict:
        if a not in scenarios:
            scenarios[a] = scenario_at(sc, a)
        return _guarded(lambda: hand.build_cosim(scenarios[a], plan, time_scale=k, time_step_s=h, feedforward=ff),
                        lambda r: _cell(r, r.get("margin") or {}, r.get("max_slip_m")))
    return run


def scenario_at(sc, approximation: str):
    """A copy of transfer scenario sc whose simulation.plant names the discrete contact approximation (the
    planar and tray plants take the section's fields over their own: sim/sim_settings.plant_config)."""
    sim = simulation_of(sc)
    plant = dataclasses.replace(sim.plant, discrete_contact_approximation=approximation)
    return dataclasses.replace(sc, simulation=dataclasses.replace(sim, plant=plant))


def check_transfer_cells(sc, cells, where: str = "cells") -> None:
    """Each cell's step checked by the hand before any run (one line: e.g. the tray's servo period)."""
    check = hand_plugin(sc).check_simulation
    _checked(lambda h, _a: check(sc, time_step_s=h), cells, where)


def carried_at_every_cell(run: Callable[[float, float, str], dict], chosen: float, cells, *, k_max: float,
                          rel_tol: float = REL_TOL, default_cell: tuple[float, str] | None = None,
                          progress: Callable[[str], None] | None = None) -> dict:
    """The smallest time scale >= chosen carried at every cell that runs (module docstring). run(k, h, a):
    a cell dict with 'outcome' and 'held' (None: the cell cannot run). Returns {'time_scale' (None: not
    carried everywhere up to k_max), 'chosen_at_default_cell', 'raised', 'relative_to_chosen',
    'lost_below' (the largest scale tried that a cell lost, None if not raised; k_max when not carried), 'cells' (the keys),
    'default_cell', 'table_at_chosen', 'table' (at the answer; {} if none), 'tries', 'runs', 'rel_tol',
    'raise_factor', 'k_max', 'status', 'wall_s'}."""
    if not (rel_tol > 0 and math.isfinite(rel_tol)):
        raise QmtInputError(f"rel_tol {rel_tol!r}: the raise's relative bracket must be a positive number, e.g. 0.002")
    say = progress or (lambda _m: None)
    t0 = time.perf_counter()
    memo: dict[tuple[float, float, str], dict] = {}
    tries: list[dict] = []

    def cell(k: float, h: float, a: str) -> dict:
        if (k, h, a) not in memo:
            c = memo[(k, h, a)] = dict(run(k, h, a), time_step_s=h, approximation=a)
            detail = (f", {c['quantity']} {c['value']:.4g} ({c['ratio']:.4f} of its threshold)"
                      if c.get("ratio") is not None else f" ({c['error']})" if c.get("error") else "")
            say(f"  x{k:.5f} {cell_key(h, a)}: {c['outcome']}{detail}")
        return memo[(k, h, a)]

    def table(k: float) -> dict:
        return {cell_key(h, a): cell(k, h, a) for h, a in cells}

    lost: list[tuple[float, str]] = []  # cells lost at some scale, the latest loss first

    def carried_where_lost(k: float) -> bool:
        outcomes = {}
        for h, a in list(lost):
            c = cell(k, h, a)
            outcomes[cell_key(h, a)] = c["outcome"]
            if c["held"] is False:
                lost.remove((h, a))
                lost.insert(0, (h, a))
                tries.append({"time_scale": k, "outcomes": outcomes, "carried": False})
                return False
        tries.append({"time_scale": k, "outcomes": outcomes, "carried": True})
        return True

    first = table(chosen)
    k, answer, lost_below, status = chosen, first, None, "carried"
    while True:
        # (the cells in `lost` carry the answer: its search's last holding try ran them)
        new = [(h, a) for h, a in cells if answer[cell_key(h, a)]["held"] is False]
        if not new:
            break
        lost[:0] = new
        say(f"  x{k:.5f} is lost at {', '.join(cell_key(*c) for c in new)}: raising the time scale")
        found = search_scale(carried_where_lost, midpoint="geometric", rel_tol=rel_tol,
                             grow=Grow(start=k, start_holds=False, factor=RAISE_FACTOR, limit=float(k_max)))
        if found.holding is None:  # lost at some cell even at k_max (found.hi)
            k, answer, lost_below, status = None, {}, found.hi, "not_carried"
            break
        k, lost_below, status = found.holding, found.lo, "raised"
        answer = table(k)
    return {"time_scale": k, "chosen_at_default_cell": chosen, "raised": k != chosen,
            "relative_to_chosen": None if k is None else k / chosen - 1.0, "lost_below": lost_below,
            "cells": [cell_key(h, a) for h, a in cells],
            "default_cell": None if default_cell is None else cell_key(*default_cell),
            "table_at_chosen": first, "table": answer, "tries": tries, "runs": len(memo), "rel_tol": rel_tol,
            "raise_factor": RAISE_FACTOR, "k_max": float(k_max), "status": status,
            "wall_s": time.perf_counter() - t0}


def carried_transfer_plan_every_cell(sc, base_plan, carried, cells, *, feedforward: str = "full",
                                     s_max: float = 2.0, rel_tol: float = REL_TOL, time_step_s: float | None = None,
                                     progress=None):
    """`carried` (sweep/robust.plan_fastest_carried's Plan) raised until it is carried at every cell
    (carried_at_every_cell; time_step_s: the search's step, None the hand's default). A time-scale search
    (base_plan: the plan it scaled) is raised on base_plan's scale from its choice, 'chosen' / 'lost_below'
    then become the raised scale and its bracket ('chosen_at_default_cell' keeps the search's); a jerk-limit
    search (base_plan None) plays `carried` slower from x1, its 'chosen' jerk limit kept. Returns `carried`
    itself if no cell is lost, else the slower Plan; extra['carried_search']['every_cell'] is the result.
    QmtInputError (one line) when not carried at every cell even s_max slower."""
    search = carried.extra["carried_search"]
    on_scale = search.get("variable") == "time_scale"
    if on_scale and base_plan is None:
        raise QmtInputError("cells: a time-scale search's every-cell raise needs the plan it scaled (base_plan)")
    base, k0 = (base_plan, float(search["chosen"])) if on_scale else (carried, 1.0)
    h0, a0 = transfer_default_cell(sc)
    h = h0 if time_step_s is None else float(time_step_s)
    todo = resolve_cells(cells, h)
    check_transfer_cells(sc, todo)
    every = carried_at_every_cell(transfer_cell_runner(sc, base, feedforward=feedforward), k0, todo,
                                  k_max=s_max, rel_tol=rel_tol, default_cell=(h, a0),
                                  progress=progress)
    k = every["time_scale"]
    if k is None:
        raise QmtInputError(f"cells: the {carried.method} plan is lost at some cell even {s_max:g}x slower; raise "
                            "--carried-max-scale")
    plan = carried
    if every["raised"]:
        plan = time_scaled_plan(base, k, carried.method, extra={
            k_: v for k_, v in carried.extra.items() if k_ not in ("base_plan_extra", "time_scale")})
        plan.planner_wall_s = carried.planner_wall_s
    update = ({"chosen": k, "chosen_at_default_cell": k0,
               "lost_below": every["lost_below"] if every["raised"] else search.get("lost_below")} if on_scale else {})
    plan.extra["carried_search"] = dict(search, **update, every_cell=every)
    return plan


def every_cell_text(every: dict) -> str:
    """One clause for a summary line: where the answer is carried, and from which scale it was raised."""
    table = every["table"]
    runs = [c for c in table.values() if c["held"] is not None]
    na = len(every["cells"]) - len(runs) if table else 0
    if every["time_scale"] is None:
        return f"; lost at some cell even x{every['k_max']:g}"
    where = f"carried at all {len(runs)} cells that run" if len(runs) != 1 else "carried at the 1 cell that runs"
    where += f" ({na} n/a)" if na else ""
    if not every["raised"]:
        return f"; {where}"
    lost = [k for k, c in every["table_at_chosen"].items() if c["held"] is False]
    return (f"; raised from x{every['chosen_at_default_cell']:.5f} (lost at {', '.join(lost)}) to "
            f"x{every['time_scale']:.5f}, {where}")


def every_cell_lines(every: dict) -> list[str]:
    """The answer's per-cell table as lines: outcome, deciding quantity, its ratio to the threshold."""
    out = []
    for key, c in every["table"].items():
        if c.get("ratio") is not None:
            out.append(f"  {key}: {c['outcome']}, {c['quantity']} {c['value']:.4g} ({c['ratio']:.4f} of "
                       f"{c['threshold']:.4g})")
        else:
            out.append(f"  {key}: {c['outcome']}" + (f" ({c['error']})" if c.get("error") else ""))
    return out
