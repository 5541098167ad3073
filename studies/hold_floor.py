"""Why P >= 0.9 within 1.10 of the bound is or is not reachable (issue 29, Must show): the hold's own floor.

A plan played k times slower asks the hand for w(k) = w_g + w_d / k^2: every term of the contact wrench
(limits/contact_wrench.contact_wrench) but gravity's is a joint acceleration or a product of two joint speeds
(the hand's a, alpha scale 1/k^2, its omega 1/k). Against a drawn hold (a weaker vacuum, a heavier part, a
lower friction) the smallest k that keeps the drawn hand's limit term at most 1 along the whole plan is
`smallest_hold_scale` (the hold term alone: a perfect drive, the plan's own motion); infinite when the drawn
part is lost standing still (w_g alone over the limit). Over many draws of the scenario's `uncertainty`
section, P(hold) at scale k = P(k_draw <= k): the 90 % quantile of k_draw is the physics floor of any
"P >= 0.9" time scale of that plan, whatever the drive; and `certification_scale` is the scale at which a
sequential Wilson test of N cases allowing f losses (sweep/certify) passes with probability 1/2.

Planar magnet rows (thesis ch.2-4): the hold is the quasi-static tau_hold = (F(I) - m g) min(rho, mu r_G)
(sim/magnet_hand.py) against the moment m r_G |a| of a horizontal arm; F ~ I^2 (systems/electromagnet.py),
the current the nominal part's calibrated one times coil_current_scale (sweep/cases.py). Relative to a plan
carried on its nominal limit: k_draw = sqrt((m' r_G' / m r_G) (F(I) - m g) / (F(I c) - m' g) lever / lever').
The CRANE-X7 tray moves along a level line (no vertical acceleration): the bottle slides at |a| = mu g and
tips at g r / h_G (both independent of the mass), so k_draw = sqrt(max(mu / mu', ...)) of the binding one.

Standing still (`at_rest_ratio`, `stand_still`): the drawn part's limit ratio at the plan's start at rest
(the limit check's static ratio), and the co-simulation of the drawn plant with the arm told to stay at the
plan's start for the plan's duration (the same drive, the same hold check), started in the drawn plant's
equilibrium (sim/spatial_start) or, to compare, at rest with the drive's zero state (`--stand-still N`).

    PYTHONPATH=. python -m studies.hold_floor [--draws 2000] [--out out/hold_floor.json]
    PYTHONPATH=. python -m studies.hold_floor --only ur5-suction-bins,ur5-magnet-part --stand-still 12
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np
from scipy.stats import binom

from qmt_drake.limits.suction import SuctionTerm, cached_grip
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.planners.spatial_plan_io import load_spatial_plan
from qmt_drake.sim.cosim_run import run
from qmt_drake.sim.magnet_hand import coil_current_for, hold_lever_m, magnet_params_for
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive
from qmt_drake.sim.spatial_cosim import FINE_GRIP, build_spatial_cosim
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.sweep.certify import failures_allowed
from qmt_drake.sweep.spatial_cases import EFFICIENCY_BLEND_RAD_S, drawn_drive, perturbed_scenario
from qmt_drake.sweep.spec import load_spec
from qmt_drake.sweep.stats import wilson_interval
from qmt_drake.systems.payload import PayloadSpec
from qmt_drake.trajectory import JointTrajectory
from qmt_drake.transfer_scenario import load_scenario
from studies.robust_table import spec_of

K_MAX = 10.0  # a draw needing more is reported as k_max (the hold's floor is then irrelevant anyway)
BISECT = 40


# ------------------------------------------------------------------------------ the hand's motion
def hand_motion(sc, traj, step_s: float = 1e-3) -> dict:
    """The hand's kinematics along traj at k = 1 (rotation, angular velocity and acceleration, linear
    acceleration of its origin; world), sampled every step_s [s] and at the end."""
    t = np.r_[np.arange(0.0, traj.duration_s, step_s), traj.duration_s]
    q, qd, qdd = traj.sample(t)
    h = sc.chain.evaluate(q, qd, qdd)
    return {"rotation": h.rotation, "angular_velocity_rad_s": h.angular_velocity_rad_s,
            "angular_acceleration_rad_s2": h.angular_acceleration_rad_s2,
            "linear_acceleration_m_s2": h.linear_acceleration_m_s2, "t_s": t}


def scaled(motion: dict, k: float) -> dict:
    """The hand's motion of the plan played k times slower (k = inf: at rest at every pose)."""
    s = 0.0 if math.isinf(k) else 1.0 / k
    return {"rotation": motion["rotation"], "angular_velocity_rad_s": motion["angular_velocity_rad_s"] * s,
            "angular_acceleration_rad_s2": motion["angular_acceleration_rad_s2"] * s * s,
            "linear_acceleration_m_s2": motion["linear_acceleration_m_s2"] * s * s}


