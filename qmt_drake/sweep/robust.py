"""Plans for what is carried, not only for what is planned (issue 13 item 3).

`robust_time_scale`: the fastest time scaling s of a plan whose success probability under a stated
uncertainty reaches a target, by bisection over sweeps. Every step is an ordinary sweep (runner.py)
of the same Monte Carlo draws (common random numbers) with `time_scale` fixed to s, stored under
its own name, so a rerun of the search reuses every finished case. The criterion is either the
estimate k/n >= target or the Wilson lower bound >= target (stricter: with n = 200 and no failure
the 95% lower bound is 0.981, so 99% cannot be certified by 200 cases).

`plan_fastest_carried`: the fastest plan carried in the NOMINAL co-simulation. For Ruckig's
jerk-limited Cartesian line the jerk limit J is chosen by bisection (in log J) between a carried
and a lost value: a larger J makes the motion shorter and the reversal of the load harsher (the
README's ch.2 finding: a near-limit load that swaps edges of the contact ring within ~20 ms tips
the bolt). For any other method the time scale of its plan is bisected (s >= 1 keeps every planned
limit). The controller's feedforward (`feedforward`, default "full": back EMF plus Drake inverse
dynamics) is part of the result: the plan is carried with that controller.

Both assume carried-ness is monotone in the searched variable; each evaluated point is kept in
the result's history so a non-monotone case shows.
"""

from __future__ import annotations

import time
from contextlib import nullcontext

import numpy as np

from qmt_drake.errors import QmtInputError, QmtSimulationError
from qmt_drake.hands import hand_plugin
from qmt_drake.plan import make_plan
from qmt_drake.planners import plan_with
from qmt_drake.sim import FEEDFORWARD_OPTIONS
from qmt_drake.spatial_task import SpatialScenario
from qmt_drake.sweep.cases import check_hand_can_vary
from qmt_drake.sweep.parameters import check_success_drive
from qmt_drake.sweep.runner import dask_client, run_sweep
from qmt_drake.sweep.spatial_cases import check_spatial_spec, spatial_time_scaled_plan
from qmt_drake.sweep.spec import SweepSpec, load_spec
from qmt_drake.sweep.stats import wilson_interval
from qmt_drake.timescale import search_scale
from qmt_drake.trajectory import TimeScaledTrajectory


