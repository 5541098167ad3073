"""Benchmark: a quick chapter-3 run writes the JSON, the Markdown table and readable figures; its
rows come from the re-check (the straight-line TOPP-RA row meets 2*sqrt(L/A), the fastest row has
ratio 1); the co-simulation is called per row and guarded (a failing or missing co-simulation gives
nulls and a note, not a crash)."""

import json

import numpy as np
import pytest

import qmt_drake.apps.benchmark
import qmt_drake.sim
from qmt_drake.apps.benchmark import (
    closed_form_bound_s,
    cosim_outcome,
    reusable_fastest_carried,
    run_benchmark,
)
from qmt_drake.planners.baselines.toppra_plan import plan_toppra
from qmt_drake.sweep import robust
from qmt_drake.transfer_scenario import load_scenario


def test_quick_benchmark_ch3(tmp_path, monkeypatch):
    calls = []

    def fake_simulate(scenario, plan, time_scale=1.0, record_path=None):
        calls.append(plan.method)
        if plan.method == "ruckig":
            raise RuntimeError("boom")
        return {"held": True, "max_slip_m": 1e-4, "sim_wall_s": 0.0}

    monkeypatch.setattr(qmt_drake.apps.benchmark, "run_simulate", fake_simulate)
    carried_steps = []

    def fake_carried(scenario, plan, *, time_scale=1.0, feedforward="full", time_step_s=None):
        # carried iff the motion lasts >= 1.70 s (bang-bang 1.674 s), at every step
        carried_steps.append(time_step_s)
        return {"held": plan.motion_time_s * time_scale >= 1.70, "max_slip_m": 2e-4, "detached_at_s": None}
    monkeypatch.setattr(robust, "carried_in_cosim", fake_carried)
    from matplotlib.figure import Figure
    saved = []
    real_savefig = Figure.savefig

    def keep(fig, path, *a, **k):
        saved.append((str(path), fig))
        return real_savefig(fig, path, *a, **k)
    monkeypatch.setattr(Figure, "savefig", keep)
    res = run_benchmark(scenarios=("thesis-ch3",), out_dir=tmp_path, quick=True, progress=None)
    moments = sorted(tmp_path.glob("benchmark_thesis-ch3_moment_*.png"))
    assert len(moments) >= 3  # one readable figure per planner group, not one mosaic
    for path, fig in saved:  # every panel: labelled axes with units, at most 6 panels a figure
        shown = [ax for ax in fig.axes if ax.get_visible() and ax.get_xlabel() != "" or ax.get_ylabel() != ""]
        assert shown, path
        for ax in [a for a in fig.axes if a.get_visible() and (a.lines or a.patches)]:
            assert "[" in ax.get_xlabel() and ax.get_ylabel(), (path, ax.get_title())
            if not ax.patches:  # a curve over time: its value has a unit too (bars are named planners)
                assert "[" in ax.get_ylabel(), (path, ax.get_title())
        assert sum(1 for a in fig.axes if a.get_visible() and a.lines) <= 6, path
    for f in ("benchmark.json", "benchmark.md", moments[0].name, "benchmark_times.png"):
        assert (tmp_path / f).is_file()
        if f.endswith(".png"):
            assert (tmp_path / f).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    data = json.loads((tmp_path / "benchmark.json").read_text())
    rows = data["scenarios"]["thesis-ch3"]["rows"]
    labels = [r["label"] for r in rows]
    for want in ("thesis reported", "GA (seed 0)", "family optimum", "TOPP-RA family",
                 "TOPP-RA ga_path", "TOPP-RA joint_line", "TOPP-RA cartesian_line",
                 "Drake Toppra family (inscribed box)", "trajopt (free path)"):
        assert want in labels
    assert any(lb.startswith("Ruckig line") for lb in labels)
    by = {r["label"]: r for r in rows}
    sc = load_scenario("thesis-ch3")
    line = by["TOPP-RA cartesian_line"]
    assert line["motion_time_s"] == pytest.approx(closed_form_bound_s(sc), rel=1e-3)
    feasible = [r for r in rows if r["feasible"]]
    assert min(r["ratio_to_fastest"] for r in feasible) == pytest.approx(1.0)
    assert all(r["motion_time_s"] >= closed_form_bound_s(sc) * (1 - 1e-3) for r in feasible)
    for r in rows:
        assert r["peak_moment_ratio"] is not None and r["peak_motor_torque_ratio"] is not None
        if r["feasible"]:
            assert max(r["peak_moment_ratio"], r["peak_motor_torque_ratio"]) <= 1.0
        if r["label"].startswith("fastest carried"):
            continue
        if r["method"] == "ruckig":
            assert r["held"] is None and "failed" in r["cosim_note"]
        else:
            assert r["held"] is True
    assert len(calls) == len(rows) - 1  # the carried row is simulated by its own search
    # the fastest carried row: a feasible Ruckig line just above the rule's 1.70 s, converged at 2 ms
    fc = [r for r in rows if r["label"].startswith("fastest carried")]
    assert len(fc) == 1 and fc[0]["held"] is True and fc[0]["feasible"]
    assert 1.70 <= fc[0]["motion_time_s"] <= 1.70 * 1.01 + 1e-9
    assert fc[0]["feedforward"] == "full" and fc[0]["cosim_time_step_s"] == 2e-3 and fc[0]["step_converged"]
    assert fc[0]["excess_over_bang_bang"] == pytest.approx(fc[0]["motion_time_s"] / closed_form_bound_s(sc) - 1)
    assert set(carried_steps) == {2e-3, 1e-3}
    plan, again = reusable_fastest_carried(tmp_path / "fastest_carried_thesis-ch3.json", sc)
    assert plan.motion_time_s == pytest.approx(fc[0]["motion_time_s"], rel=1e-9) and again["held"] is True
    assert reusable_fastest_carried(tmp_path / "missing.json", sc) is None
    summary = data["scenarios"]["thesis-ch3"]["fastest_carried"]
    assert summary["motion_time_s"] == fc[0]["motion_time_s"] and summary["carried_wall_s"] > 0
    assert data["settings"]["fastest_carried_wall_s"] == pytest.approx(summary["carried_wall_s"])
    ratios = data["scenarios"]["thesis-ch3"]["ratios"]
    assert "GA / TOPP-RA ga_path: motion time" in ratios
    md = (tmp_path / "benchmark.md").read_text()
    assert "| TOPP-RA cartesian_line | yes |" in md
    assert "co-simulation failed" in md
    assert "**Fastest carried**" in md and "over the bang-bang bound" in md
    assert "2 ms: " in md and "at 1 ms carried" in md  # the step-convergence clause
    assert "| fastest carried (Ruckig line" in md
    assert res["scenarios"]["thesis-ch3"]["closed_form_bound_s"] == pytest.approx(
        closed_form_bound_s(sc))


