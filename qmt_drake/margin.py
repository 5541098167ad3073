"""How far a co-simulation's verdict is from the other verdict (issue 29, item 4).

The cheap part, in every `simulate` result as its "margin" entry (`verdict_margin`): each quantity
that decides the outcome next to the threshold at which it changes it, with the ratio value /
threshold. The run is carried iff every ratio is below 1 (a ratio of exactly 1 is lost for the slip
limits, which are "at least", and still carried for the arrival tolerance, "at most"); the
"deciding" criterion is the one the outcome came from when lost, and the one nearest its threshold
when carried. The builders pass their own thresholds (sim/runner.py, tray/execute.py,
margin_runs.spatial_margin), so each lives once, where the verdict is decided:

    magnet (planar)   max_slip_m vs 1 mm (slipped); max_gap_m vs 2 mm and max_slip_m vs 5 mm
                      (detached: the monitor's rules); final_goal_error_rad vs 1e-3 rad (unfinished)
    tray (CRANE-X7)   max_slip_m (slid faster than 3 mm/s) vs 1 mm (slipped); max_tilt_rad vs the
                      tipping angle atan(r_c / h_G) (tipped); the base's largest offset over the
                      tray's half size per axis (slid_off); final_goal_error_rad vs 0.1 rad
    spatial, cup / magnet   max_grip_ratio_while_held vs 1 (detached: the weld breaks the first step
                      the hand's limit term exceeds 1); final_goal_error_rad vs 1e-3 rad
    spatial, tray     final_slide_m vs 5 mm (slipped), max_tilt_rad vs atan(r / h_G) (tipped),
                      max_slide_m vs the nearer tray edge (slid_off: an upper bound of the per-axis
                      ratio, which the summary does not carry), final_goal_error_rad vs 1e-3 rad
    energy-time       final_error_rad vs 1e-3 rad (reached_goal): no payload, nothing to lose

The expensive part, on request (`simulate(..., margin=True)`, `qmt-drake simulate ... --margin`):
`flip_time_scale`, the time scale at which the verdict flips (geometric steps outward from the run's
own scale, then bisection to a stated relative tolerance, at most max_runs runs, one progress line
per run), and `half_step_verdict`, the verdict at half the plant step. Both take `run(time_scale,
time_step_s) -> summary`, so they serve every kind through its own simulate entry point; the
energy-time run has only the cheap part (ENERGY_NO_FLIP says why: ideal unlimited torques under an
exact-model inverse-dynamics controller follow any time scale, and a continuous plant has no step).

qmt_drake/margin_runs.py (apart: it imports the spatial co-simulation, which sim/runner.py, importing
this module, must not reach): `spatial_margin`, and `spatial_plant_options`, the run options (time_step_s,
contact_approximation) that run the spatial co-simulation (sim/spatial_cosim.py: 1 ms SAP by default) at another
step or discrete contact approximation over the scenario's simulation section: the verdict study
(studies/verdict_margins.py) uses them; the margin's half step passes its step to spatial_run the same way.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from qmt_drake.config.simulation import APPROXIMATIONS  # noqa: F401 (re-exported: the one list of Drake's names)
from qmt_drake.errors import QmtInputError, QmtSimulationError
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD
from qmt_drake.timescale import Grow, search_scale

FLIP_TOLERANCE = 0.005  # relative width of the final bracket of the flip scale (0.5 %)
FLIP_MAX_RUNS = 12
OUTWARD_FACTORS = (1.02, 1.1, 1.5, 2.5)  # geometric steps out from the run's own scale until it flips


def criterion(quantity: str, value: float | None, threshold: float, outcome_over: str) -> dict:
    """One deciding quantity: its value, the threshold at which it makes outcome_over, value / threshold."""
    v = None if value is None or not math.isfinite(float(value)) or not math.isfinite(threshold) else float(value)
    return {"quantity": quantity, "value": v, "threshold": float(threshold), "outcome_over": outcome_over,
            "ratio": None if v is None else v / float(threshold)}


def verdict_margin(outcome: str, criteria: list[dict], note: str | None = None) -> dict:
    """The margin entry of a summary: the deciding criterion's fields at the top, every criterion under
    'criteria' (module docstring). A criterion without a value (not measured) is listed, never deciding."""
    measured = [c for c in criteria if c["ratio"] is not None]
    if outcome == "carried":
        pool = measured
    else:
        pool = [c for c in measured if c["outcome_over"] == outcome] or measured
    deciding = max(pool, key=lambda c: c["ratio"]) if pool else criterion("none", None, 1.0, outcome)
    out = {k: deciding[k] for k in ("quantity", "value", "threshold", "ratio", "outcome_over")}
    out["criteria"] = criteria
    if note:
        out["note"] = note
    return out


def energy_margin(summary: dict) -> dict:
    """The energy-time run's margin: its final error against the arrival tolerance (no payload)."""
    return verdict_margin("carried" if summary.get("reached_goal") else "unfinished",
                          [criterion("final_error_rad", summary.get("final_error_rad"),
                                     ARRIVAL_TOLERANCE_DC_MOTOR_RAD, "unfinished")],
                          note="energy-time: no payload, the verdict is reached_goal; no time scale or step to vary")