# ------------------------------------------------------------------ robust time scale (sweeps)
def robust_time_scale(spec: SweepSpec | dict | str, out_dir="out", *, target: float = 0.99,
                      criterion: str = "estimate", s_min: float = 1.0, s_max: float = 1.5,
                      rel_tol: float = 0.005, confidence: float = 0.95, client=None, workers=None,
                      scheduler=None, progress=None, figures: bool = False, **run_kw) -> dict:
    """Smallest time scale s in [s_min, s_max] (to rel_tol) at which the spec's single plan is
    carried with probability >= target under the spec's distributions.

    Returns {time_scale, motion_time_s, p, ci_low, ci_high, n, history: [...], found}; found=False
    when even s_max misses the target (time_scale is then None). run_kw go to run_sweep (tests
    pass case_fn / plan_fn)."""
    if not isinstance(spec, SweepSpec):
        spec = load_spec(spec)
    if len(spec.plans) != 1 or spec.grid:
        raise QmtInputError(f"robust time scale: spec '{spec.name}' needs exactly one plan and no grid "
                            f"parameter (it has {len(spec.plans)} plans, grid {list(spec.grid)})")
    if "time_scale" in spec.distributions:
        raise QmtInputError("robust time scale: time_scale is what is searched; drop it from the spec")
    if not 0 < target < 1:
        raise QmtInputError(f"target success probability must lie in (0, 1), got {target}")
    if criterion not in ("estimate", "lower_bound"):
        raise QmtInputError(f"criterion must be 'estimate' or 'lower_bound', got {criterion!r}")
    if not 0 < s_min < s_max:
        raise QmtInputError(f"need 0 < s_min < s_max, got {s_min}, {s_max}")
    say = progress or (lambda _m: None)
    history = []

    def evaluate(s: float, cl) -> dict:
        raw = dict(spec.raw)
        params = dict(raw.get("parameters") or {})
        params["time_scale"] = float(s)
        raw["parameters"] = params
        sub = load_spec(raw, name=f"{spec.name}-ts{s:.5f}")
        # each step's sweep shows its own count (minutes per step on the tray) when progress is asked for
        out = run_sweep(sub, out_dir, client=cl, progress=progress is not None, figures=figures, **run_kw)
        n = sum(r["n"] for r in out["rows"])
        k = sum(r["carried"] for r in out["rows"])
        lo, hi = wilson_interval(k, n, confidence)
        ok = (k / n if n else 0.0) >= target if criterion == "estimate" else lo >= target
        point = dict(time_scale=float(s), n=n, carried=k, p=k / n if n else float("nan"), ci_low=lo,
                     ci_high=hi, meets_target=bool(ok), failed_cases=out["failed"],
                     motion_time_s=_motion_time(out, s))
        history.append(point)
        say(f"robust {spec.name}: s = {s:.5f}: {k}/{n} carried, p = {point['p']:.3f} "
            f"[{lo:.3f}, {hi:.3f}] -> {'meets' if ok else 'misses'} {target}")
        return point

    ctx = nullcontext(client) if client is not None else dask_client(scheduler, workers)
    t0 = time.perf_counter()
    with ctx as cl:
        points = {}

        def meets(s: float) -> bool:
            points[s] = evaluate(s, cl)
            return points[s]["meets_target"]

        found = robust_bisection(meets, s_min, s_max, rel_tol)
        if found.holding is None:
            return dict(found=False, time_scale=None, target=target, criterion=criterion, history=history,
                        wall_s=time.perf_counter() - t0)
        best = points[found.holding]
    return dict(found=True, target=target, criterion=criterion, confidence=confidence,
                time_scale=best["time_scale"], motion_time_s=best["motion_time_s"], p=best["p"],
                ci_low=best["ci_low"], ci_high=best["ci_high"], n=best["n"],
                history=sorted(history, key=lambda h: h["time_scale"]), wall_s=time.perf_counter() - t0)


def robust_bisection(meets, s_min: float, s_max: float, rel_tol: float):
    """The sweeps' variant of the one search (timescale.search_scale): s_max first (is the target reachable?),
    then s_min, then geometric bisection to rel_tol; meets(s): the sweep at s meets the target."""
    return search_scale(meets, s_min, s_max, midpoint="geometric", rel_tol=rel_tol, ends=("hi", "lo"))


def _motion_time(out: dict, s: float):
    """The sweep's common motion time [s], or (cases with a drawn time_scale_jitter differ) the plan's
    motion time x s."""
    row = out["rows"][0] if out["rows"] else {}
    t = (out["results"] or [{}])[0].get("plan_motion_time_s")
    return row.get("motion_time_s") if row.get("motion_time_s") is not None or t is None else float(t) * s


def time_scaled_plan(plan, time_scale: float, method: str, extra: dict | None = None):
    """`plan` played time_scale times slower, as a re-checked Plan (every inertial ratio / s^2)."""
    traj = plan.trajectory if time_scale == 1.0 else TimeScaledTrajectory(plan.trajectory, time_scale)
    return make_plan(plan.scenario, method, traj, genes=plan.genes,
                     extra={"base_plan_extra": plan.extra, "time_scale": float(time_scale), **(extra or {})})


def plan_robust(plan, spec: SweepSpec | dict | str, out_dir="out", **kw):
    """The planner option of item 3: `plan` slowed to the robust time scale of `spec` (whose single
    plan must be this plan, e.g. {file: PLAN.json}); returns (Plan, robust_time_scale result).
    Raises QmtInputError when the target is not reached within s_max."""
    r = robust_time_scale(spec, out_dir, **kw)
    if not r["found"]:
        raise QmtInputError(f"no time scale up to {kw.get('s_max', 1.5)} reaches success probability "
                            f"{r['target']}; raise s_max")
    return time_scaled_plan(plan, r["time_scale"], f"{plan.method}-robust",
                            {"robust": {k: v for k, v in r.items() if k != "history"}}), r


