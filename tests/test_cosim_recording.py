"""Headless Meshcat recording: one self-contained HTML file with the animated arm and payload."""

import base64
import re

from qmt_drake.sim import GenesPlan, simulate_transfer
from qmt_drake.sim.recording import make_headless_meshcat
from qmt_drake.config.scenario import load_scenario


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
