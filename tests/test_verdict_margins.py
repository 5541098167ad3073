"""The verdict study (studies/verdict_margins.py) and the contact hand's margin (margin_runs.spatial_margin).

The contact hand's margin is its own loss rule (gap 5 mm, slide 10 mm, final slide 5 mm), checked on real
runs: the UR5 cup holding its part at rest (pull 1.05 m g) and dropping it (0.95 m g), under Drake's TAMSI
as well (the contact hand has no weld constraint). The study's store resumes without re-running, and its
contact search finds the flip of a known monotone verdict.
"""

import dataclasses
import json

import pytest

from qmt_drake.limits.suction import GripModel
from qmt_drake.margin_runs import spatial_margin, spatial_plant_options
from qmt_drake.sim.spatial_contact_hand import CONTACT_HAND_REVISION, LOST_GAP_M
from qmt_drake.sim.spatial_cosim import simulate_spatial
from studies.verdict_margins import TOL, Store, _cell, contact_fastest, key, reusable
from studies.verdict_margins_table import fmt
from tests.spatial_fixtures import load_or_skip
from tests.test_margin import check_consistent
from tests.test_spatial_contact_hand import Motion


@pytest.fixture(scope="module")
def cup():
    sc = dataclasses.replace(load_or_skip("ur5-suction-bins"), hand_physics="contact")
    w = sc.body.mass_kg * 9.81
    return sc, {f: GripModel(sc.grip.radius_m, f * w, sc.grip.friction, face_normal=sc.grip.basis[2], rim_points=24)
                for f in (1.05, 0.95)}


@pytest.mark.parametrize("approximation", [None, "tamsi"])
def test_contact_margin_is_the_loss_rule(cup, approximation):
    sc, grips = cup
    rest = Motion(sc.q_path_rad[0], 0.2)
    held = simulate_spatial(sc, rest, grip=grips[1.05], **spatial_plant_options(None, approximation))
    held["margin"] = spatial_margin(sc, held)
    check_consistent(held)
    assert held["outcome"] == "carried"
    names = [c["quantity"] for c in held["margin"]["criteria"]]
    assert names == ["max_gap_m", "max_slide_m", "final_slide_on_face_m", "final_goal_error_rad"]
    assert held["margin"]["criteria"][0]["value"] == held["max_gap_m"]
    dropped = simulate_spatial(sc, rest, grip=grips[0.95], **spatial_plant_options(None, approximation))
    dropped["margin"] = spatial_margin(sc, dropped)
    check_consistent(dropped)  # detached: its deciding quantity at or above its threshold
    assert dropped["outcome"] == "detached" and dropped["margin"]["quantity"] == "max_gap_m"
    assert dropped["max_gap_m"] > LOST_GAP_M > dropped["max_gap_while_held_m"]
    assert fmt(_cell(dropped)).startswith("detached at ") and "while held" in fmt(_cell(dropped))
    assert fmt(_cell(held)).startswith("carried, ") and " mm (" in fmt(_cell(held)) and "arrival" in fmt(_cell(held))


def test_store_resumes_without_running_again(tmp_path):
    path, calls = tmp_path / "v.json", []
    store = Store(path)
    assert store.memo("a|1.0", lambda: calls.append(1) or {"held": True}) == {"held": True}
    assert json.loads(path.read_text())["_runs"]["a|1.0"] == {"held": True}  # written at once
    again = Store(path)
    assert again.memo("a|1.0", lambda: calls.append(2) or {"held": False}) == {"held": True} and calls == [1]


@pytest.mark.parametrize("edge, s_weld", [(1.137, 1.05), (1.03, 1.1), (0.9, 1.0), (1.01, 1.0)])
def test_contact_search_brackets_the_flip(edge, s_weld):
    seen = []

    def run(s, h, a):  # carried from `edge` on, at the contact hand's default cell only
        assert (h, a) == (1e-3, "lagged")
        seen.append(s)
        return {"held": s >= edge, "outcome": "carried" if s >= edge else "detached"}

    found = contact_fastest(run, s_weld)
    if edge <= 1.0:
        assert found["chosen"] == 1.0 and found["lost_below"] is None and seen == [1.0]
        return
    assert found["lost_below"] < edge <= found["chosen"] <= found["lost_below"] * (1 + TOL)
    assert seen[0] == s_weld and found["tries"][-1]["time_scale"] == seen[-1]


def test_contact_runs_are_keyed_by_the_contact_hand_revision():
    assert key("tray") == "tray" and key("ur5-suction") == "ur5-suction"  # stored tray and weld runs stay valid
    assert key("ur5-suction-contact") == f"ur5-suction-contact|r{CONTACT_HAND_REVISION}"
    assert reusable("ur5-magnet", {}) and not reusable("ur5-magnet-contact", {})  # a row of the old contact hand
    assert reusable("ur5-magnet-contact", {"contact_hand_revision": CONTACT_HAND_REVISION})