# ------------------------------------------------------------ fastest carried (nominal co-sim)
def carried_in_cosim(scenario, plan, *, time_scale: float = 1.0, feedforward: str = "full",
                     time_step_s: float | None = None) -> dict:
    """One nominal co-simulation through the hand's plug-in (hands.HandPlugin.carried_check): {'held',
    'outcome', 'max_slip_m', 'detached_at_s', 'max_tilt_rad', 'sim_wall_s'} (a failed simulation counts
    as not carried). A tray scenario runs through its servos (the DC-motor feedforward does not
    apply there)."""
    try:
        return hand_plugin(scenario).carried_check(scenario, plan, time_scale=time_scale, feedforward=feedforward,
                                                   time_step_s=time_step_s)
    except QmtSimulationError as exc:
        return {"held": False, "outcome": "failed", "max_slip_m": None, "detached_at_s": None, "error": str(exc)}


def plan_fastest_carried(scenario, method: str = "ruckig", *, feedforward: str = "full",
                         jerk_range_m_s3: tuple[float, float] = (0.3, 300.0), s_max: float = 2.0,
                         rel_tol: float = 0.002, time_step_s: float | None = None, seed: int = 0,
                         progress=None, base_plan=None, **planner_options):
    """The fastest plan of `method` carried in the nominal co-simulation with `feedforward`.

    method "ruckig": bisection on log J over jerk_range_m_s3 (Cartesian line unless a `mode`
    option says otherwise); the lower end must be carried. Any other method: plan once, then
    bisect its time scale s in [1, s_max] and return the plan played s times slower
    (TimeScaledTrajectory, re-checked); base_plan: time-scale this plan instead of planning one
    (method is then only its name). rel_tol: relative width of the final bracket in motion time.
    Returns a Plan whose extra['carried_search'] holds every co-simulated point."""
    if feedforward not in FEEDFORWARD_OPTIONS:
        raise QmtInputError(f"feedforward must be one of {sorted(FEEDFORWARD_OPTIONS)}, got {feedforward!r}")
    say = progress or (lambda _m: None)
    t_start = time.perf_counter()
    history = []

    def record(var, value, plan, s=1.0):
        out = carried_in_cosim(scenario, plan, time_scale=s, feedforward=feedforward, time_step_s=time_step_s)
        history.append({var: float(value), "motion_time_s": float(plan.motion_time_s) * s,
                        "plan_feasible": bool(plan.feasible), **out})
        say(f"{scenario.name} {method} {var}={value:.6g}: T = {plan.motion_time_s * s:.4f} s, "
            f"{out.get('outcome', 'carried' if out['held'] else 'lost')}")
        return out["held"] and plan.feasible

    if method == "ruckig" and base_plan is None:
        lo, hi = (float(x) for x in jerk_range_m_s3)
        if not 0 < lo < hi:
            raise QmtInputError(f"jerk_range_m_s3 must be two increasing positive numbers, got {jerk_range_m_s3}")
        plans = {}

        def carried_at(J: float) -> bool:
            plans[J] = plan_with("ruckig", scenario, jerk_limit=J, **planner_options)
            return record("jerk_limit_m_s3", J, plans[J])

        found = jerk_bisection(carried_at, lambda J: plans[J].motion_time_s, lo, hi, rel_tol)
        if found.holding is None:
            raise QmtInputError(f"{scenario.name}: even the ruckig plan at the lowest jerk limit {lo:g} m/s^3 is "
                                "lost in the co-simulation; lower jerk_range_m_s3[0]")
        best_J, hi = found.holding, found.hi
        search = {"variable": "jerk_limit_m_s3", "chosen": best_J, "lost_above": hi if best_J < hi else None}
        plan = plans[best_J]
    else:
        base = base_plan if base_plan is not None else plan_with(method, scenario, seed=seed, **planner_options)
        if not base.feasible:
            raise QmtInputError(f"{scenario.name}: the {method} plan breaks a limit; nothing to time-scale")
        found = scale_bisection(lambda s: record("time_scale", s, base, s), float(s_max), rel_tol)
        if found.holding is None:
            raise QmtInputError(f"{scenario.name}: the {method} plan is lost even {found.hi:g}x slower; raise s_max")
        best_s, lo = found.holding, found.lo
        search = {"variable": "time_scale", "chosen": best_s, "lost_below": lo if best_s > lo else None}
        plan = time_scaled_plan(base, best_s, f"{method}-carried")
    plan.method = f"{method}-carried"
    plan.planner_wall_s = time.perf_counter() - t_start
    plan.extra = dict(plan.extra or {})
    plan.extra.update({"carried_search": dict(search, feedforward=feedforward,
                                               time_step_s=time_step_s, points=history),
                       "note_carried": f"carried in the nominal co-simulation with feedforward '{feedforward}'; "
                                       "execute it with that controller"})
    return plan


