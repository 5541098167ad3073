"""The report's spatial section: figures drawn from the spatial benchmark's JSON (the hand's ratio over
time per method, the motion times against the bound, the clearance when there are obstacles), shown
inline in the report; the series the benchmark stores keep every plan's peak."""

import json

import numpy as np
import pytest

from qmt_drake.apps.report import SECTIONS, build_report
from qmt_drake.apps.spatial_figures import MAX_POINTS, main, plan_series, thin_max, write_spatial_figures
from qmt_drake.planners.spatial_methods import plan_toppra_spatial
from qmt_drake.planners.spatial_trajectory import check
from qmt_drake.spatial_task import load_spatial_scenario

PNG = b"\x89PNG\r\n\x1a\n"


def _row(m, T, held=True, recheck=0.99, clearance=False):
    t = np.linspace(0.0, T, 50)
    s = {"t_s": t.tolist(), "hand_ratio": (0.9 * np.sin(np.pi * t / T) ** 2).tolist(),
         "timed_t_s": t.tolist(), "max_timed_ratio": np.full(50, recheck).tolist()}
    if clearance:
        s |= {"clearance_t_s": t.tolist(), "clearance_m": np.minimum(0.1, 0.12 - 0.11 * np.sin(np.pi * t / T)).tolist(),
              "clearance_horizon_m": 0.1}
    return {"method": m, "duration_s": T, "ratio_to_bound": T / 1.0, "recheck_max_ratio": recheck,
            "cosim": {"outcome": "carried" if held else "detached", "held": held}, "series": s}


def _fake(clearance: bool) -> dict:
    rows = {"toppra": _row("toppra", 1.0, clearance=clearance), "ruckig": _row("ruckig", 1.3, clearance=clearance),
            "ga": _row("ga", 1.1, recheck=1.02, clearance=clearance),
            "toppra_x0.67": _row("toppra_x0.67", 0.67, held=False, recheck=2.2, clearance=clearance),
            "toppra-trapezoid_ptp": _row("toppra-trapezoid_ptp", 1.6, clearance=clearance)}
    rows["toppra_carried"] = {"method": "toppra_carried", "duration_s": float("nan"), "cosim": {"held": False}}
    return {"scenario": "fake-arm", "hand_kind": "suction", "bound_s": 1.0, "rows": rows}


@pytest.mark.parametrize("clearance", [True, False])
def test_figures_from_a_small_benchmark_json(tmp_path, clearance):
    files = write_spatial_figures(_fake(clearance), tmp_path)
    names = sorted(f.name for f in files)
    want = ["fake-arm-hand_ratio.png", "fake-arm-times.png"] + (["fake-arm-clearance.png"] if clearance else [])
    assert names == sorted(want)
    for f in files:
        assert f.read_bytes()[:8] == PNG and f.stat().st_size > 10_000  # a drawn figure, not an empty canvas


def test_report_shows_the_spatial_figures_and_names_the_arms(tmp_path):
    spatial = next(s for s in SECTIONS if s.folder == "spatial")
    (tmp_path / "spatial").mkdir()
    res = _fake(True)
    (tmp_path / "spatial" / "fake-arm.json").write_text(json.dumps(res))
    (tmp_path / "spatial" / "fake-arm.md").write_text("| method | time s |\n|---|---|\n| toppra | 1.0 |\n")
    assert main([str(tmp_path / "spatial" / "fake-arm.json")]) == 0  # redrawn from the saved JSON
    html = build_report(tmp_path, [spatial]).read_text()
    for f in ("hand_ratio", "times", "clearance"):
        assert f"src='spatial/fake-arm-{f}.png'" in html
    assert "issue 19" not in html and "UR5" in html and "Panda" in html


def test_thinning_keeps_the_peak():
    t = np.linspace(0.0, 1.0, 10_001)
    v = np.sin(7 * t) ** 2
    v[4321] = 3.0
    tt, vv = thin_max(t, v)
    assert len(tt) == MAX_POINTS and vv.max() == 3.0 and tt[np.argmax(vv)] == t[4321]
    assert np.all(np.diff(tt) > 0)


def test_plan_series_agrees_with_the_recheck():
    sc = load_spatial_scenario("ur5-suction-bins")
    p = plan_toppra_spatial(sc, n_grid=200)
    s = plan_series(sc, p.trajectory, sc.recheck_rate_hz)
    r = check(sc, p.trajectory, sc.recheck_rate_hz)  # the re-check's own maxima, same samples
    assert len(s["t_s"]) == MAX_POINTS and 0.0 <= s["t_s"][0] < s["t_s"][-1] <= p.trajectory.duration_s
    assert max(s["hand_ratio"]) == pytest.approx(r[sc.hand_term().name], rel=1e-12)
    assert max(s["max_timed_ratio"]) == pytest.approx(r["max_timed"], rel=1e-12)