def test_a_failed_cosimulation_is_a_note(monkeypatch):
    sc = load_scenario("thesis-ch3")
    plan = plan_toppra(sc, path="joint_line", measure_polygon_cost=False)

    def broken(*a, **k):
        raise RuntimeError("solver failed")
    monkeypatch.setattr(qmt_drake.apps.benchmark, "run_simulate", broken)
    out = cosim_outcome(sc, plan)
    assert out["held"] is None and "solver failed" in out["cosim_note"]


def test_closed_form_bound():
    sc = load_scenario("thesis-ch2")
    A = sc.limits.moment_limit_Nm / sc.moment_per_accel_kgm
    assert closed_form_bound_s(sc) == pytest.approx(2 * np.sqrt(0.2 / A))
    assert closed_form_bound_s(load_scenario("thesis-ch4")) is None


def test_fastest_carried_with_vias_time_scales_the_fastest_limit_keeping_candidate(monkeypatch):
    """ch.4 has via points (no Ruckig line): the search time-scales the fastest candidate that keeps
    every limit (the raw TOPP-RA spline, faster but over the limit, is skipped)."""
    from qmt_drake.apps.benchmark import fastest_carried
    from qmt_drake.planners import plan_with
    sc = load_scenario("thesis-ch4")
    thesis = plan_with("thesis", sc)
    family = plan_toppra(sc, path="family", measure_polygon_cost=False)
    raw = plan_toppra(sc, path="family", parametrizer="ParametrizeSpline", slow_to_limits=False,
                      measure_polygon_cost=False)
    assert not raw.feasible and family.feasible and family.motion_time_s < thesis.motion_time_s

    def fake_carried(scenario, plan, *, time_scale=1.0, feedforward="full", time_step_s=None):
        return {"held": plan.motion_time_s * time_scale >= 1.6, "max_slip_m": 2e-4, "detached_at_s": None}
    monkeypatch.setattr(robust, "carried_in_cosim", fake_carried)
    plan, row = fastest_carried(sc, candidates=[("thesis", thesis), ("family", family), ("raw", raw)])
    assert row["label"].startswith("fastest carried (family time-scaled") and row["held"] is True
    assert 1.6 <= plan.motion_time_s <= 1.6 * 1.002 + 1e-9 and plan.feasible
    assert row["bang_bang_s"] is None and row["search_variable"] == "time_scale"