def jerk_bisection(carried_at, motion_time_s, J_lo: float, J_hi: float, rel_tol: float):
    """The jerk-limit variant of the one search (timescale.search_scale; a small J is carried): J_lo (must be
    carried), then J_hi, then geometric bisection until the carried and the lost plan differ by rel_tol in
    motion time (J itself matters only through it) or J by 1e-4."""
    def done(lo: float, hi: float) -> bool:
        return not (motion_time_s(lo) / motion_time_s(hi) - 1 > rel_tol and hi / lo > 1.0001)

    return search_scale(carried_at, J_lo, J_hi, safe="below", midpoint="geometric", done=done, ends=("lo", "hi"))


def scale_bisection(carried, s_max: float, rel_tol: float):
    """The time-scale variant (timescale.search_scale): s = 1 (the plan as planned) first, then s_max, then
    geometric bisection to rel_tol; carried(s): the plan s times slower is carried."""
    return search_scale(carried, 1.0, s_max, midpoint="geometric", rel_tol=rel_tol, ends=("lo", "hi"))


def plan_fastest_carried_converged(scenario, method: str = "ruckig", *,
                                   steps_s=(2e-3, 1e-3, 0.5e-3), feedforward: str = "full",
                                   progress=None, **kw):
    """`plan_fastest_carried` at the coarsest plant step whose verdict is converged in the step.

    At a step h the search ends with a bracket: the chosen (carried) plan and its lost neighbour
    (rel_tol faster). Both are co-simulated again at h/2; if both verdicts stay the same, h's
    verdict is converged at this bracket and the plan is returned. Otherwise the search is repeated
    at the next (finer) step of steps_s. Why: near the limit a verdict can change with the step
    (ch.2's jerk-limited line is lost at 2 ms and carried at 0.5 ms; session 5, with the part
    floating in the world frame, also saw a step drift of held parts, since removed:
    systems/payload.py); the 1 mm 'held' line itself is not changed. The result's extra['carried_search']['convergence'] lists every step tried with the
    re-simulated verdicts ('converged' False on the last step means no step in steps_s converged).
    A finer search starts from the coarser bracket's lost neighbour when that is carried at the
    finer step (as the lowest jerk limit / the largest time scale), not from the whole range."""
    kw = dict(kw)
    say = progress or (lambda _m: None)
    t0 = time.perf_counter()
    tried = []
    plan = None
    for h in steps_s:
        plan = plan_fastest_carried(scenario, method, feedforward=feedforward, time_step_s=h,
                                    progress=progress, **kw)
        s = plan.extra["carried_search"]
        h2 = h / 2
        chosen_fine = carried_in_cosim(scenario, plan, feedforward=feedforward, time_step_s=h2)
        row = {"time_step_s": h, "check_step_s": h2, "motion_time_s": float(plan.motion_time_s),
               "chosen": s["chosen"], "chosen_at_check_step": chosen_fine}
        ok = chosen_fine["held"]
        nb = _neighbour(scenario, plan, method, kw)
        if nb is not None:
            lost_fine = carried_in_cosim(scenario, nb, feedforward=feedforward, time_step_s=h2)
            row.update(lost_neighbour_motion_time_s=float(nb.motion_time_s), lost_neighbour_at_check_step=lost_fine)
            ok = ok and not lost_fine["held"]
        row["converged"] = bool(ok)
        tried.append(row)
        if nb is not None and lost_fine["held"]:
            # Warm start of the finer search (carried-ness is assumed monotone, as in the search):
            # the lost neighbour is carried at the finer step, so the bracket starts there.
            if s["variable"] == "jerk_limit_m_s3":
                kw["jerk_range_m_s3"] = (s["lost_above"], kw.get("jerk_range_m_s3", (0.3, 300.0))[1])
            else:
                kw["s_max"] = s["lost_below"]
        say(f"{scenario.name} {method}: step {h * 1e3:g} ms -> {plan.motion_time_s:.4f} s; verdicts at "
            f"{h2 * 1e3:g} ms {'agree' if ok else 'differ'}")
        if ok:
            break
    plan.extra["carried_search"]["convergence"] = tried
    plan.extra["carried_search"]["converged"] = tried[-1]["converged"]
    plan.planner_wall_s = time.perf_counter() - t0
    return plan


