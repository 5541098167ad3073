"""Obstacles and clearance: every spatial method's plan in its cell, and the fastest carried time with the
obstacles against without (docs/obstacles.md).

    cd <checkout> && PYTHONPATH=. .venv/bin/python -m studies.obstacles_clearance [--out out]
        [--ga-generations 30] [--no-cosim] [--kto] [--collision-free [poses] [ends]]
    ... -m studies.obstacles_clearance --avoid-check SEED [--avoid-through poses|ends]   (avoid_check only)

Cells: ur5-suction-bins (its shipped totes), the same task in docs/examples/ur5-deep-totes.yaml (totes 4 cm
deeper than the task's lift clears) and panda-tray-cup (its table). The planners do not see obstacles, so
each task is planned once (TOPP-RA, Ruckig, the via-cubic family optimum, the GA, trajopt:
planners/spatial_methods) and every plan is re-checked in each cell (planners/spatial_plan_io.make_spatial_plan:
the limits at the re-check rate and the clearance, limits/clearance.py: Drake's signed distance of the arm's
URDF collision shapes and the carried part against the obstacles, independent of the planner).

A detour where the task's path collides (the deep totes): the lifted task poses (1 and K-2) raised by the
smallest whole centimetre dz >= the TOPP-RA plan's penetration depth + DETOUR_MARGIN_M for which its plan
clears by DETOUR_MARGIN_M (IK solves the raised poses: the scenario loader), then timed by TOPP-RA, the family
optimum and the GA under the same limits, each re-checked in the cell. --kto also retimes (qmt_drake/retime.py,
TOPP-RA) the path of Drake's KinematicTrajectoryOptimization with MinimumDistanceLowerBoundConstraint
(`kto_path`), re-checked the same way.

--collision-free: in every cell, the certified collision-free path (planners/collision_free.collision_free_scenario,
FREE_TRIES seeds; through every task pose, and/or only from the first to the last) timed by every planner, each row's clearance certified (limits/clearance.certified_clearance at
10x the re-check rate, a bound between samples), and the cell's collision-free TOPP-RA plan co-simulated in it.

Side by side per cell: the fastest plan within every limit without the obstacles (every plan) and with them
(clearance >= 0 as well, detour plans included), and, unless --no-cosim, the fastest CARRIED time of each:
the candidates in order of their time, each co-simulated (sim/spatial_cosim, with the cell's obstacles or
without them) and, when not carried as planned, slowed by planners/spatial_carried.carried_search (the
smallest time scale up to CARRIED_K_MAX the co-simulation carries), until no later candidate can be faster.
Prints the tables and writes OUT/obstacles/clearance.json atomically (qmt_drake/outputs.py).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml
from pydrake.multibody.inverse_kinematics import (
    AngleBetweenVectorsConstraint,
    MinimumDistanceLowerBoundConstraint,
)
from pydrake.planning import KinematicTrajectoryOptimization
from pydrake.solvers import Solve
from pydrake.trajectories import BsplineTrajectory

from qmt_drake.energy.energy_plan import METHODS as ENERGY_TIME_METHODS
from qmt_drake.errors import QmtNoPlanError
from qmt_drake.limits.clearance import certified_clearance, collision_model
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic
from qmt_drake.planners.collision_free import collision_free_scenario
from qmt_drake.planners.spatial_carried import carried_search
from qmt_drake.planners.spatial_methods import PLANNERS, plan_ga_spatial
from qmt_drake.planners.spatial_plan_io import make_spatial_plan
from qmt_drake.retime import retime_path
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario

ROOT = Path(__file__).resolve().parents[1]
DEEP_TOTES = ROOT / "docs" / "examples" / "ur5-deep-totes.yaml"
TASKS = {"ur5-suction-bins": ("ur5-suction-bins", DEEP_TOTES), "panda-tray-cup": ("panda-tray-cup",)}
CELL_NAMES = {str(DEEP_TOTES): "ur5-deep-totes"}
DETOUR_METHODS = ("toppra", "family_optimum", "ga")
DETOUR_MARGIN_M = 0.005
DETOUR_STEPS = 5
# the optimizer's clearance bound at its samples (below the 1 cm the part starts and ends above the tote's floor;
# a larger bound inside the path stalled SNOPT at its iteration limit); the plan is re-checked independently
KTO_BOUND_M = 0.009
KTO_CONTROL_POINTS, KTO_SAMPLES, KTO_TILT_RAD, KTO_WAYPOINTS = 12, 60, 0.02, 40
CARRIED_K_MAX = 1.5
FREE_TRIES = 4  # --collision-free: seeded paths per cell, the one TOPP-RA times fastest kept
CERTIFY_RATE_FACTOR = 10
CARRIED_ITERATIONS = 6
# the minimum-time methods (registry order, TOPP-RA first): the energy-time ones minimise another cost and take c1, c2
METHODS = tuple(m for m in PLANNERS if m not in ENERGY_TIME_METHODS)


def _plans(sc, methods, ga_generations: int) -> dict:
    out = {}
    for m in methods:
        t0 = time.perf_counter()
        out[m] = plan_ga_spatial(sc, generations=ga_generations) if m == "ga" else PLANNERS[m](sc)
        print(f"  {sc.name} {m}: {out[m].duration_s:.4f} s ({time.perf_counter() - t0:.1f} s)", flush=True)
    return out


def _in_cell(cell, plan):
    """The plan re-checked in `cell` (its limits and its clearance from the cell's obstacles)."""
    return make_spatial_plan(cell, plan.method, plan.trajectory, plan.pose_times_s, planning_s=plan.planning_s,
                             raw_duration_s=plan.raw_duration_s, hold_scale=plan.hold_scale, info={})


def _row(cell_name: str, p, note: str = "", cell=None) -> dict:
    """The plan's table row; with `cell`, also its clearance certified independently of the planner and of the
    re-check (limits/clearance.certified_clearance at CERTIFY_RATE_FACTOR x the re-check rate, bounded between
    samples)."""
    c = p.clearance
    row = {"cell": cell_name, "method": p.method + note, "motion_time_s": p.duration_s,
           "recheck_max_ratio": p.recheck["max"], "within_limits": bool(p.check.feasible),
           "clearance_m": c.get("clearance_m"), "clearance_pair": c.get("clearance_pair"),
           "clearance_time_s": c.get("clearance_time_s"), "feasible": bool(p.feasible)}
    if cell is not None:
        cc = certified_clearance(cell, p.trajectory, CERTIFY_RATE_FACTOR * cell.recheck_rate_hz)
        row["certified"] = {k: cc[k] for k in ("clearance_m", "clearance_lower_bound_m", "clearance_time_s",
                                                "clearance_samples", "certified", "tolerance_m")}
    return row


def collision_free_rows(cell, name: str, ga_generations: int, through: str) -> tuple[list, dict, dict]:
    """([(row, plan)] of every planner on the collision-free path through the task's `through` (poses: every
    task pose; ends: the first and the last; planners/collision_free.py, FREE_TRIES seeded paths from seed 0,
    the one TOPP-RA times fastest), the path's facts, {method: plan})."""
    t0 = time.perf_counter()
    free, facts = collision_free_scenario(cell, seed=0, tries=FREE_TRIES, through=through)
    facts["planning_s"] = time.perf_counter() - t0
    print(f"  {name} collision-free path through the {through}: {facts['vertices']} vertices, {facts['path_length_rad']:.3f} rad, certified "
          f">= {facts['path_clearance_lower_bound_m']:.4f} m, seed {facts['seed']} ({facts['planning_s']:.1f} s)",
          flush=True)
    plans = {}
    for m in METHODS:
        try:
            plans.update(_plans(free, (m,), ga_generations))
        except QmtNoPlanError as exc:
            facts.setdefault("no_plan", {})[m] = str(exc)
            print(f"  {name} {m} on the collision-free path: no plan ({exc})", flush=True)
    note = " (collision-free path)" if through == "poses" else " (collision-free, ends only)"
    return [(_row(name, p, note, cell), p) for p in plans.values()], facts, plans


def avoid_check(seed: int, through: str = "poses", methods=("toppra", "trajopt")) -> list:
    """--avoid-check: `plan docs/examples/ur5-deep-totes.yaml --avoid [through] --avoid-seed SEED` by each method
    (its planning wall time), each row's clearance certified as in --collision-free, and each plan co-simulated
    in the cell (ideal actuators): the outcome and a touch (docs/obstacles.md, trajopt that keeps the clearance)."""
    cell = load_spatial_scenario(DEEP_TOTES)
    free, facts = collision_free_scenario(cell, seed=seed, through=through)
    rows = []
    for m in methods:
        t0 = time.perf_counter()
        try:
            p = PLANNERS[m](free)
        except QmtNoPlanError as exc:
            print(f"| ur5-deep-totes | {m} (collision-free path, seed {seed}, {through}) | no plan: {exc} |", flush=True)
            rows.append({"method": m, "no_plan": str(exc), "planning_wall_s": time.perf_counter() - t0})
            continue
        wall = time.perf_counter() - t0
        row = _row("ur5-deep-totes", p, f" (collision-free path, seed {seed}, {through})", cell)
        r = simulate_spatial(free, p.trajectory)
        row.update(planning_wall_s=wall, outcome=r["outcome"], collided_at_s=r.get("collided_at_s"),
                   trajopt_clearance=p.extra.get("trajopt_clearance"))
        c = row["certified"]
        print(f"| ur5-deep-totes | {row['method']} | {p.duration_s:.4f} | {p.recheck['max']:.5f} | "
              f"{row['clearance_m']:+.4f} | {c['clearance_m']:+.4f} [{c['clearance_lower_bound_m']:+.4f}] | "
              f"{'yes' if p.feasible else 'NO'} | {wall:.1f} | {r['outcome']} |", flush=True)
        rows.append(row)
    return rows


def _raised(path: Path, dz: float, tmp: Path) -> Path:
    """A copy of the scenario file with its lifted task poses (1 and K-2) raised by dz (m)."""
    raw = yaml.safe_load(path.read_text())
    poses = raw["task"]["poses_m"]
    for k in (1, len(poses) - 2):
        poses[k][2] = round(poses[k][2] + dz, 6)
    out = tmp / f"{path.stem}-lift{dz:+.2f}.yaml"
    out.write_text(yaml.safe_dump(raw, sort_keys=False))
    return out


def detour(path: Path, depth_m: float, ga_generations: int, tmp: Path) -> tuple[float, dict]:
    """(dz, plans) of the smallest raised lift whose TOPP-RA plan clears the cell by DETOUR_MARGIN_M."""
    dz = max(0.01, float(int((depth_m + DETOUR_MARGIN_M) * 100 + 0.999)) / 100)
    for _ in range(DETOUR_STEPS):
        sc = load_spatial_scenario(_raised(path, dz, tmp))
        first = _plans(sc, ("toppra",), ga_generations)
        if first["toppra"].clearance["clearance_m"] >= DETOUR_MARGIN_M:
            return dz, {**first, **_plans(sc, DETOUR_METHODS[1:], ga_generations)}
        dz = round(dz + 0.01, 2)
    raise RuntimeError(f"no lift up to {dz:.2f} m clears {path.name}")


def kto_path(cell, guess_q: np.ndarray) -> np.ndarray:
    """(KTO_WAYPOINTS, n) joint waypoints of a collision-free path from the first to the last task pose:
    Drake's KinematicTrajectoryOptimization (a B-spline of KTO_CONTROL_POINTS, duration cost, the joint range
    and speed limits, at rest at both ends; a path-length cost stalls SNOPT, info 41) with
    MinimumDistanceLowerBoundConstraint
    (KTO_BOUND_M, on the clearance model's plant: arm and part against the obstacles only) and the face
    normal within KTO_TILT_RAD of the task's at KTO_SAMPLES path parameters; started from guess_q (the
    raised-lift path). Its timing is retime's (TOPP-RA, the GA), its clearance the re-check's."""
    cm, n = collision_model(cell), cell.n_dof
    plant, ctx = cm.plant, cm.plant_context
    to = KinematicTrajectoryOptimization(n, KTO_CONTROL_POINTS, 4)
    to.AddDurationCost(1.0)
    to.AddPositionBounds(plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits())
    to.AddVelocityBounds(-cell.velocity_limit_rad_s, cell.velocity_limit_rad_s)
    to.AddDurationConstraint(0.1, 20.0)
    for sk, qk in ((0.0, cell.q_poses_rad[0]), (1.0, cell.q_poses_rad[-1])):
        to.AddPathPositionConstraint(qk, qk, sk)
        to.AddPathVelocityConstraint(np.zeros(n), np.zeros(n), sk)
    hand = plant.GetFrameByName(cell.hand_frame)
    clear = MinimumDistanceLowerBoundConstraint(plant, KTO_BOUND_M, ctx)
    for sk in np.linspace(0.0, 1.0, KTO_SAMPLES):
        to.AddPathPositionConstraint(clear, sk)
        to.AddPathPositionConstraint(AngleBetweenVectorsConstraint(plant, plant.world_frame(), cell.face_normal, hand,
                                                                   cell.face_axis, 0.0, KTO_TILT_RAD, ctx), sk)
    d = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(guess_q, axis=0), axis=1))]
    u = np.linspace(0.0, d[-1], KTO_CONTROL_POINTS)
    ctrl = [np.array([np.interp(x, d, guess_q[:, j]) for j in range(n)]).reshape(n, 1) for x in u]
    to.SetInitialGuess(BsplineTrajectory(to.basis(), ctrl))
    res = Solve(to.get_mutable_prog())
    if not res.is_success():
        raise RuntimeError(f"KinematicTrajectoryOptimization found no clear path ({res.get_solution_result()}, "
                           f"{res.get_solver_id().name()} info {getattr(res.get_solver_details(), 'info', None)})")
    bs = to.ReconstructTrajectory(res)
    return np.array([bs.value(t).ravel() for t in np.linspace(bs.start_time(), bs.end_time(), KTO_WAYPOINTS)])