def hold_ratio(term, motion: dict, k: float) -> float:
    """The largest ratio of the hand's limit term along the plan played k times slower."""
    return float(np.max(term.columns(scaled(motion, k))))


def smallest_hold_scale(term, motion: dict, k_max: float = K_MAX, rel_tol: float = 1e-6) -> float:
    """The smallest k with hold_ratio <= 1 (inf when lost at rest; k_max when it needs more). Each ratio
    column is linear (or a norm of an affine map, or linear-fractional) in s = 1/k^2, so the feasible s form
    an interval from 0: bisection in s; a suction grip's rows are linear in the wrench: in closed form."""
    if isinstance(term, SuctionTerm):
        k = suction_hold_scale(term, motion)
        return k if math.isinf(k) else min(k, k_max)
    if hold_ratio(term, motion, math.inf) > 1.0:
        return math.inf
    if hold_ratio(term, motion, 1.0 / np.sqrt(4.0)) <= 1.0:  # holds even twice as fast
        return 0.5
    if hold_ratio(term, motion, k_max) > 1.0:
        return k_max
    lo, hi = 1.0 / k_max**2, 4.0  # s feasible, s infeasible
    while hi - lo > rel_tol * lo:
        mid = 0.5 * (lo + hi)
        if hold_ratio(term, motion, 1.0 / np.sqrt(mid)) <= 1.0:
            lo = mid
        else:
            hi = mid
    return float(1.0 / np.sqrt(lo))


def suction_hold_scale(term, motion: dict) -> float:
    """smallest_hold_scale of a SuctionTerm in closed form: its rows F_k w / g_k <= 1 are linear in the wrench
    w = w_g + s w_d (s = 1/k^2), so s* = min over rows and samples with F_k w_d > 0 of (1 - F_k w_g / g_k) /
    (F_k w_d / g_k)."""
    rows = (term.grip.F / term.grip.g[:, None]).T
    w_g = term.wrench(scaled(motion, math.inf))
    a = w_g @ rows
    if np.max(a) > 1.0:
        return math.inf
    b = (term.wrench(motion) - w_g) @ rows
    pos = b > 0
    if not pos.any():
        return 0.0
    return float(1.0 / np.sqrt(np.min((1.0 - a[pos]) / b[pos])))


# --------------------------------------------------------------------------- statistics of k_draw
def p_hold(k_draws, k: float) -> float:
    return float(np.mean(np.asarray(k_draws) <= k))


def certification_pass_probability(p: float, n: int, target: float = 0.9) -> float:
    """Probability that N cases of a point with true success p lose at most f(N) (sweep/certify)."""
    return float(binom.cdf(failures_allowed(n, target), n, 1.0 - p))


def certification_scale(k_draws, n: int, target: float = 0.9, chance: float = 0.5) -> float:
    """The smallest scale among the draws' k at which the sequential test of n cases passes with at least
    `chance` (inf when no finite scale does: too many draws are lost at rest)."""
    ks = np.sort(np.asarray(k_draws, float))
    for k in ks[np.isfinite(ks)]:
        if certification_pass_probability(p_hold(ks, k), n, target) >= chance:
            return float(k)
    return math.inf


def quantile_scale(k_draws, p: float) -> float:
    """The smallest scale held by a fraction p of the draws (inf if more than 1 - p are lost at rest)."""
    ks = np.sort(np.asarray(k_draws, float))
    i = int(math.ceil(p * len(ks))) - 1
    return float(ks[max(i, 0)])


def summary(k_draws, n_cert: int) -> dict:
    ks = np.asarray(k_draws, float)
    return {"draws": int(len(ks)), "lost_at_rest": int(np.isinf(ks).sum()),
            "p_held_at_rest": float(np.mean(np.isfinite(ks))), "k_q50": quantile_scale(ks, 0.5),
            "k_q90": quantile_scale(ks, 0.9), "k_q95": quantile_scale(ks, 0.95), "k_q99": quantile_scale(ks, 0.99),
            "k_cert50": certification_scale(ks, n_cert), "n_cert": int(n_cert),
            "allowed": int(failures_allowed(n_cert))}