# why the energy-time run has no flip scale and no half-step verdict (physics, not a missing feature)
ENERGY_NO_FLIP = ("not available: seed 001's arm is driven by ideal, unlimited torque sources under an "
                  "inverse-dynamics controller holding the plant's own model, so it follows the plan at any time "
                  "scale (the verdict cannot flip with it); its plant is continuous by default (an error-controlled "
                  "integrator, accuracy 1e-6: no step to halve), and a discrete run (--time-step-ms) converges to "
                  "that one as its step shrinks")


# ------------------------------------------------------------------------------- the expensive part
def _try(run, time_scale: float, time_step_s: float | None) -> dict:
    """run(...) as a summary; a run the co-simulation cannot finish (the arm leaves its reference, the
    solver fails) is a lost one, with its one-line reason."""
    try:
        return run(time_scale, time_step_s)
    except QmtSimulationError as exc:
        return {"outcome": "failed", "held": False, "error": str(exc)}


def _point(time_scale: float, r: dict) -> dict:
    m = r.get("margin") or {}
    return {"time_scale": float(time_scale), "outcome": r["outcome"], "held": bool(r["held"]),
            "quantity": m.get("quantity"), "value": m.get("value"), "ratio": m.get("ratio"),
            **({"error": r["error"]} if "error" in r else {})}


def flip_time_scale(run: Callable[[float, float | None], dict], summary: dict, *, time_scale: float = 1.0,
                    tolerance: float = FLIP_TOLERANCE, max_runs: int = FLIP_MAX_RUNS,
                    progress: Callable[[str], None] | None = None) -> dict:
    """The time scale at which the verdict of `summary` (the run at `time_scale`) flips: scales
    time_scale * f for f in OUTWARD_FACTORS (slower when lost, 1/f faster when carried) until the
    verdict differs, then geometric bisection until the bracket's relative width is <= tolerance or
    max_runs runs are spent. Returns {'flip_time_scale' (the bracket's geometric mean, None when no
    flip was found), 'carried_at' / 'lost_at' (the bracket's ends), 'relative_to_run' (flip /
    time_scale - 1: how much faster (< 0) or slower the plan can be played before the verdict
    changes), 'bracket_relative_width', 'converged', 'runs', 'points'}."""
    if not (tolerance > 0 and max_runs >= 1):
        raise QmtInputError(f"margin tolerance {tolerance} must be > 0 and max_runs {max_runs} >= 1")
    say = progress or (lambda _m: None)
    held0 = bool(summary["held"])
    points: list[dict] = []

    def probe(s: float) -> bool:
        r = _try(run, s, None)
        points.append(_point(s, r))
        say(f"margin: run {len(points)} of at most {max_runs}: time scale {s:.5g}: {r['outcome']}")
        return bool(r["held"])

    found = flip_search(probe, time_scale, held0, tolerance, max_runs)
    same, other = (found.hi, found.lo) if held0 else (found.lo, found.hi)  # same: the run's verdict
    if found.status == "exhausted":
        other = None
    if other is None:
        return {"flip_time_scale": None, "carried_at": same if held0 else None, "lost_at": None if held0 else same,
                "relative_to_run": None, "bracket_relative_width": None, "converged": False, "tolerance": tolerance,
                "runs": len(points), "max_runs": max_runs, "points": points,
                "note": f"no flip within x{OUTWARD_FACTORS[-1]:g} of the run's scale"}
    flip = math.sqrt(same * other)
    width = max(same, other) / min(same, other) - 1
    return {"flip_time_scale": flip, "carried_at": same if held0 else other, "lost_at": other if held0 else same,
            "relative_to_run": flip / time_scale - 1.0, "bracket_relative_width": width,
            "converged": width <= tolerance, "tolerance": tolerance, "runs": len(points), "max_runs": max_runs,
            "points": points}