def _fastest(pairs: list, key: str):
    """(row, plan) of the shortest plan whose row says `key`, or (None, None)."""
    ok = [rp for rp in pairs if rp[0][key]]
    return min(ok, key=lambda rp: rp[0]["motion_time_s"]) if ok else (None, None)


def fastest_carried(cell, pairs: list, key: str) -> dict | None:
    """The fastest carried time over the plans whose row says `key` (module docstring)."""
    best = None
    for row, p in sorted((rp for rp in pairs if rp[0][key]), key=lambda rp: rp[0]["motion_time_s"]):
        if best is not None and row["motion_time_s"] >= best["carried_time_s"]:
            break
        r = simulate_spatial(cell, p.trajectory)
        k, outcome = 1.0, r["outcome"]
        if outcome != "carried":
            search = carried_search(cell, p, k_max=CARRIED_K_MAX, iterations=CARRIED_ITERATIONS, try_planned=False)
            k = search["chosen"]
        print(f"  {row['cell']} {row['method']}: {outcome} as planned"
              + ("" if k == 1.0 else f", carried at x{k:.4f}" if k else f", not carried up to x{CARRIED_K_MAX}"),
              flush=True)
        if k and (best is None or k * row["motion_time_s"] < best["carried_time_s"]):
            best = {"method": row["method"], "planned_s": row["motion_time_s"], "time_scale": k,
                    "carried_time_s": k * row["motion_time_s"], "outcome_as_planned": outcome,
                    "collided_at_s": r.get("collided_at_s")}
    return best