# ---------------------------------------------------------------------------------- planar rows
def magnet_scale_draws(sc, draws: list[dict]) -> np.ndarray:
    """Planar magnet (module docstring): k_draw of each draw (friction, coil_current_scale, mass_scale,
    com_offset_scale) relative to a plan carried on the nominal hold."""
    p0 = PayloadSpec.for_scenario(sc)
    g = sc.world.g_m_s2
    I0 = coil_current_for(sc, p0)
    mp = magnet_params_for(sc, p0)
    cap0 = (mp.force_N(I0) - p0.mass_kg * g) * hold_lever_m(p0)
    out = []
    for d in draws:
        m = p0.mass_kg * d.get("mass_scale", 1.0)
        rg = p0.com_offset_m * d.get("com_offset_scale", 1.0)
        p = dataclasses.replace(p0, mass_kg=m, com_offset_m=rg, friction=d.get("friction", p0.friction))
        cap = (mp.force_N(I0 * d.get("coil_current_scale", 1.0)) - m * g) * hold_lever_m(p)
        demand = (m * rg) / (p0.mass_kg * p0.com_offset_m)
        out.append(math.inf if cap <= 0 else math.sqrt(demand * cap0 / cap))
    return np.array(out)


def tray_scale_draws(sc, draws: list[dict]) -> np.ndarray:
    """CRANE-X7 tray on its level line (module docstring): k_draw relative to a plan carried on the nominal
    bottle's binding condition (slide: mu g, tip: g r / h_G)."""
    mu0, r = sc.hand.friction, sc.hand.contact_radius_m
    h0 = sc.payload.com_offset_m
    cap0 = min(mu0, r / h0)
    return np.array([math.sqrt(cap0 / min(d.get("friction", mu0), r / (h0 * d.get("com_offset_scale", 1.0))))
                     for d in draws])


# ------------------------------------------------------------------------------- standing still
class StandStill(JointTrajectory):
    """The arm told to stay at q0 [rad] for duration_s [s] (a spatial kind: holds its end value)."""

    holds_end_value = True

    def __init__(self, q0, duration_s: float) -> None:
        self.q0 = np.asarray(q0, float).reshape(-1)
        self.duration_s, self.n_dof = float(duration_s), len(self.q0)
        self.breakpoints_s = np.array([0.0, self.duration_s])

    def sample(self, t_s):
        n = len(np.atleast_1d(np.asarray(t_s, float)))
        return np.tile(self.q0, (n, 1)), np.zeros((n, self.n_dof)), np.zeros((n, self.n_dof))


def at_rest_ratio(sc_drawn, grip, q0) -> float:
    """The drawn part's limit ratio at rest at joint pose q0 (the co-simulation's hand term)."""
    h = sc_drawn.chain.evaluate(np.atleast_2d(q0), np.zeros((1, len(q0))), np.zeros((1, len(q0))))
    state = {"rotation": h.rotation, "angular_velocity_rad_s": np.zeros((1, 3)),
             "angular_acceleration_rad_s2": np.zeros((1, 3)), "linear_acceleration_m_s2": np.zeros((1, 3))}
    return float(np.max(sc_drawn.hand_term(grip).columns(state)))


# -------------------------------------------------------------------------------- spatial rows
def cosim_grip(sc):
    """The suction grip the co-simulation checks (sim/spatial_cosim.build_spatial_cosim: the FINE_GRIP
    polyhedron of the drawn cup); None for the other hands."""
    if sc.hand_kind != "suction":
        return None
    g = sc.grip
    return cached_grip(g.radius_m, g.pull_force_N, g.friction, face_normal=g.basis[2], rim_points=FINE_GRIP[0],
                       pyramid_edges=FINE_GRIP[1])


def spatial_draw(sc, motion: dict, draw: dict) -> dict:
    """One draw of a spatial scenario: its at-rest ratio at the plan's start, its ratio on the plan at x1,
    and its smallest hold scale."""
    ps = perturbed_scenario(sc, draw)
    term = ps.hand_term(cosim_grip(ps))
    start = {k: v[:1] for k, v in motion.items() if k != "t_s"}
    return {"at_rest_ratio": hold_ratio(term, start, math.inf), "ratio_x1": hold_ratio(term, motion, 1.0),
            "k": smallest_hold_scale(term, motion)}


