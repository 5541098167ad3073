"""The memory and time estimate of a sweep (budgets.py), made from the spec before anything runs.

Each case is one co-simulated replay: its cost grows with the motion time (bounded before planning
by the scenario's time genes), the largest time scale and the smallest plant step the spec can
draw; the plans run first (a GA plan costs its population x generations evaluations).
"""

from __future__ import annotations

import json
from pathlib import Path

from qmt_drake.budgets import (
    SPATIAL_REPLAY,
    Estimate,
    ga_estimate,
    motion_time_bound_s,
    replay_estimate,
    sweep_estimate,
)
from qmt_drake.config.registry import hand_entry
from qmt_drake.sweep.spec import SweepSpec

NORMAL_REACH_STD = 6.0  # a normal draw is bounded by mean + 6 std for the estimate
SPATIAL_MOTION_GUESS_S = 5.0  # a spatial plan to be planned (the shipped TOPP-RA plans: 1.6-3.3 s)


def _extreme(spec: SweepSpec, name: str, largest: bool):
    """The largest (or smallest) value parameter `name` can take in the spec (None: not varied)."""
    vals = []
    if name in spec.fixed:
        vals.append(spec.fixed[name])
    vals += list(spec.grid.get(name, []))
    d = spec.distributions.get(name)
    if d is not None:
        a = d.args
        if largest:
            vals.append(a.get("high", a.get("mean", 0.0) + NORMAL_REACH_STD * a.get("std", 0.0)))
        else:
            vals.append(a.get("low", max(a.get("mean", 0.0) - NORMAL_REACH_STD * a.get("std", 0.0), 1e-9)))
    if not vals:
        return None
    return max(vals) if largest else min(vals)


def estimate_sweep(spec: SweepSpec, scenario, workers: int) -> Estimate:
    """An upper bound of the sweep's memory and wall time on `workers` processes."""
    T = motion_time_bound_s(scenario)
    ts = _extreme(spec, "time_scale", True) or 1.0
    cost = hand_entry(scenario).replay_cost  # the hand's co-simulation (its default step when none is set)
    step = _extreme(spec, "time_step_s", False) or spec.sim.get("time_step_s") or cost.default_step_s
    per_case = replay_estimate(ts, T, step, cost=cost)
    plans = None
    n_dof = len(scenario.limits.motor_torque_limit_Nm)
    for p in spec.plans:
        if p.get("method") == "ga":
            o = p.get("options", {})
            seeds = len(spec.grid.get("seed", [0]))
            g = ga_estimate(scenario.ga.population, o.get("max_generations", scenario.ga.max_generations),
                            plan_rate_hz=scenario.sampling.plan_rate_hz, motion_time_s=T, n_dof=n_dof,
                            n_genes=len(scenario.family.gene_names), bits_per_gene=scenario.ga.bits_per_gene)
            g = Estimate(g.bytes, g.seconds * seeds, g.what, g.fix)
            plans = g if plans is None else Estimate(max(plans.bytes, g.bytes), plans.seconds + g.seconds,
                                                     plans.what, plans.fix)
    return sweep_estimate(spec.n_cases, per_case, workers=workers, plans=plans)


def estimate_spatial_sweep(spec: SweepSpec, workers: int) -> Estimate:
    """estimate_sweep for a spatial scenario: each case one spatial co-simulation (budgets.SPATIAL_REPLAY)
    of the longest plan file's duration (SPATIAL_MOTION_GUESS_S for a plan still to be planned),
    stretched by the largest time scale and jitter the spec can draw."""
    T = SPATIAL_MOTION_GUESS_S
    files = [p["file"] for p in spec.plans if "file" in p]
    if files and len(files) == len(spec.plans):
        T = max(float(json.loads(Path(f).read_text()).get("duration_s", SPATIAL_MOTION_GUESS_S)) for f in files)
    ts = (_extreme(spec, "time_scale", True) or 1.0) * (_extreme(spec, "time_scale_jitter", True) or 1.0)
    return sweep_estimate(spec.n_cases, replay_estimate(ts, T, cost=SPATIAL_REPLAY), workers=workers)
