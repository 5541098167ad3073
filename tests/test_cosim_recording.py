"""Headless Meshcat recording: one self-contained HTML file with the animated arm and payload."""

import base64
import re

import pytest

from qmt_drake.recording import make_headless_meshcat
from qmt_drake.sim import GenesPlan, build_transfer_diagram, run_diagram, simulate_transfer
from qmt_drake.transfer_scenario import load_scenario


def _embedded_bytes(html: str) -> bytes:
    return b"".join(base64.b64decode(b) for b in re.findall(r"base64,([A-Za-z0-9+/=]{200,})", html))


def test_recording_writes_self_contained_html(tmp_path):
    sc = load_scenario("thesis-ch4")
    plan = GenesPlan(sc, (0.622, 0.532, 0.562))
    path = tmp_path / "transfer.html"
    r = simulate_transfer(sc, plan, record_path=path, keep_series=False)
    html = path.read_text()
    assert r.held
    assert html.lstrip().lower().startswith("<!doctype html")
    empty = make_headless_meshcat().StaticHtml()
    assert len(html) > len(empty) + 30_000  # the scene and its animation are inlined
    data = _embedded_bytes(html)
    # The inlined scene names the arm links and the payload, and carries an animation.
    assert b"link2" in data and b"payload" in data and b"animation" in data
    assert b"floor_visual" in data  # a lost part lands on the floor


def test_camera_frames_the_arm_from_its_reach_and_a_lost_part_stops_on_the_floor(tmp_path):
    import numpy as np
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
    from pydrake.systems.framework import DiagramBuilder

    from qmt_drake.recording import add_floor, arm_reach_m
    from qmt_drake.sim.plant import add_arm

    sc = load_scenario("thesis-ch4")
    p, _ = AddMultibodyPlantSceneGraph(DiagramBuilder(), 0.0)
    arm = add_arm(p, sc.urdf_path)
    # link 1 0.16 m, link 2 to the hand 0.12 m and 0.035 m down: 0.16 + hypot(0.12, 0.035), + 0.1 m margin
    assert arm_reach_m(p, arm) == pytest.approx(0.16 + float(np.hypot(0.12, 0.035)) + 0.1, rel=1e-12)
    floor_z = add_floor(p, arm)
    assert floor_z == -arm_reach_m(p, arm)
    # a transfer that loses its part (0.6x the thesis timing): the part ends on the floor, not 14 m down
    plan = GenesPlan(sc, (0.622, 0.532, 0.562))
    td = build_transfer_diagram(sc, plan, time_scale=0.6, meshcat=make_headless_meshcat())
    run_diagram(td)
    ctx = td.plant.GetMyContextFromRoot(td.simulator.get_context())
    z_part = td.payload_body.EvalPoseInWorld(ctx).translation()[2]
    assert floor_z - 0.01 < z_part < floor_z + 0.05
