"""Spatial arms: the batched SpatialChain against Drake's per-sample loops, side by side in one run.

    cd <checkout> && PYTHONPATH=. .venv/bin/python -m studies.bench_spatial [--n 1000] [--rounds 5] [--out out]

Hand state of N random samples (q, qd, qdd) on the UR5 and the Panda of `example-robot-data`:
- `spatial_chain`: SpatialChain.evaluate (pose, twist, spatial acceleration, joint torques), one pass;
- `drake_chain`: today's DrakeChain loop (hand_pose + hand_velocity + hand acceleration and joint
  torques), the same quantities sample by sample;
- `drake_inverse_dynamics`: Drake's CalcInverseDynamics alone (with gravity), sample by sample.
Rounds are interleaved (a busy machine slows all alike); in each round every method runs twice and
its second (warm) run is timed; the median per-sample time is reported with
the ratios, and the largest torque difference between the three as a check. Prints a table and
writes OUT/bench_spatial.json atomically.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from pydrake.multibody.tree import MultibodyForces

from qmt_drake.errors import QmtInputError
from qmt_drake.model.drake_chain import DrakeChain
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic

ARMS = ("ur5", "panda")


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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000, help="samples per evaluation (default 1000)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--out", default="out")
    a = ap.parse_args(argv)
    try:
        check_output_dir(a.out, "--out")
        if a.n < 1 or a.rounds < 1:
            raise QmtInputError(f"--n {a.n} / --rounds {a.rounds}: give positive integers")
        results = {"hand_state": [bench_hand_state(arm, a.n, a.rounds) for arm in ARMS]}
    except QmtInputError as exc:
        print(f"bench_spatial: error: {exc}", file=sys.stderr)
        return 2
    print("| arm | spatial_chain us/sample | DrakeChain us/sample | Drake ID us/sample | DrakeChain / spatial "
          "| Drake ID / spatial |\n|---|---|---|---|---|---|")
    for r in results["hand_state"]:
        m = r["median_per_sample_s"]
        print(f"| {r['arm']} | {m['spatial_chain'] * 1e6:.2f} | {m['drake_chain'] * 1e6:.1f} | "
              f"{m['drake_inverse_dynamics'] * 1e6:.1f} | {r['ratio_drake_chain_over_spatial']:.1f} | "
              f"{r['ratio_drake_inverse_dynamics_over_spatial']:.1f} |")
    write_text_atomic(Path(a.out) / "bench_spatial.json", json.dumps(jsonable(results), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
