"""The margin's runs for every scenario kind (qmt_drake/margin.py documents the margin): `with_margin`,
what `simulate` calls on every result (the cheap part; the expensive one on request), the
run(time_scale, time_step_s) closures of the transfer (`transfer_run`, through hands.run_simulate)
and spatial (`spatial_run`) co-simulations, the spatial summary's cheap margin (`spatial_margin`),
and `spatial_plant_options`, the run options of the spatial co-simulation at another plant step or
discrete contact approximation. Apart from margin.py because it imports the co-simulations, which import it."""

from __future__ import annotations

import math
from collections.abc import Callable

import qmt_drake.sim.spatial_contact_hand as contact_hand
import qmt_drake.sim.spatial_cosim as spatial_cosim
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import hand_plugin, run_simulate
from qmt_drake.margin import ENERGY_NO_FLIP, criterion, energy_margin, expensive_margin, verdict_margin
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD
from qmt_drake.plan import ENERGY_PLAN_KIND, SPATIAL_PLAN_KIND
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.sim_settings import APPROXIMATION_ENUMS, time_step_of

APPROXIMATIONS = APPROXIMATION_ENUMS  # Drake's names -> its enum (sim/sim_settings.py, the one map)


def spatial_margin(sc, summary: dict) -> dict:
    """The cheap margin of a spatial co-simulation's summary (sim/spatial_cosim.simulate_spatial). The weld
    hand: its limit ratio against 1; the contact hand (hand_physics contact): the part's largest gap from the
    face and slide along it (from the plan's start, the loss included) against the loss rule's 5 mm and
    10 mm, its final slide against the slip tolerance 5 mm; the tray: slide, tilt and edge."""
    tol = ARRIVAL_TOLERANCE_DC_MOTOR_RAD
    arrival = criterion("final_goal_error_rad", summary.get("final_goal_error_rad"), tol, "unfinished")
    if sc.hand_kind == "tray":
        cup = sc.cup
        tip = math.atan2(cup.radius_m, cup.h_G)
        edge = 0.5 * min(cup.tray_size_m[:2])
        crit = [criterion("final_slide_m", summary.get("final_slide_m"), spatial_cosim.SLIP_TOLERANCE_M, "slipped"),
                criterion("max_tilt_rad", summary.get("max_tilt_rad"), tip, "tipped"),
                criterion("max_slide_m", summary.get("max_slide_m"), edge, "slid_off"), arrival]
        return verdict_margin(summary["outcome"], crit, note="max_slide_m against the nearer tray edge: an upper "
                              "bound of the per-axis ratio that decides slid_off")
    if summary.get("hand_physics") == "contact":  # the contact hand's own rules (sim/spatial_contact_hand)
        crit = [criterion("max_gap_m", summary.get("max_gap_m"), contact_hand.LOST_GAP_M, "detached"),
                criterion("max_slide_m", summary.get("max_slide_m"), contact_hand.LOST_SLIDE_M, "detached"),
                criterion("final_slide_on_face_m", summary.get("final_slide_on_face_m"),
                          contact_hand.SLIP_TOLERANCE_M, "slipped"), arrival]
        return verdict_margin(summary["outcome"], crit, note="contact hand: the part's gap and slide on the hand's "
                              "face (the weld's threshold on this run's hand motion is max_grip_ratio_while_held, "
                              "a diagnostic)")
    crit = [criterion("max_grip_ratio_while_held", summary.get("max_grip_ratio_while_held"), 1.0, "detached"),
            arrival]
    return verdict_margin(summary["outcome"], crit)


def spatial_plant_options(time_step_s: float | None = None, approximation: str | None = None) -> dict:
    """simulate_spatial's run options (passed through spatial_run as well) for another plant step
    time_step_s [s] and discrete contact approximation `approximation` (APPROXIMATIONS key); None: not
    given (the scenario's simulation.plant, else 1 ms SAP). As run options they win over the scenario's
    section (sim/sim_settings: run option > section > kind default); checked here in one line each."""
    if approximation is not None and approximation not in APPROXIMATIONS:
        raise QmtInputError(f"contact approximation {approximation!r}: use one of {', '.join(APPROXIMATIONS)}")
    if time_step_s is not None and not (time_step_s > 0 and abs(1e-3 / time_step_s - round(1e-3 / time_step_s)) < 1e-9):
        raise QmtInputError(f"time step {time_step_s} s: the spatial co-simulation needs 1 ms divided by a whole "
                            "number (its hold check runs in 250 ms chunks of whole steps)")
    return {k: v for k, v in (("time_step_s", None if time_step_s is None else float(time_step_s)),
                              ("contact_approximation", approximation)) if v is not None}


