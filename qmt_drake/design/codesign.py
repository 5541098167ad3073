"""Structure + motion co-design (issue 12, item 7, beyond seed 003): link lengths of the thesis's
chapter-4 two-link transfer arm (seed 000) chosen to minimise the family-optimum QMT motion time of
chapter 4's task under the same moment and motor-torque limits.

Arm family: the chapter-4 arm (models/generate_urdf.py ARMS["two_link_ch4"], Table 4.1) with link i
scaled by s_i = l_i / l_i,thesis at constant cross-section and density: length, centre-of-mass
distance x s_i, mass x s_i, inertia about the centre of mass x s_i^3 (a slender link); motors,
gears and the electromagnet unchanged. For each (l1, l2) a URDF and a scenario (a copy of
thesis-ch4.yaml whose arm.urdf points at it) are written under `folder`; the inner planner is
`plan_with("optimum", scenario)`. Lengths in m, times in s.

Joint layout: the base (joint 1's axis) may also move in the plane to (x_b, y_b): the task's four
points stay where chapter 4 puts them in the world, so the scenario's points (given relative to the
base) are shifted by -(x_b, y_b). Moving the base changes the joint-space cubics and so the tip
path and its accelerations; the moment limit (payload, hand) and the motor limits stay those of
thesis-ch4.yaml. `pattern_search` searches (l1, l2, x_b, y_b) together.
"""

from __future__ import annotations

import copy
import importlib.util
import time
from pathlib import Path

import numpy as np
import yaml

from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import write_text_atomic
from qmt_drake.planners import plan_with
from qmt_drake.transfer_scenario import load_scenario

ROOT = Path(__file__).resolve().parents[2]


