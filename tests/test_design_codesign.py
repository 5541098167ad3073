"""Co-design arm family: at the thesis lengths the generated URDF is the committed ch.4 arm; scaled
links follow the uniform-density rule; a scenario written for new lengths loads."""

import re
from pathlib import Path

import numpy as np

from qmt_drake.design.codesign import ROOT, _arms, scaled_spec, write_scenario


def _body(text):
    # drop comment lines and the robot name, which name the source
    text = re.sub(r"<!--.*?-->", "", text)
    return re.sub(r'<robot name="[^"]*"', "<robot", text)


def test_thesis_lengths_reproduce_the_committed_urdf():
    gen = _arms().make_urdf("two_link_ch4", scaled_spec(0.160, 0.120))
    committed = (ROOT / "models" / "two_link_ch4.urdf").read_text()
    assert _body(gen) == _body(committed)


def test_scaling_rule_and_scenario(tmp_path):
    s = scaled_spec(0.20, 0.06)
    np.testing.assert_allclose(s["mass_kg"], [0.547 * 0.2 / 0.16, 0.146 * 0.06 / 0.12])
    np.testing.assert_allclose(s["izz_about_com_kgm2"], [2.440e-3 * (0.2 / 0.16) ** 3, 0.361e-3 * 0.5 ** 3])
    from qmt_drake.transfer_scenario import load_scenario
    p = write_scenario(0.18, 0.10, tmp_path)
    sc = load_scenario(p)
    assert Path(sc.urdf_path).name.startswith("two_link_ch4_l1_180mm_l2_100mm")


def test_base_shift_moves_the_task_points_not_the_world(tmp_path):
    import yaml

    from qmt_drake.transfer_scenario import load_scenario
    world = yaml.safe_load((ROOT / "models" / "scenarios" / "thesis-ch4.yaml").read_text())["task"]["points_m"]
    p = write_scenario(0.16, 0.12, tmp_path, base_m=(0.03, -0.02))
    pts = yaml.safe_load(p.read_text())["task"]["points_m"]
    np.testing.assert_allclose(np.array(pts) + [0.03, -0.02], world, atol=1e-12)
    load_scenario(p)    # still reachable: loads
    # a base far off leaves the start point out of reach: the scenario loader says so
    from qmt_drake.design.codesign import evaluate_lengths
    r = evaluate_lengths(0.16, 0.12, tmp_path, base_m=(0.10, -0.10))
    assert r["motion_time_s"] == float("inf") and "unreachable" in r["error"]


def test_pattern_search_finds_the_grid_minimum_within_bounds(tmp_path):
    """On a known objective (quadratic bowl with its minimum at a 1 mm grid point inside the bounds,
    and an infeasible region) the compass search reaches that minimum; calls are cached."""
    from qmt_drake.design.codesign import pattern_search
    target = np.array([0.183, 0.097, -0.021, 0.034])
    calls = []

    def fake(l1, l2, folder, base):
        x = np.array([l1, l2, *base])
        calls.append(tuple(np.round(x * 1e3)))
        T = 1.0 + float(np.sum((x - target) ** 2)) if l1 + l2 >= 0.22 else float("inf")
        return {"l1_m": l1, "l2_m": l2, "base_m": list(base), "motion_time_s": T}

    res = pattern_search([0.16, 0.12, 0.0, 0.0], tmp_path, step_m=0.016, min_step_m=0.001,
                         max_evaluations=500, evaluate=fake)
    np.testing.assert_allclose(res["x_best"], target, atol=1.01e-3)
    assert len(calls) == len(set(calls)) == res["evaluations"]
