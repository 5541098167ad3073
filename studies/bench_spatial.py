"""Spatial arms: the batched SpatialChain against Drake's per-sample loops, side by side in one run.

    cd <checkout> && PYTHONPATH=. .venv/bin/python -m studies.bench_spatial [--n 1000] [--rounds 5]
        [--grid 1000] [--toppra-rounds 25] [--out out]

Hand state of N random samples (q, qd, qdd) on the UR5 and the Panda of `example-robot-data`:
- `spatial_chain`: SpatialChain.evaluate (pose, twist, spatial acceleration, joint torques), one pass;
- `drake_chain`: today's DrakeChain loop (hand_pose + hand_velocity + hand acceleration and joint
  torques), the same quantities sample by sample;
- `drake_inverse_dynamics`: Drake's CalcInverseDynamics alone (with gravity), sample by sample.
Rounds are interleaved (a busy machine slows all alike); in each round every method runs twice and
its second (warm) run is timed; the median per-sample time is reported with
the ratios, and the largest torque difference between the three as a check.

TOPP-RA on a UR5 suction pick-and-place path of `--grid` points (issue 19: under 50 ms): ours
(planners/spatial_toppra.plan_toppra) against Drake's Toppra on the problem both can state (joint
speed and acceleration limits; joint torque limits, the box welded in both models), ours with the
suction rows (Drake's Toppra has no such constraint), and the same suction problem through toppra's
own TOPPRA driver; `--toppra-rounds` interleaved repeats after one warm-up each, medians and
Drake's time over ours in the same run. Prints tables and writes OUT/bench_spatial.json atomically.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from pydrake.multibody.tree import MultibodyForces

from qmt_drake import malloc_tuning
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.contact_wrench import CarriedBody
from qmt_drake.limits.motor_torque import MotorTorqueTerm
from qmt_drake.limits.suction import GripModel, SuctionTerm
from qmt_drake.model.drake_chain import DrakeChain
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.model.spatial_ik import SpatialIK
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic
from qmt_drake.planners.spatial_toppra import (
    joint_path,
    pick_and_place_waypoints,
    plan_drake_toppra,
    plan_toppra,
    recheck,
    toppra_problem,
)

ARMS = ("ur5", "panda")

# The UR5 suction pick-and-place of the TOPP-RA measure (SI units; chosen here, not from a datasheet):
# a 2 kg box held 8 cm below a 15 mm-radius cup pulling 40 N (about -57 kPa), friction 0.5; the URDF's
# joint speed limits, 15 rad/s^2 joint accelerations (torque runs: limits well below the URDF's, so they
# bind; the box welded to the hand in both solvers' models); pick at (0.45, -0.30, 0.10) m, place at
# (0.30, 0.45, 0.10) m, 0.25 m lift, the cup facing down throughout.
UR5_TASK = {"pick_m": [0.45, -0.30, 0.10], "place_m": [0.30, 0.45, 0.10], "lift_m": 0.25,
            "seed_rad": [-0.6, -1.3, 1.6, -1.9, -1.57, 0.0], "acceleration_limit_rad_s2": 15.0,
            "torque_limit_Nm": [50.0, 50.0, 25.0, 6.0, 6.0, 6.0],
            "body": {"mass_kg": 2.0, "com_m": [0.0, 0.0, 0.08], "inertia_kgm2": [0.006, 0.006, 0.004]},
            "cup": {"radius_m": 0.015, "pull_force_N": 40.0, "friction": 0.5}}
# (rim points, pyramid edges, pyramid angle deg): GripModel's default, a hexagon rim with its pyramids
# turned 45 deg (54 faces instead of 86 unturned), and the square rim (16 faces)
GRIP_RESOLUTIONS = ((8, 4, 0), (6, 4, 45), (4, 4, 0))
FINE_GRIP = (24, 8)  # the re-check's model: its rim and pyramids contain all three (closer to the round cup)


def _drake_id_loop(plant, q, qd, qdd):
    ctx = plant.CreateDefaultContext()
    forces = MultibodyForces(plant)
    tau = np.empty_like(q)
    for k in range(len(q)):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, qd[k])
        forces.SetZero()
        plant.CalcForceElementsContribution(ctx, forces)
        tau[k] = plant.CalcInverseDynamics(ctx, qdd[k], forces)
    return tau


def bench_hand_state(arm: str, n: int, rounds: int) -> dict:
    path, hand, lock = example_robot_urdf(arm)
    plant, H, _ = load_arm_plant(path, hand, lock_joints=lock)
    chain, drake_chain = SpatialChain(plant, H), DrakeChain(plant, H)
    rng = np.random.default_rng(0)
    q, qd, qdd = (rng.uniform(-2, 2, (n, chain.n_dof)) for _ in range(3))

    def run_spatial():
        return chain.evaluate(q, qd, qdd)["joint_torque_Nm"]

    def run_drake_chain():
        drake_chain.hand_pose(q)
        drake_chain.hand_velocity(q, qd)
        return drake_chain.hand_acceleration_and_joint_torque(q, qd, qdd)[2]

    def run_drake_id():
        return _drake_id_loop(plant, q, qd, qdd)

    methods = {"spatial_chain": run_spatial, "drake_chain": run_drake_chain, "drake_inverse_dynamics": run_drake_id}
    times = {m: [] for m in methods}
    torques = {m: f() for m, f in methods.items()}  # warm-up and check
    for _ in range(rounds):
        for m, f in methods.items():
            f()  # each method timed warm (its own caches), as it runs inside a planner's loop
            t = time.perf_counter()
            f()
            times[m].append((time.perf_counter() - t) / n)
    med = {m: float(np.median(v)) for m, v in times.items()}
    ref = torques["drake_inverse_dynamics"]
    return {"arm": arm, "n_dof": chain.n_dof, "n_samples": n, "rounds": rounds,
            "per_sample_s": times, "median_per_sample_s": med,
            "ratio_drake_chain_over_spatial": med["drake_chain"] / med["spatial_chain"],
            "ratio_drake_inverse_dynamics_over_spatial": med["drake_inverse_dynamics"] / med["spatial_chain"],
            "max_torque_difference_Nm": {m: float(np.abs(t - ref).max()) for m, t in torques.items()}}


def _toppra_driver(pp, chain, **kwargs) -> dict:
    """plan_toppra's problem solved by toppra's own TOPPRA driver (its Python passes): what
    planners/toppra_passes.py replaces, timed the same way (rows, constructor, passes)."""
    import toppra

    t0 = time.perf_counter()
    path, cons, grid = toppra_problem(pp, chain, **kwargs)
    sdd, sd, _ = toppra.algorithm.TOPPRA(cons, path, gridpoints=grid, solver_wrapper="seidel").compute_parameterization(
        0.0, 0.0)
    return {"planning_s": time.perf_counter() - t0, "grid": grid, "sd": np.asarray(sd, float),
            "duration_s": float(np.sum(2.0 * np.diff(grid) / (sd[:-1] + sd[1:])))}


def bench_toppra(n_grid: int, rounds: int) -> dict:
    """TOPP-RA on the UR5 suction path: toppra with joint limits vs Drake's Toppra (same path, grid and
    limits), the same with joint torque limits, and toppra with the suction grip at several rim
    resolutions (the default grip also through toppra's own TOPPRA driver); median planning times over
    `rounds` interleaved repeats, Drake's over ours in the same run, durations, and the largest suction
    ratio re-checked at 10 points per grid interval."""
    path, hand, lock = example_robot_urdf("ur5")
    plant, H, _ = load_arm_plant(path, hand, lock_joints=lock)
    ik = SpatialIK(plant, H, name="ur5")
    t = UR5_TASK
    b = t["body"]
    body = CarriedBody(b["mass_kg"], np.array(b["com_m"]), np.diag(b["inertia_kgm2"]))
    plant_b, H_b, names = load_arm_plant(path, hand, lock_joints=lock, carried=body.as_dict())
    chain_b = SpatialChain(plant_b, H_b)  # the box welded: joint torques include it
    torque = np.array(t["torque_limit_Nm"])
    torque_term = MotorTorqueTerm(SimpleNamespace(gear_ratio=np.ones(6), joint_names=names, gravity_does_no_work=False),
                                  torque)
    Q = pick_and_place_waypoints(ik, t["pick_m"], t["place_m"], lift_m=t["lift_m"], seed=np.array(t["seed_rad"]))
    pp = joint_path(Q)
    vel = plant.GetVelocityUpperLimits()
    acc = np.full(ik.chain.n_dof, t["acceleration_limit_rad_s2"])
    g = plant.gravity_field().gravity_vector()
    terms = {}
    for rp, pe, deg in GRIP_RESOLUTIONS:
        name = f"suction_{rp}x{pe}" + (f"@{deg}deg" if deg else "")
        grip = GripModel(**t["cup"], rim_points=rp, pyramid_edges=pe, pyramid_angle_rad=np.radians(deg))
        terms[name] = SuctionTerm(grip, body, g, name=name)
    default = next(iter(terms))
    runs = {"toppra_joint_limits": lambda: plan_toppra(pp, ik.chain, velocity_limit=vel, acceleration_limit=acc,
                                                       n_grid=n_grid),
            "drake_toppra_joint_limits": lambda: plan_drake_toppra(pp, plant, velocity_limit=vel,
                                                                   acceleration_limit=acc, n_grid=n_grid),
            "toppra_torque_limits": lambda: plan_toppra(pp, chain_b, velocity_limit=vel, acceleration_limit=acc,
                                                        terms=[torque_term], n_grid=n_grid),
            "drake_toppra_torque_limits": lambda: plan_drake_toppra(pp, plant_b, velocity_limit=vel,
                                                                    acceleration_limit=acc, torque_limit=torque,
                                                                    n_grid=n_grid)}
    for name, term in terms.items():
        runs[name] = (lambda term=term: plan_toppra(pp, ik.chain, velocity_limit=vel, acceleration_limit=acc,
                                                   terms=[term], n_grid=n_grid))
    runs[f"{default}_toppra_driver"] = lambda: _toppra_driver(pp, ik.chain, velocity_limit=vel,
                                                              acceleration_limit=acc, terms=[terms[default]],
                                                              n_grid=n_grid)
    times = {k: [] for k in runs}
    last = {}
    load_before = os.getloadavg()  # the machine is shared: its load says what the milliseconds mean
    for f in runs.values():
        f()  # warm-up (imports, first-call allocations) outside the timing
    for _ in range(rounds):
        for k, f in runs.items():
            last[k] = f()
            times[k].append(last[k]["planning_s"])
    med = {k: 1e3 * float(np.median(v)) for k, v in times.items()}
    out = {"task": t, "n_grid": n_grid, "rounds": rounds, "waypoints_rad": Q, "cpus": os.cpu_count(),
           "load_average_1_5_15min": {"before": load_before, "after": os.getloadavg()},
           "planning_ms_median": med,
           "planning_ms": {k: [1e3 * x for x in v] for k, v in times.items()},
           "duration_s": {k: r["duration_s"] for k, r in last.items()},
           "rows": {k: int(len(term.grip.g)) for k, term in terms.items()}}
    out["rows"][f"{default}_toppra_driver"] = out["rows"][default]
    out["drake_over_toppra_time"] = {lim: med[f"drake_toppra_{lim}"] / med[f"toppra_{lim}"]
                                     for lim in ("joint_limits", "torque_limits")}
    out["suction_over_drake_joint_limits_time"] = {k: med[k] / med["drake_toppra_joint_limits"] for k in terms}
    out["toppra_driver_over_ours_time"] = med[f"{default}_toppra_driver"] / med[default]
    out["toppra_driver_max_sd_difference"] = float(np.max(np.abs(last[default]["sd"] -
                                                                 last[f"{default}_toppra_driver"]["sd"])))
    out["duration_toppra_vs_drake_rel"] = {
        lim: abs(out["duration_s"][f"toppra_{lim}"] / out["duration_s"][f"drake_toppra_{lim}"] - 1.0)
        for lim in ("joint_limits", "torque_limits")}
    fine = SuctionTerm(GripModel(**t["cup"], rim_points=FINE_GRIP[0], pyramid_edges=FINE_GRIP[1]), body, g,
                       name="suction_fine")
    out["recheck_max_ratio"] = {k: recheck(r, pp, ik.chain, [terms[k]] if k in terms else [])
                                .get(k) for k, r in last.items() if "grid" in r}
    out["recheck_max_ratio_fine_grip"] = {k: recheck(r, pp, ik.chain, [fine])["suction_fine"]
                                          for k, r in last.items() if "grid" in r}
    out["fine_grip"] = {"rim_points": FINE_GRIP[0], "pyramid_edges": FINE_GRIP[1], "rows": int(len(fine.grip.g))}
    return out


def main(argv=None) -> int:
    malloc_tuning.tune()  # as the command line does (qmt_drake/malloc_tuning.py)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="samples per evaluation (default 1000)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--grid", type=int, default=1000, help="TOPP-RA grid points (default 1000)")
    ap.add_argument("--toppra-rounds", type=int, default=25, help="TOPP-RA repeats per run (default 25)")
    ap.add_argument("--out", default="out")
    a = ap.parse_args(argv)
    try:
        check_output_dir(a.out, "--out")
        if a.n < 1 or a.rounds < 1 or a.toppra_rounds < 1 or a.grid < 2:
            raise QmtInputError(f"--n {a.n} / --rounds {a.rounds} / --toppra-rounds {a.toppra_rounds} / --grid "
                                f"{a.grid}: give positive integers (grid >= 2)")
        results = {"hand_state": [bench_hand_state(arm, a.n, a.rounds) for arm in ARMS],
                   "toppra": bench_toppra(a.grid, a.toppra_rounds)}
    except QmtInputError as exc:
        print(f"bench_spatial: error: {exc}", file=sys.stderr)
        return 2
    lines = ["Batched spatial hand state against Drake, per sample (median of the rounds):", "",
             "| arm | spatial_chain us/sample | DrakeChain us/sample | Drake ID us/sample | DrakeChain / spatial "
             "| Drake ID / spatial |", "|---|---|---|---|---|---|"]
    for r in results["hand_state"]:
        m = r["median_per_sample_s"]
        lines.append(f"| {r['arm']} | {m['spatial_chain'] * 1e6:.2f} | {m['drake_chain'] * 1e6:.1f} | "
                     f"{m['drake_inverse_dynamics'] * 1e6:.1f} | {r['ratio_drake_chain_over_spatial']:.1f} | "
                     f"{r['ratio_drake_inverse_dynamics_over_spatial']:.1f} |")
    tp = results["toppra"]
    load = tp["load_average_1_5_15min"]
    lines += ["", f"TOPP-RA, UR5 suction pick-and-place, {tp['n_grid']} grid points (median of {tp['rounds']}; load "
              f"average {load['before'][0]:.1f} before, {load['after'][0]:.1f} after on {tp['cpus']} CPUs):", "",
              "| run | rows | planning ms | duration s | max ratio, own grip (10x re-check) | max ratio, "
              f"{tp['fine_grip']['rim_points']}x{tp['fine_grip']['pyramid_edges']} grip |", "|---|---|---|---|---|---|"]
    for k, ms in tp["planning_ms_median"].items():
        own, fine = tp["recheck_max_ratio"].get(k), tp["recheck_max_ratio_fine_grip"].get(k)
        lines.append(f"| {k} | {tp['rows'].get(k, '-')} | {ms:.1f} | {tp['duration_s'][k]:.4f} | "
                     f"{'-' if own is None else f'{own:.4f}'} | {'-' if fine is None else f'{fine:.4f}'} |")
    lines.append("")
    for lim, rel in tp["duration_toppra_vs_drake_rel"].items():
        lines.append(f"toppra vs Drake Toppra ({lim}): duration relative difference {rel:.2e}, Drake's planning "
                     f"time {tp['drake_over_toppra_time'][lim]:.2f}x ours.")
    for k, r in tp["suction_over_drake_joint_limits_time"].items():
        lines.append(f"{k}: our planning time with the suction rows {r:.2f}x Drake's Toppra with the joint limits only.")
    lines.append(f"toppra's own TOPPRA driver on the same rows: {tp['toppra_driver_over_ours_time']:.2f}x our planning "
                 f"time, largest sd difference {tp['toppra_driver_max_sd_difference']:.1e}.")
    print("\n".join(lines))
    # the report's spatial section shows every table of out/spatial/
    write_text_atomic(Path(a.out) / "spatial" / "bench_spatial.md", "\n".join(lines) + "\n")
    write_text_atomic(Path(a.out) / "bench_spatial.json", json.dumps(jsonable(results), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
