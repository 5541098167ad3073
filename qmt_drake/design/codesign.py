"""Structure + motion co-design (issue 12, item 7, beyond seed 003): link lengths of the thesis's
chapter-4 two-link transfer arm (seed 000) chosen to minimise the family-optimum QMT motion time of
chapter 4's task under the same moment and motor-torque limits.

Arm family: the chapter-4 arm (models/generate_urdf.py ARMS["two_link_ch4"], Table 4.1) with link i
scaled by s_i = l_i / l_i,thesis at constant cross-section and density: length, centre-of-mass
distance x s_i, mass x s_i, inertia about the centre of mass x s_i^3 (a slender link); motors,
gears and the electromagnet unchanged. For each (l1, l2) a URDF and a scenario (a copy of
thesis-ch4.yaml whose arm.urdf points at it) are written under `folder`; the inner planner is
`plan_with("optimum", scenario)`. Lengths in m, times in s.
"""

from __future__ import annotations

import copy
import importlib.util
import time
from pathlib import Path

import numpy as np
import yaml

from qmt_drake.errors import QmtInputError

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


def write_scenario(l1_m: float, l2_m: float, folder: Path) -> Path:
    """URDF + scenario for one pair of lengths; returns the scenario path."""
    from qmt_drake.plan import write_text_atomic
    folder = Path(folder)
    name = f"two_link_ch4_l1_{l1_m * 1e3:.0f}mm_l2_{l2_m * 1e3:.0f}mm"
    urdf = folder / f"{name}.urdf"
    write_text_atomic(urdf, _arms().make_urdf(name, scaled_spec(l1_m, l2_m)))
    sc = yaml.safe_load((ROOT / "models" / "scenarios" / "thesis-ch4.yaml").read_text())
    sc["name"] = f"codesign-{name}"
    sc["arm"]["urdf"] = str(urdf.resolve())
    sc.pop("reported", None)
    path = folder / f"{name}.yaml"
    write_text_atomic(path, yaml.safe_dump(sc, sort_keys=False))
    return path


def evaluate_lengths(l1_m: float, l2_m: float, folder: Path) -> dict:
    """Family-optimum motion time of the chapter-4 task for one pair of lengths (inf if the task
    is out of reach or no plan meets the limits)."""
    from qmt_drake.planners import plan_with
    from qmt_drake.config.scenario import load_scenario
    t0 = time.perf_counter()
    path = write_scenario(l1_m, l2_m, folder)
    try:
        sc = load_scenario(path)
        plan = plan_with("optimum", sc)
        T = float(plan.motion_time_s) if plan.feasible else float("inf")
        genes = np.asarray(plan.genes).tolist()
        feas = bool(plan.feasible)
    except QmtInputError as e:   # e.g. a via point out of reach
        T, genes, feas = float("inf"), None, False
        return {"l1_m": l1_m, "l2_m": l2_m, "motion_time_s": T, "feasible": feas, "genes": genes,
                "scenario": str(path), "error": str(e), "wall_s": time.perf_counter() - t0}
    return {"l1_m": l1_m, "l2_m": l2_m, "motion_time_s": T, "feasible": feas, "genes": genes,
            "scenario": str(path), "wall_s": time.perf_counter() - t0}


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
