"""Weld threshold vs contact physics on the spatial hands: where they disagree and why (issue 29, item 1).

    cd <checkout> && PYTHONPATH=. .venv/bin/python -m studies.spatial_hand_physics [--out out]
        [--scenario ur5-magnet-part ur5-suction-bins] [--scales 1.0 1.05 1.1 1.2 1.36]

For each scenario: TOPP-RA's plan (planners/spatial_methods, the bound) and its time-scaled versions
(duration x scale, planners/spatial_trajectory.TimeScaled), each co-simulated (ideal actuators) with
- weld: `hand.physics: weld` (the default; the part welded, detached the first step its required wrench
  leaves the hand's limit, sim/spatial_hold.py);
- contact: `hand.physics: contact` (sim/spatial_contact_hand.py: the part a free body held by point
  contacts and the magnet's or the vacuum's pull; lost when it leaves the face by 5 mm or slides 10 mm);
- for the suction cup also contact with a 10x stiffer rim (1e6 N/m): the compliance's share.
Per run: the outcome and the time lost; the plan's own largest hand-term ratio (the part rigid on the
hand, moving as planned), the weld run's (its welded part's simulated motion, up to the loss); for contact the largest tilt / slide / gap while held and the
weld's threshold on the same run's hand motion (its largest ratio and the first time it passed 1). For the
magnet also the contact ring's rigid-body hold condition on the plan itself, with and without the hand's
acceleration along the face normal (`ring_grip_on_plan`): why the contact hand loses where the limit holds.
Prints a Markdown table and writes OUT/spatial_hand_physics.json and .md atomically (qmt_drake/outputs.py).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from qmt_drake.limits.suction import SuctionTerm, cached_grip
from qmt_drake.outputs import check_output_dir, jsonable, write_text_atomic
from qmt_drake.planners.spatial_methods import PLANNERS
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.contact_hand_build import (
    MAGNET_COIL,
    RIM_STIFFNESS_N_PER_M,
    magnet_current_A,
    magnet_spec,
)
from qmt_drake.sim.magnet_hand import MAGNET_EFFECTIVE_GAP_M
from qmt_drake.sim.spatial_cosim import FINE_GRIP, simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.systems.electromagnet import THESIS_COILS, MagnetParams

SCALES = (1.0, 1.05, 1.1, 1.2, 1.36)
SCENARIOS = ("ur5-magnet-part", "ur5-suction-bins")
STIFF_RIM_N_PER_M = 10.0 * RIM_STIFFNESS_N_PER_M


def variants(sc) -> dict:
    """name -> (scenario, simulate_spatial's contact overrides)."""
    out = {"weld": (dataclasses.replace(sc, hand_physics="weld"), None),
           "contact": (dataclasses.replace(sc, hand_physics="contact"), None)}
    if sc.hand_kind == "suction":
        out["contact_stiff_rim"] = (out["contact"][0], {"rim_stiffness_N_per_m": STIFF_RIM_N_PER_M})
    return out


def planned_max_ratio(sc, traj) -> float:
    """The hand term's largest ratio of the plan itself at 1 kHz (the part rigid on the hand moving exactly as
    planned; a cup on the weld check's finer grip, simulate_spatial's default)."""
    grip = None if sc.grip is None else cached_grip(sc.grip.radius_m, sc.grip.pull_force_N, sc.grip.friction,
                                                    face_normal=sc.grip.basis[2], rim_points=FINE_GRIP[0],
                                                    pyramid_edges=FINE_GRIP[1])
    q, qd, qdd = traj.sample(np.arange(0.0, traj.duration_s, 1e-3))
    return float(sc.hand_term(grip).columns(sc.chain.evaluate(q, qd, qdd)).max())


def ring_grip_on_plan(sc, traj) -> dict:
    """Magnet: the contact ring's rigid-body hold condition (the cup's GripModel for the contact hand's
    ring, friction and pull at the seat, sim/spatial_contact_hand) on the plan at 1 kHz, against the
    moment limit: its largest ratio, the moment ratio and the hand's acceleration along the face normal u
    (into the part; negative: away from it) at that sample, and both maxima with that acceleration removed."""
    spec = magnet_spec(sc)
    params = MagnetParams(THESIS_COILS[MAGNET_COIL], MAGNET_EFFECTIVE_GAP_M, spec.face_radius_m)
    ring = SuctionTerm(cached_grip(spec.contact_radius_m, params.force_N(magnet_current_A(sc, spec, params)),
                                   spec.friction, face_normal=sc.face_axis, rim_points=spec.n_contact_points,
                                   pyramid_edges=8), sc.body, sc.gravity_m_s2)
    q, qd, qdd = traj.sample(np.arange(0.0, traj.duration_s, 1e-3))
    st = sc.chain.evaluate(q, qd, qdd)
    u = np.asarray(st["rotation"]) @ np.asarray(sc.face_axis, float)
    a = np.asarray(st["linear_acceleration_m_s2"])
    a_u = np.einsum("si,si->s", a, u)
    no_normal = dict(st, linear_acceleration_m_s2=a - a_u[:, None] * u)
    r, m = ring.columns(st)[:, 0], sc.hand_term().columns(st)[:, 0]
    i = int(np.argmax(r))
    return {"ring_grip_max": float(r[i]), "at_s": i * 1e-3, "moment_ratio_there": float(m[i]),
            "accel_along_normal_there_m_s2": float(a_u[i]),
            "ring_grip_max_without_normal_accel": float(ring.columns(no_normal).max()),
            "moment_ratio_max_without_normal_accel": float(sc.hand_term().columns(no_normal).max())}


def run(scenario: str, scales) -> dict:
    sc = load_spatial_scenario(scenario)
    plan = PLANNERS["toppra"](sc)
    rows = []
    for k in scales:
        traj = TimeScaled(plan.trajectory, k)
        row = {"scale": k, "duration_s": traj.duration_s, "planned_max_ratio": planned_max_ratio(sc, traj)}
        if sc.hand_kind == "magnet":
            row["planned_ring_grip"] = ring_grip_on_plan(sc, traj)
        for name, (s, opts) in variants(sc).items():
            t0 = time.perf_counter()
            r = simulate_spatial(s, traj, contact=opts)
            r["wall_s"] = time.perf_counter() - t0
            row[name] = r
        rows.append(row)
    return {"scenario": sc.name, "hand_kind": sc.hand_kind, "bound_s": plan.raw_duration_s, "rows": rows}


def _verdict(r: dict) -> str:
    return r["outcome"] + (f" {r['lost_at_s']:.3f} s" if r.get("lost_at_s") is not None else "")


def _ratio(r: dict, name: str) -> str:
    first = r.get(f"{name}_first_above_1_s")
    return f"{r[f'{name}_max_ratio']:.3f}, {'-' if first is None else f'{first:.3f}'}"


def markdown(results: list) -> str:
    lines = []
    for res in results:
        names = [n for n in ("weld", "contact", "contact_stiff_rim") if n in res["rows"][0]]
        contacts = [n for n in names if n != "weld"]
        ring = res["hand_kind"] == "magnet"
        lines += [f"{res['scenario']} ({res['hand_kind']}): TOPP-RA bound {res['bound_s']:.4f} s, ideal actuators", "",
                  "| scale | time s | " + " | ".join(names) + " | plan: max ratio | weld: max ratio | "
                  + " | ".join(f"{n}: max tilt mrad / slide mm / gap mm held" for n in contacts)
                  + " | contact's hand motion: threshold max, first > 1 s |"
                  + (" contact's hand motion: ring grip max, first > 1 s |" if ring else ""),
                  "|---|---|" + "---|" * (2 * len(names) + 2 + ring)]
        for row in res["rows"]:
            c = row["contact"]
            held = [f"{1e3 * row[n]['max_tilt_while_held_rad']:.1f} / {1e3 * row[n]['max_slide_while_held_m']:.2f} / "
                    f"{1e3 * row[n]['max_gap_while_held_m']:.3f}" for n in contacts]
            lines.append(f"| {row['scale']:g} | {row['duration_s']:.4f} | " + " | ".join(_verdict(row[n]) for n in names)
                         + f" | {row['planned_max_ratio']:.3f} | {row['weld']['max_grip_ratio_while_held']:.3f} | "
                         + " | ".join(held)
                         + f" | {_ratio(c, 'threshold')} |" + (f" {_ratio(c, 'ring_grip')} |" if ring else ""))
        lines.append("")
        if ring:
            lines += ["Magnet, on the plan: the ring's rigid-body hold (ring grip) vs the moment limit, with the hand's "
                      "acceleration along the face normal u (into the part) at the ring's worst sample", "",
                      "| scale | ring grip max | at s | moment ratio there | accel along u m/s^2 | ring grip max without it "
                      "| moment max without it |", "|---|---|---|---|---|---|---|"]
            for row in res["rows"]:
                g = row["planned_ring_grip"]
                lines.append(f"| {row['scale']:g} | {g['ring_grip_max']:.3f} | {g['at_s']:.3f} | {g['moment_ratio_there']:.3f} | "
                             f"{g['accel_along_normal_there_m_s2']:+.2f} | {g['ring_grip_max_without_normal_accel']:.3f} | "
                             f"{g['moment_ratio_max_without_normal_accel']:.3f} |")
            lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="out")
    ap.add_argument("--scenario", nargs="+", default=list(SCENARIOS))
    ap.add_argument("--scales", nargs="+", type=float, default=list(SCALES))
    args = ap.parse_args(argv)
    check_output_dir(args.out, "--out")
    results = [run(s, args.scales) for s in args.scenario]
    text = markdown(results)
    print(text)
    out = Path(args.out)
    write_text_atomic(out / "spatial_hand_physics.json", json.dumps(jsonable(results), indent=1))
    write_text_atomic(out / "spatial_hand_physics.md", text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