def spatial_run(sc, trajectory, **simulate_kw):
    """run(time_scale, time_step_s) -> the spatial co-simulation's summary with its margin, for
    margin.expensive_margin (time_step_s None: the module's 1 ms)."""
    def run(time_scale: float, time_step_s: float | None) -> dict:
        traj = trajectory if time_scale == 1.0 else TimeScaled(trajectory, time_scale)
        kw = {**simulate_kw, "time_step_s": simulate_kw.get("time_step_s") if time_step_s is None else time_step_s}
        r = spatial_cosim.simulate_spatial(sc, traj, **kw)
        r["margin"] = spatial_margin(sc, r)
        return r
    return run


def transfer_run(scenario, plan, *, time_step_s: float | None = None, feedforward: str = "none"):
    """run(time_scale, time_step_s) -> hands.run_simulate's summary (time_step_s None: the given one)."""
    def run(time_scale: float, step_s: float | None) -> dict:
        return run_simulate(scenario, plan, time_scale=time_scale, time_step_s=step_s or time_step_s,
                            feedforward=feedforward)
    return run


def with_margin(scenario, plan, summary: dict, *, expensive: bool = False, time_scale: float = 1.0,
                time_step_s: float | None = None, feedforward: str = "none", spatial_kw: dict | None = None,
                progress: Callable[[str], None] | None = None) -> dict:
    """`summary` with its cheap margin (added here for the spatial and energy-time runs, whose
    co-simulations do not build one) and, if expensive, the flip time scale and the half-step verdict
    under summary['margin']['flip'] / ['half_step'] (energy-time: a note why not). spatial_kw: the
    spatial run's simulate_spatial keywords (actuator, feedforward) for the expensive part's reruns."""
    kind = getattr(plan, "scenario_kind", "transfer")  # a transfer Motion may be any object with sample()
    if kind == SPATIAL_PLAN_KIND:
        summary["margin"] = spatial_margin(scenario, summary)
    elif kind == ENERGY_PLAN_KIND:
        summary["margin"] = energy_margin(summary)
    if not expensive:
        return summary
    if kind == ENERGY_PLAN_KIND:
        summary["margin"]["flip"] = summary["margin"]["half_step"] = ENERGY_NO_FLIP
        return summary
    if kind == SPATIAL_PLAN_KIND:
        run = spatial_run(scenario, plan.trajectory, **(spatial_kw or {}))
        # the step the run used (the run's option, else the scenario's simulation section, else 1 ms)
        h = spatial_cosim.spatial_time_step(scenario, (spatial_kw or {}).get("time_step_s"))
    else:
        run, h = transfer_run(scenario, plan, time_step_s=time_step_s, feedforward=feedforward), summary["time_step_s"]
    summary["margin"].update(expensive_margin(run, summary, h, time_scale=time_scale, progress=progress))
    return summary


def search_half_step(sc, plan, *, feedforward: str = "full", time_step_s: float | None = None) -> dict:
    """The chosen plan of a fastest-carried search of a transfer scenario (`plan`: the search's
    time-scaled result) co-simulated again at half the search's plant step (time_step_s; None: the
    hand's default): {'time_step_s', 'half_step_s', 'verdict_at_half_step' (the outcome),
    'slip_at_half_step' [m], 'flips_at_half_step'}. One run; nothing is re-chosen."""
    hand = hand_plugin(sc)
    h = float(time_step_of(time_step_s, sc, hand.replay_cost.default_step_s))  # the search's own step
    r = hand.carried_check(sc, plan, feedforward=feedforward, time_step_s=0.5 * h)
    return {"time_step_s": h, "half_step_s": 0.5 * h, "verdict_at_half_step": r["outcome"],
            "slip_at_half_step": r["max_slip_m"], "flips_at_half_step": not r["held"]}


def spatial_half_step(sc, trajectory, *, actuator: str = "ideal", feedforward: str = "full") -> dict:
    """The spatial counterpart of `search_half_step` (planners/spatial_carried.carried_search): the
    trajectory at half the spatial co-simulation's step; 'slip_at_half_step' is the tray hand's final
    slide [m] (None for a cup or magnet, whose weld does not slide: 'deciding_at_half_step' then holds
    the hand ratio against 1)."""
    h = spatial_cosim.spatial_time_step(sc, None)  # the scenario's simulation section, else 1 ms
    r = spatial_run(sc, trajectory, actuator=actuator, feedforward=feedforward)(1.0, 0.5 * h)
    m = r["margin"]
    return {"time_step_s": h, "half_step_s": 0.5 * h, "verdict_at_half_step": r["outcome"],
            "slip_at_half_step": r.get("final_slide_m"),
            "deciding_at_half_step": {k: m[k] for k in ("quantity", "value", "threshold", "ratio")},
            "flips_at_half_step": not r["held"]}