def at_rest_ratios(sc, q0, draws: list[dict]) -> np.ndarray:
    """The drawn parts' limit ratios at rest at q0, many draws at once: at rest the cup carries no tangential
    force and no twist, so only the rim's normal forces act (the friction pyramid's edges cancel in pairs)
    and the ratio does not depend on the friction; the grip's rows scale with the pull (g = F w_pull), so
    one grip of the nominal cup serves every draw: ratio = (rows at the nominal pull) / vacuum_force_scale.
    A magnet: the face moment over the drawn limit."""
    motion = {k: v[:1] for k, v in hand_motion_at(sc, q0).items()}
    out = []
    for d in draws:
        ps = perturbed_scenario(sc, {k: v for k, v in d.items() if k not in ("friction", "vacuum_force_scale")
                                     and not (k == "time_scale_jitter")})
        r = hold_ratio(ps.hand_term(cosim_grip(sc)), motion, math.inf)  # the nominal cup (suction), else None
        out.append(r / d.get("vacuum_force_scale", 1.0))
    return np.array(out)


def hand_motion_at(sc, q0) -> dict:
    """hand_motion of the arm at rest at q0 (one sample)."""
    return hand_motion(sc, StandStill(q0, 0.0), step_s=1.0)


def stand_still(sc, draw: dict, q0, duration_s: float, integral_rate_per_s: float = 5.0,
                blend: bool = True, settled_start: bool = True) -> dict:
    """The drawn plant (perturbed_scenario) with the arm told to stay at q0 [rad] for duration_s [s]: the
    nominal controller (the shaped drive with the integral rate), the drawn motors and law (drawn_drive; with
    `blend` the regularised gear switch of a sweep case that draws the efficiency), the same hold check as
    every sweep case (sim/spatial_cosim.simulate_spatial), started in the drawn plant's equilibrium
    (settled_start False: at rest at q0 with the law's zero state, the start before sim/spatial_start)."""
    physical = perturbed_scenario(sc, draw)
    nominal = SpatialMotorDrive.for_scenario(sc, q0, "shaped", integral_rate_per_s=integral_rate_per_s)
    drive = drawn_drive(nominal, sc, physical, draw,
                        EFFICIENCY_BLEND_RAD_S if blend and "gear_efficiency" in draw else None)
    cosim = build_spatial_cosim(physical, StandStill(q0, duration_s), controller_sc=sc, drive=drive,
                                feedforward="shaped", settled_start=settled_start)
    r = run(cosim)
    t, ratio = cosim.monitor.ratios(cosim.simulator.get_context(), 1)  # the hold check's samples (spatial_hold)
    j = int(np.argmax(ratio))
    return {"outcome": r["outcome"], "lost_at_s": r["lost_at_s"], "max_ratio": float(ratio[j]),
            "max_ratio_at_s": float(t[j]), "final_ratio": float(ratio[-1]),
            "late_mean_ratio": float(ratio[len(ratio) // 2:].mean()),  # the second half: settled, or chattering
            "max_tracking_error_rad": r["max_tracking_error_rad"]}


def stand_still_rows(name: str, plan_file: str, draws_n: int, duration_s: float | None = None) -> list[dict]:
    """stand_still of the first draws_n draws of the row (the search's), started in equilibrium and at rest
    (the old start), beside each draw's static ratio at the plan's start (at_rest_ratio)."""
    sc = load_spatial_scenario(name)
    plan = load_spatial_plan(plan_file, sc)
    q0 = plan.trajectory.sample([0.0])[0][0]
    rows = []
    for i, d in enumerate(draws_of(name, plan_file, draws_n)):
        ps = perturbed_scenario(sc, d)
        row = {"draw": i, "static_ratio": at_rest_ratio(ps, cosim_grip(ps), q0)}
        for settled in (True, False):
            r = stand_still(sc, d, q0, plan.duration_s if duration_s is None else duration_s, settled_start=settled)
            row["settled" if settled else "at_rest"] = r
        rows.append(row)
    return rows


# ----------------------------------------------------------------------------------------- rows
PLANAR = {"thesis-ch2": "magnet", "thesis-ch3": "magnet", "thesis-ch4": "magnet", "crane-tray": "tray"}
SPATIAL = ("ur5-suction-bins", "ur5-magnet-part", "panda-tray-cup")
N_CERT = {"planar": 100, "spatial": 60}  # the robust table's cases per point (studies/robust_table.CASES)


def draws_of(name: str, plan_file: str | None, cases: int, seed: int | None = None) -> list[dict]:
    """The first `cases` draws of the robust table's spec of the row (the search's draws, seed unless given)."""
    spec = spec_of(name, plan_file, "scale", {})
    raw = dict(spec.raw, monte_carlo={"cases": int(cases), "seed": int(spec.mc_seed if seed is None else seed)})
    return load_spec(raw, name=spec.name).samples()


def planar_row(name: str, draws_n: int) -> dict:
    sc = load_scenario(name)
    draws = draws_of(name, None, draws_n)
    k = magnet_scale_draws(sc, draws) if PLANAR[name] == "magnet" else tray_scale_draws(sc, draws)
    return {"scenario": name, "model": PLANAR[name], **summary(k, N_CERT["planar"])}


def spatial_row(name: str, plan_file: str, draws_n: int, rest_n: int, only: list[str] | None = None,
                step_s: float = 1e-3) -> dict:
    """A spatial row: the hold scale of draws_n draws, P(held at rest) of rest_n; `only`: draw just these
    parameters (the others nominal); step_s [s]: the plan's hand motion sampled at this step."""
    sc = load_spatial_scenario(name)
    plan = load_spatial_plan(plan_file, sc)
    q0 = plan.trajectory.sample([0.0])[0][0]
    motion = hand_motion(sc, plan.trajectory, step_s)
    draws = draws_of(name, plan_file, max(draws_n, rest_n))
    if only is not None:
        draws = [{k: v for k, v in d.items() if k in only} for d in draws]
    per = [spatial_draw(sc, motion, d) for d in draws[:draws_n]]
    rest = at_rest_ratios(sc, q0, draws[:rest_n]) if sc.hand_kind != "tray" else np.array([r["at_rest_ratio"]
                                                                                           for r in per])
    held = int(np.sum(rest <= 1.0))
    lo, hi = wilson_interval(held, len(rest))
    nominal = spatial_draw(sc, motion, {})
    return {"scenario": name, "model": sc.hand_kind, "plan_T_s": float(plan.duration_s),
            "bound_s": float(plan.raw_duration_s), "nominal": nominal,
            "held_at_rest": held, "rest_draws": int(len(rest)), "p_held_at_rest_wilson": [lo, hi],
            "at_rest_ratio_q50_q90": [float(np.quantile(rest, 0.5)), float(np.quantile(rest, 0.9))],
            "per_draw": per, **summary([r["k"] for r in per], N_CERT["spatial"])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--plans", default="out/robust_table/plans", help="the robust table's plan files (NAME-base.json)")
    ap.add_argument("--only", default=",".join((*PLANAR, *SPATIAL)))
    ap.add_argument("--draws", type=int, default=10000, help="planar draws (closed form)")
    ap.add_argument("--spatial-draws", type=int, default=100, help="spatial draws for the hold scale")
    ap.add_argument("--rest-draws", type=int, default=2000, help="spatial draws for P(held at rest)")
    ap.add_argument("--only-parameters", default=None, metavar="A,B",
                    help="spatial rows: draw only these parameters (the others nominal)")
    ap.add_argument("--step-ms", type=float, default=1.0, help="spatial rows: the plan's motion sampled at this step")
    ap.add_argument("--stand-still", type=int, default=0, metavar="N",
                    help="spatial rows: only co-simulate the first N draws standing still (both starts)")
    ap.add_argument("--out", default="out/hold_floor.json")
    a = ap.parse_args(argv)
    if a.stand_still:
        rows = [{"scenario": n, "stand_still": stand_still_rows(n, str(Path(a.plans) / f"{n}-base.json"), a.stand_still)}
                for n in a.only.split(",") if n in SPATIAL]
        write_text_atomic(a.out, json.dumps(jsonable({"rows": rows}), indent=1))
        for row in rows:
            for r in row["stand_still"]:
                s, o = r["settled"], r["at_rest"]
                print(f"{row['scenario']} draw {r['draw']}: static {r['static_ratio']:.4f}; settled start "
                      f"{s['outcome']} max {s['max_ratio']:.4f} at {s['max_ratio_at_s'] * 1e3:.0f} ms; old start "
                      f"{o['outcome']} max {o['max_ratio']:.4f} at {o['max_ratio_at_s'] * 1e3:.0f} ms")
        return 0
    only = None if a.only_parameters is None else a.only_parameters.split(",")
    rows = []
    for name in a.only.split(","):
        print(f"{name} ...", file=sys.stderr, flush=True)
        rows.append(planar_row(name, a.draws) if name in PLANAR else
                    spatial_row(name, str(Path(a.plans) / f"{name}-base.json"), a.spatial_draws, a.rest_draws, only,
                                a.step_ms * 1e-3))
        write_text_atomic(a.out, json.dumps(jsonable({"rows": rows}), indent=1))
    for r in rows:
        print(f"{r['scenario']}: P(held at rest) {r['p_held_at_rest']:.3f}, k q50 {r['k_q50']:.4f} q90 {r['k_q90']:.4f} "
              f"q95 {r['k_q95']:.4f} q99 {r['k_q99']:.4f}; certification ({r['n_cert']} cases, {r['allowed']} "
              f"losses) passes half the time at x{r['k_cert50']:.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