def flip_search(held, time_scale: float, held0: bool, tolerance: float, max_runs: int):
    """The margin's variant of the one search (timescale.search_scale, carried above, lost below): from the
    run's scale outward by OUTWARD_FACTORS (faster when carried, slower when lost) until the verdict flips,
    then geometric bisection to `tolerance`; max_runs runs in all."""
    return search_scale(held, midpoint="geometric", rel_tol=tolerance, max_probes=max_runs,
                        grow=Grow(start=time_scale, start_holds=held0, table=OUTWARD_FACTORS))


def half_step_verdict(run: Callable[[float, float | None], dict], summary: dict, time_step_s: float, *,
                      time_scale: float = 1.0, progress: Callable[[str], None] | None = None) -> dict:
    """The run again at half the plant step: {'time_step_s', 'half_step_s', 'outcome_at_half_step',
    'verdict_at_half_step' (carried or lost), 'slip_at_half_step' (the deciding quantity's value),
    'changes_verdict'}."""
    h2 = 0.5 * float(time_step_s)
    r = _try(run, time_scale, h2)
    m = r.get("margin") or {}
    out = {"time_step_s": float(time_step_s), "half_step_s": h2, "outcome_at_half_step": r["outcome"],
           "verdict_at_half_step": "carried" if r["held"] else "lost",
           "slip_at_half_step": r.get("max_slip_m", r.get("final_slide_m")),
           "deciding_at_half_step": {k: m.get(k) for k in ("quantity", "value", "threshold", "ratio")},
           "changes_verdict": bool(r["held"]) != bool(summary["held"])}
    if "error" in r:
        out["error"] = r["error"]
    if progress:
        progress(f"margin: half step {h2 * 1e3:g} ms: {r['outcome']}"
                 + (" (the verdict changes)" if out["changes_verdict"] else " (same verdict)"))
    return out


def expensive_margin(run: Callable[[float, float | None], dict], summary: dict, time_step_s: float, *,
                     time_scale: float = 1.0, tolerance: float = FLIP_TOLERANCE, max_runs: int = FLIP_MAX_RUNS,
                     progress: Callable[[str], None] | None = None) -> dict:
    """{'flip': flip_time_scale(...), 'half_step': half_step_verdict(...)}: at most max_runs + 1 runs."""
    return {"flip": flip_time_scale(run, summary, time_scale=time_scale, tolerance=tolerance, max_runs=max_runs,
                                    progress=progress),
            "half_step": half_step_verdict(run, summary, time_step_s, time_scale=time_scale, progress=progress)}


def apart(value: float, threshold: float, style: str = "f", digits: int = 4) -> str:
    """`value` with `digits` digits (style 'f' or 'g'), more when it would print as `threshold` without being
    it: a verdict's deciding number never reads as its threshold."""
    d = digits
    while d < 12 and value != threshold and f"{value:.{d}{style}}" == f"{threshold:.{d}{style}}":
        d += 1
    return f"{value:.{d}{style}}"


def margin_text(m: dict) -> str:
    """The CLI's margin line: the deciding quantity against its threshold, then the expensive part if run."""
    if m.get("ratio") is None:
        return "margin: nothing measured"
    # (0.99996 against 1 printed "1 vs 1 (detached at or above)" beside a carried verdict)
    line = (f"margin: {m['quantity']} {apart(m['value'], m['threshold'], 'g')} vs {m['threshold']:.4g} "
            f"({m['outcome_over']} at or above), ratio {apart(m['ratio'], 1.0)}")
    f, h = m.get("flip"), m.get("half_step")
    if isinstance(f, dict):
        line += ("; no flip found within the tried scales" if f["flip_time_scale"] is None else
                 f"; verdict flips at time scale {f['flip_time_scale']:.5g} ({f['relative_to_run']:+.2%} of the run's, "
                 f"bracket {f['bracket_relative_width']:.2%}, {f['runs']} runs)")
    if isinstance(h, dict):
        line += (f"; at half the step ({h['half_step_s'] * 1e3:g} ms): {h['outcome_at_half_step']}"
                 + (" (the verdict CHANGES)" if h["changes_verdict"] else ""))
    return line