def _arms():
    spec = importlib.util.spec_from_file_location("qmt_generate_urdf", ROOT / "models" / "generate_urdf.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def scaled_spec(l1_m: float, l2_m: float) -> dict:
    mod = _arms()
    base = copy.deepcopy(mod.ARMS["two_link_ch4"])
    s = np.array([l1_m, l2_m]) / np.array(base["length_m"])
    base["length_m"] = [float(l1_m), float(l2_m)]
    base["com_from_joint_m"] = (np.array(base["com_from_joint_m"]) * s).tolist()
    base["mass_kg"] = (np.array(base["mass_kg"]) * s).tolist()
    base["izz_about_com_kgm2"] = (np.array(base["izz_about_com_kgm2"]) * s ** 3).tolist()
    base["source"] = (base["source"] + f"; links scaled by {s.round(4).tolist()} (uniform density) "
                      "by qmt_drake.design.codesign")
    return base


def write_scenario(l1_m: float, l2_m: float, folder: Path, base_m=(0.0, 0.0)) -> Path:
    """URDF + scenario for one pair of lengths and a base position (x_b, y_b) in the chapter-4
    world frame; returns the scenario path."""
    folder = Path(folder)
    name = f"two_link_ch4_l1_{l1_m * 1e3:.0f}mm_l2_{l2_m * 1e3:.0f}mm"
    urdf = folder / f"{name}.urdf"
    if not urdf.exists():
        write_text_atomic(urdf, _arms().make_urdf(name, scaled_spec(l1_m, l2_m)))
    sc = yaml.safe_load((ROOT / "models" / "scenarios" / "thesis-ch4.yaml").read_text())
    bx, by = (float(v) for v in base_m)
    if bx or by:
        name += f"_base_{bx * 1e3:+.0f}_{by * 1e3:+.0f}mm"
        sc["task"]["points_m"] = [[round(p[0] - bx, 12), round(p[1] - by, 12)]
                                  for p in sc["task"]["points_m"]]
    sc["name"] = f"codesign-{name}"
    sc["arm"]["urdf"] = str(urdf.resolve())
    sc.pop("reported", None)
    path = folder / f"{name}.yaml"
    write_text_atomic(path, yaml.safe_dump(sc, sort_keys=False))
    return path


def evaluate_lengths(l1_m: float, l2_m: float, folder: Path, base_m=(0.0, 0.0)) -> dict:
    """Family-optimum motion time of the chapter-4 task for one pair of lengths and base position
    (inf if the task is out of reach or no plan meets the limits)."""
    t0 = time.perf_counter()
    base = [float(base_m[0]), float(base_m[1])]
    path = write_scenario(l1_m, l2_m, folder, base)
    try:
        sc = load_scenario(path)
        plan = plan_with("optimum", sc)
        T = float(plan.motion_time_s) if plan.feasible else float("inf")
        genes = np.asarray(plan.genes).tolist()
        feas = bool(plan.feasible)
    except QmtInputError as e:   # e.g. a via point out of reach
        T, genes, feas = float("inf"), None, False
        return {"l1_m": l1_m, "l2_m": l2_m, "base_m": base, "motion_time_s": T, "feasible": feas,
                "genes": genes, "scenario": str(path), "error": str(e),
                "wall_s": time.perf_counter() - t0}
    return {"l1_m": l1_m, "l2_m": l2_m, "base_m": base, "motion_time_s": T, "feasible": feas,
            "genes": genes, "scenario": str(path), "wall_s": time.perf_counter() - t0}


def grid_search(l1s, l2s, folder: Path, progress=None) -> list[dict]:
    """Outer search: every pair of the grid (the task's reach is checked by the scenario loader)."""
    out = []
    for l1 in l1s:
        for l2 in l2s:
            r = evaluate_lengths(float(l1), float(l2), folder)
            out.append(r)
            if progress:
                progress(f"codesign l1 {l1:.3f} l2 {l2:.3f}: T0 {r['motion_time_s']:.4f} s "
                         f"({r['wall_s']:.1f} s)")
    return out


# Bounds of the layout search (m): lengths around the thesis's 0.16 / 0.12 m, base within 0.10 m
# of the thesis's (the task points span x -0.18..0.17 m, y 0.10..0.20 m).
LAYOUT_LOWER_M = np.array([0.08, 0.06, -0.10, -0.10])
LAYOUT_UPPER_M = np.array([0.26, 0.20, 0.10, 0.10])


def pattern_search(start, folder: Path, *, step_m: float = 0.02, min_step_m: float = 0.005,
                   lower=LAYOUT_LOWER_M, upper=LAYOUT_UPPER_M, max_evaluations: int = 150,
                   progress=None, evaluate=None) -> dict:
    """Outer search over x = (l1, l2, x_b, y_b) in m: compass search (poll +-step along each
    coordinate, move to the best improving poll point, halve the step when none improves, stop
    below min_step_m or after max_evaluations inner plans). Deterministic; points on a 1 mm grid
    are evaluated once (cache). The objective (family-optimum time) is not smooth in x (the GA's
    optimum jumps), so a derivative-free poll is used. Returns the best row, every evaluated row
    and the step history. `evaluate(l1, l2, folder, base)` defaults to evaluate_lengths."""
    evaluate = evaluate or evaluate_lengths
    cache: dict = {}

    def f(x):
        key = tuple(np.round(np.asarray(x) * 1e3).astype(int))
        if key not in cache:
            xm = np.array(key) / 1e3
            if np.any(xm < lower - 1e-12) or np.any(xm > upper + 1e-12):
                cache[key] = {"l1_m": xm[0], "l2_m": xm[1], "base_m": xm[2:].tolist(),
                              "motion_time_s": float("inf"), "feasible": False,
                              "error": "outside the search bounds"}
            else:
                cache[key] = evaluate(float(xm[0]), float(xm[1]), folder, xm[2:])
                if progress:
                    r = cache[key]
                    progress(f"layout l1 {xm[0]:.3f} l2 {xm[1]:.3f} base ({xm[2]:+.3f}, {xm[3]:+.3f}) m: "
                             f"T0 {r['motion_time_s']:.4f} s")
        return cache[key]

    def n_evals():
        return sum(1 for r in cache.values() if r.get("error") != "outside the search bounds")

    x = np.asarray(start, dtype=float)
    best = f(x)
    steps = []
    step = step_m
    while step >= min_step_m - 1e-12 and n_evals() < max_evaluations:
        polls = []
        for j in range(4):
            for sgn in (1, -1):
                y = x.copy()
                y[j] += sgn * step
                polls.append((y, f(y)))
                if n_evals() >= max_evaluations:
                    break
        y, r = min(polls, key=lambda p: p[1]["motion_time_s"])
        if r["motion_time_s"] < best["motion_time_s"] - 1e-9:
            x, best = y, r
            steps.append({"step_m": step, "moved_to": x.tolist(), "T0_s": r["motion_time_s"]})
        else:
            step /= 2
            steps.append({"step_m": step * 2, "halved": True})
    rows = [r for r in cache.values() if r.get("error") != "outside the search bounds"]
    return {"best": best, "x_best": x.tolist(), "evaluations": n_evals(), "rows": rows, "steps": steps}