def _neighbour(scenario, plan, method, kw):
    """The lost end of the final bracket of a plan_fastest_carried result (None if none was lost)."""
    s = plan.extra["carried_search"]
    if s["variable"] == "jerk_limit_m_s3":
        if s.get("lost_above") is None:
            return None
        opts = {k: v for k, v in kw.items() if k not in _SEARCH_KW}
        return plan_with("ruckig", scenario, jerk_limit=s["lost_above"], **opts)
    if s.get("lost_below") is None:
        return None
    # the chosen plan is base x chosen; base x lost_below is chosen x (lost_below / chosen)
    return time_scaled_plan(plan, s["lost_below"] / s["chosen"], plan.method)


_SEARCH_KW = ("jerk_range_m_s3", "s_max", "rel_tol", "seed", "base_plan")


def bracket_check(scenario, plan, *, feedforward: str = "full", steps_s=(1e-3, 0.5e-3)) -> list[dict]:
    """The same plan co-simulated at finer plant steps: is 'carried' a property of the plan or of
    the 2 ms step?"""
    rows = []
    for h in steps_s:
        rows.append({"time_step_s": h, **carried_in_cosim(scenario, plan, feedforward=feedforward, time_step_s=h)})
    return rows


def relative_excess(t: float, bound: float) -> float:
    return float(t / bound - 1.0) if bound and np.isfinite(t) else float("nan")


# ------------------------------------------------------- plan --success P (scenario's uncertainty)
def success_spec(scenario, plan_file=None, *, cases: int | None = None, seed: int | None = None,
                 name: str = "success", sim: dict | None = None) -> SweepSpec:
    """The sweep spec of `plan_file` (a written plan of `scenario`; None: its optimum, to check the
    section before planning) under the scenario's
    `uncertainty` section: its parameters, its monte_carlo cases / seed unless given, and (spatial) the drive
    the cells run through: the section's `sim` {actuator, feedforward}, updated by `sim` (default: the
    scenario's real drive, full feedforward). One-line QmtInputError when the scenario has none, it is not a
    valid sweep parameter block, or a drive is asked of a planar scenario (its drive is its YAML's)."""
    u = getattr(scenario, "uncertainty", None) or {}
    if not u:
        mu = getattr(getattr(scenario, "grip", None), "friction", None)  # a spatial suction cup's own friction
        example = ("mass_scale: {dist: normal, mean: 1.0, std: 0.05}" if mu is None else
                   f"friction: {{dist: normal, mean: {mu:g}, std: {0.1 * mu:.2g}}}")
        raise QmtInputError(f"--success: scenario {scenario.name} has no uncertainty section; add one, e.g. "
                            f"uncertainty: {{parameters: {{{example}}}, monte_carlo: {{cases: 40, seed: 1}}}} "
                            "(models/scenarios/*.yaml show every parameter)")
    mc = dict(u.get("monte_carlo") or {})
    if cases is not None:
        mc["cases"] = int(cases)
    if seed is not None:
        mc["seed"] = int(seed)
    mc.setdefault("cases", 100)
    mc.setdefault("seed", 1)
    spatial = isinstance(scenario, SpatialScenario)
    if sim and not spatial:
        raise QmtInputError(f"--success drive {sim}: scenario {scenario.name} is planar; its drive is its YAML's "
                            "actuator section (a drive choice is for spatial scenarios)")
    drive = {**check_success_drive(u.get("sim"), "uncertainty.sim"), **check_success_drive(sim, "--success drive")}
    plan_ref = ({"method": "toppra" if spatial else "optimum"} if plan_file is None else {"file": str(plan_file)})
    path = scenario.path if spatial else scenario.source_path
    try:
        spec = load_spec({"name": name, "scenario": str(path), "plans": [plan_ref], "monte_carlo": mc,
                          "parameters": dict(u["parameters"]), **({"sim": drive} if drive else {})}, name=name)
    except QmtInputError as exc:  # the user wrote the scenario's uncertainty section, not a sweep spec: name it
        if cases is not None or seed is not None:  # (a caller's own count or seed: the caller names its option)
            raise
        raise QmtInputError(str(exc).replace(f"sweep spec '{name}'", f"scenario {scenario.name}: uncertainty",
                                             1)) from None
    if spatial:  # its real drive (sweep/spatial_cases.default_actuator)
        check_spatial_spec(spec, scenario)
    else:
        check_hand_can_vary(spec, scenario)
    return spec