def run(ga_generations: int, cosim: bool, kto: bool = False, free: tuple = ()) -> dict:
    """The study (module docstring); free: the collision-free paths to plan in every cell, ("poses", "ends")."""
    rows, side, paths, cosims = [], [], {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for task, cells in TASKS.items():
            base = load_spatial_scenario(task)
            plans = _plans(base, METHODS, ga_generations)
            for cell_ref in cells:
                cell = base if cell_ref == task else load_spatial_scenario(cell_ref)
                name = CELL_NAMES.get(str(cell_ref), str(cell_ref))
                pairs = [(_row(name, q, cell=cell if free else None), q)
                         for q in (p if cell is base else _in_cell(cell, p) for p in plans.values())]
                without = _fastest(pairs, "within_limits")[0]
                if min(r["clearance_m"] for r, _ in pairs) < 0:
                    toppra = pairs[0][1]  # METHODS lists TOPP-RA first
                    dz, extra = detour(Path(cell_ref), -toppra.clearance["clearance_m"], ga_generations, Path(tmp))
                    pairs += [(_row(name, p, f" (lift +{dz:.2f} m)"), p) for p in extra.values()]
                    if kto:
                        raised = load_spatial_scenario(_raised(Path(cell_ref), dz, Path(tmp)))
                        p = retime_path(cell, kto_path(cell, raised.q_path_rad), "toppra", collisions="report")
                        print(f"  {name} TOPP-RA on the KTO path: {p.duration_s:.4f} s", flush=True)
                        pairs.append((_row(name, p, " (KTO path)"), p))
                for through in free:
                    key = f"{name} through the {through}"
                    try:
                        extra, facts, fplans = collision_free_rows(cell, name, ga_generations, through)
                    except QmtNoPlanError as exc:  # reported, not hidden: the cell's row says the planner failed
                        paths[key] = {"failed": str(exc)}
                        print(f"  {key}: collision-free path FAILED ({exc})", flush=True)
                        continue
                    pairs += extra
                    paths[key] = facts
                    if "toppra" in fplans:
                        r = simulate_spatial(cell, fplans["toppra"].trajectory)  # the co-simulation, in the cell
                        cosims[key] = {k: r.get(k) for k in ("outcome", "collided_at_s", "clearance_m",
                                                             "clearance_pair", "clearance_time_s", "lost_at_s")}
                        print(f"  {key}: collision-free TOPP-RA co-simulated: {cosims[key]}", flush=True)
                rows += [r for r, _ in pairs]
                entry = {"cell": name, "without_obstacles": without, "with_obstacles": _fastest(pairs, "feasible")[0]}
                if cosim:
                    entry["carried_without_obstacles"] = fastest_carried(replace(cell, obstacles=()), pairs,
                                                                         "within_limits")
                    entry["carried_with_obstacles"] = fastest_carried(cell, pairs, "feasible")
                side.append(entry)
    return {"ga_generations": ga_generations, "rows": rows, "side_by_side": side, "collision_free_paths": paths,
            "collision_free_toppra_cosim": cosims}


def tables(res: dict) -> str:
    cert = any("certified" in r for r in res["rows"])
    out = ["| cell | method | T (s) | re-check max ratio | smallest clearance (m) | pair | at (s) | feasible |"
           + (" certified at 10x: smallest [lower bound] (m) |" if cert else ""),
           "|---|---|---|---|---|---|---|---|" + ("---|" if cert else "")]
    for r in res["rows"]:
        pair = " vs ".join(r["clearance_pair"] or ["-"])
        c = r.get("certified")
        out.append(f"| {r['cell']} | {r['method']} | {r['motion_time_s']:.4f} | {r['recheck_max_ratio']:.4f} | "
                   f"{r['clearance_m']:+.4f} | {pair} | {r['clearance_time_s']:.3f} | {'yes' if r['feasible'] else 'NO'} |"
                   + (f" {c['clearance_m']:+.4f} [{c['clearance_lower_bound_m']:+.4f}] |" if c else (" - |" if cert else "")))
    out += ["", "| cell | fastest within the limits, without obstacles | with obstacles (clear) | fastest carried "
            "without obstacles | with obstacles |", "|---|---|---|---|---|"]

    def planned(r):
        return "none" if r is None else f"{r['method']} {r['motion_time_s']:.4f} s"

    def carried(c):
        if c is None:
            return "-"
        scale = "" if c["time_scale"] == 1.0 else f" (x{c['time_scale']:.4f} of {c['planned_s']:.4f} s)"
        return f"{c['method']} {c['carried_time_s']:.4f} s{scale}"
    for s in res["side_by_side"]:
        out.append(f"| {s['cell']} | {planned(s['without_obstacles'])} | {planned(s['with_obstacles'])} | "
                   f"{carried(s.get('carried_without_obstacles'))} | {carried(s.get('carried_with_obstacles'))} |")
    return "\n".join(out)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--ga-generations", type=int, default=30)
    ap.add_argument("--no-cosim", action="store_true")
    ap.add_argument("--kto", action="store_true", help="also retime a KinematicTrajectoryOptimization path (kto_path)")
    ap.add_argument("--collision-free", nargs="*", choices=("poses", "ends"), default=None,
                    help="also every planner on the collision-free path (planners/collision_free.py) through the "
                         "task's poses and/or its ends in every cell (no value: both), and every row's clearance "
                         "certified at 10x the re-check rate")
    ap.add_argument("--avoid-check", type=int, default=None, metavar="SEED",
                    help="only: toppra and trajopt on the deep totes' --avoid path of this seed (avoid_check)")
    ap.add_argument("--avoid-through", choices=("poses", "ends"), default="poses")
    a = ap.parse_args(argv)
    check_output_dir(a.out, "--out")
    if a.avoid_check is not None:
        print("| cell | method | T (s) | re-check max ratio | clearance (m) | certified at 10x [lower bound] (m) | "
              "feasible | planning (s) | co-simulated |")
        rows = avoid_check(a.avoid_check, a.avoid_through)
        out = Path(a.out) / "obstacles"
        out.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out / f"avoid_check_{a.avoid_through}_{a.avoid_check}.json", json.dumps(jsonable(rows), indent=1))
        return
    free = () if a.collision_free is None else tuple(a.collision_free or ("poses", "ends"))
    res = run(a.ga_generations, not a.no_cosim, a.kto, free)
    text = tables(res)
    print(text)
    out = Path(a.out) / "obstacles"
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "clearance.json", json.dumps(jsonable(res), indent=1))
    write_text_atomic(out / "clearance.md", text + "\n")
    print(f"wrote {out / 'clearance.json'} and .md")


if __name__ == "__main__":
    main()