def plan_for_success(plan, plan_file, out_dir, *, target: float, check_cases: int = 200, s_max: float = 2.0,
                     progress=None, scenario=None, rel_tol: float = 0.005, sim: dict | None = None, **run_kw):
    """The fastest time scale of `plan` whose success probability under its scenario's uncertainty has
    its lower 95 % Wilson bound >= target (robust_time_scale on the sweep store under out_dir, so a
    rerun resumes), then a FRESH sweep of check_cases cases with another seed at that time scale,
    which the search did not see. Returns (the time-scaled Plan, {search, fresh_check}). scenario: the
    plan's scenario (default plan.scenario; a SpatialPlan's is given: a SpatialScenario), rel_tol: the
    search's final bracket (relative), sim: the drive (success_spec; spatial only)."""
    sc = plan.scenario if scenario is None else scenario
    spec = success_spec(sc, plan_file, sim=sim)
    found = robust_time_scale(spec, out_dir, target=target, criterion="lower_bound", s_max=s_max,
                              rel_tol=rel_tol, progress=progress, **run_kw)
    if not found["found"]:
        raise QmtInputError(f"--success {target}: not reached even {s_max:g}x slower ({found['history'][-1]['carried']}"
                            f"/{found['history'][-1]['n']} carried there); raise --success-max-scale or lower the target")
    s = found["time_scale"]
    seed = int((sc.uncertainty.get("monte_carlo") or {}).get("seed", 1)) + 1000003
    fresh = success_spec(sc, plan_file, cases=check_cases, seed=seed, name=f"success-check-ts{s:.5f}", sim=sim)
    raw = dict(fresh.raw)
    raw["parameters"] = {**raw["parameters"], "time_scale": float(s)}
    out = run_sweep(load_spec(raw, name=fresh.name), out_dir, progress=False, figures=False, **run_kw)
    n = sum(r["n"] for r in out["rows"])
    k = sum(r["carried"] for r in out["rows"])
    lo, hi = wilson_interval(k, n)
    check = {"cases": n, "carried": k, "p": k / n if n else None, "ci_low": lo, "ci_high": hi, "seed": seed,
             "meets_target": bool(lo >= target)}
    if progress:
        progress(f"fresh check at x{s:.4f}: {k}/{n} carried, 95 % interval [{lo:.3f}, {hi:.3f}]")
    summary = {"search": {k2: v for k2, v in found.items() if k2 != "history"}, "fresh_check": check,
               "tries": found["history"]}
    if isinstance(sc, SpatialScenario):
        return spatial_time_scaled_plan(sc, plan, s, f"{plan.method}-success", {"success": summary}), summary
    return time_scaled_plan(plan, s, f"{plan.method}-success", {"success": summary}), summary
