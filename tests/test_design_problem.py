"""Task YAML validation, the design Problem (protocol, batching, Drake re-check), the exhaustive
search as certificate on a sub-grid, the `design` CLI and its bad inputs."""

import argparse

import numpy as np
import pytest

from qmt_drake.design.arm_types import LEVEL_STEP_M
from qmt_drake.design.problem import DesignProblem
from qmt_drake.design.search import exhaustive, reduced_grid, run_ga_adapter
from qmt_drake.design.tasks import load_task, task_from_dict
from qmt_drake.errors import QmtInputError

UNIT = {"name": "P", "position_m": [0.5, 0.0, 0.0], "rpy_deg": [180, 0, 0], "work": ["x"],
        "constrained": ["z"]}


def test_task_files_load():
    for n in ("task1_welding_plate", "task2_welding_opening", "peg_in_hole"):
        t = load_task(n)
        P, R, W, C, a = t.arrays()
        np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
        assert np.all(W.sum(axis=1) > 0) and not np.any(W & C)
    t1 = load_task("task1_welding_plate")
    assert len(t1.units) == 8 and len(t1.obstacles) == 2 and len(t1.without_obstacles().obstacles) == 0


@pytest.mark.parametrize("change,match", [
    ({"work": ["w"]}, "not a unit axis"),
    ({"constrained": ["x"]}, "more than one"),
    ({"position_m": [9.0, 0, 0]}, "no design reaches"),
    ({"position_m": [0.5, 0, -0.3]}, "inside box"),
    ({"a": 1.5}, r"\[0(\.0)?, 1(\.0)?\]"),
])
def test_bad_unit_tasks(change, match):
    u = dict(UNIT, **change)
    d = {"units": [u], "work_boxes": [{"name": "table", "center_m": [0.5, 0, -0.3], "size_m": [0.4, 0.4, 0.1]}]}
    with pytest.raises(QmtInputError, match=match):
        task_from_dict(d)


def test_problem_protocol_batching_and_drake_recheck():
    task = load_task("task1_welding_plate")
    pr = DesignProblem(task, "BP")
    assert pr.lower.shape == pr.upper.shape == (len(pr.gene_names),)
    G = np.random.default_rng(0).integers(0, 16, (40, 5)) * LEVEL_STEP_M
    ev = pr.evaluate(G)
    assert ev.cost.shape == (40,) and np.all(ev.violation == 0)
    fit = pr.fitness(ev)
    assert np.all(fit >= 0) and fit.max() > 0
    # batched == one at a time (chunking, broadcasting)
    single = np.array([pr.fitness_E(g[None])[0] for g in G[:8]])
    np.testing.assert_allclose(single, fit[:8], rtol=0, atol=0)
    # the best of them re-checked independently with Drake (plant, Jacobian, SceneGraph)
    rep = pr.confirm_report(G[int(np.argmax(fit))])
    assert rep["ok"], rep
    assert all(d > 0 for d in rep["min_env_distance_m"])


def test_task_wide_branch_choice():
    """One branch label for the whole task (the seed's choice) never beats the best branch per
    point, equals it for a single unit task, uses one label at every unit, and E is the best over
    the labels of eq. 8 with the label's unreachable units counted 0."""
    from qmt_drake.design import ik
    from qmt_drake.design.operability import fitness_E
    from qmt_drake.design.problem import lengths6
    task = load_task("task1_welding_plate")
    G = np.random.default_rng(4).integers(0, 16, (80, 5)) * LEVEL_STEP_M
    for T in ("BP", "PB", "FF"):
        pt = DesignProblem(task, T, branch="task")
        pp = DesignProblem(task, T, branch="point")
        et, ep = pt.fitness_E(G), pp.fitness_E(G)
        assert np.all(et <= ep + 1e-15) and np.any(et < ep - 1e-6)
        # E by label recomputed from the per-label unit values
        mu_l, r_l, _ = pt._units(G)
        EL = np.stack([fitness_E(mu_l[..., b], r_l[..., b], lengths6(G).sum(axis=1)) for b in range(4)], 1)
        np.testing.assert_allclose(et, EL.max(axis=1), rtol=0, atol=0)
        # the chosen configurations all carry the chosen label
        g = G[int(np.argmax(et))]
        det = pt.details(g)
        qs = np.array([u["q_rad"] for u in det["units"] if u["reachable"]])
        o = pt.type.origins(lengths6(g)[0])
        assert set(ik.labels_of(pt.type, o, qs).tolist()) == {det["branch_label"]}
    one = task_from_dict({"units": [UNIT]})
    np.testing.assert_array_equal(DesignProblem(one, "BP").fitness_E(G),
                                  DesignProblem(one, "BP", branch="point").fitness_E(G))
    with pytest.raises(QmtInputError, match="branch"):
        DesignProblem(task, "BP", branch="each")


def test_obstacles_can_only_lower_E():
    task = load_task("task1_welding_plate")
    G = np.random.default_rng(1).integers(0, 16, (60, 5)) * LEVEL_STEP_M
    e_obs = DesignProblem(task, "FF").fitness_E(G)
    e_free = DesignProblem(task.without_obstacles(), "FF").fitness_E(G)
    assert np.all(e_obs <= e_free + 1e-15) and np.any(e_obs < e_free)


def test_exhaustive_certifies_on_a_subgrid():
    task = load_task("task2_welding_opening")
    pr = DesignProblem(task, "BF")
    grid = reduced_grid()
    assert grid.shape == (16 * 16 * 31 * 16, 5)
    rng = np.random.default_rng(2)
    sub = grid[rng.choice(grid.shape[0], 200, replace=False)]
    ex = exhaustive(pr, genes=sub, batch=128)
    assert ex.E_per_m == pytest.approx(pr.fitness_E(sub).max(), rel=1e-12)
    assert ex.gene_hex == ex.extra["top10"][0][0] and ex.evaluations == 200


def test_ga_adapter_runs_the_project_ga_on_the_design_problem():
    pr = DesignProblem(load_task("peg_in_hole"), "BP")
    res = run_ga_adapter(pr, max_generations=5, stall_generations=0)
    assert res.generations == 5 and res.feasible
    # The reported cost is -E of the returned genes, re-evaluated independently.
    assert -res.cost == pytest.approx(pr.fitness_E(res.genes[None])[0], rel=1e-12) and -res.cost > 0
    assert np.all(np.diff(res.history.best_cost) <= 1e-15)


def test_cli_design_and_bad_inputs(tmp_path, capsys):
    from qmt_drake.design.cli import add_parser, cmd_design
    ap = argparse.ArgumentParser()
    add_parser(ap.add_subparsers())
    args = ap.parse_args(["design", "peg_in_hole", "--types", "BP,PB", "--generations", "2,0",
                          "--workers", "1", "--out", str(tmp_path)])
    assert cmd_design(args) == 0
    assert (tmp_path / "BP.urdf").exists() and (tmp_path / "results.json").exists()
    import json
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["branch"] == "task" and {r["type"] for r in res["results"]} == {"BP", "PB"}
    # one design evaluated: the same E as the Problem gives
    assert cmd_design(ap.parse_args(["design", "peg_in_hole", "--design", "BP:0,5,1,0,0,0",
                                     "--out", str(tmp_path)])) == 0
    det = json.loads((tmp_path / "BP_051000.json").read_text())
    pr = DesignProblem(load_task("peg_in_hole"), "BP")
    assert det["E_per_m"] == pytest.approx(pr.fitness_E(np.array([[0, .5, .1, 0, 0]]))[0], rel=1e-12)
    for bad, match in ((["--types", "XX"], "unknown"), (["--types", "FB"], "not among")):
        args = ap.parse_args(["design", "peg_in_hole", "--out", str(tmp_path)] + bad)
        with pytest.raises(QmtInputError, match=match):
            cmd_design(args)
    with pytest.raises(QmtInputError, match="not found"):
        cmd_design(ap.parse_args(["design", "no_such_task"]))


def test_ga_restarts_keep_the_best_run():
    from qmt_drake.design.search import search_type
    task = load_task("peg_in_hole")
    r = search_type(task, "PB", "ga", seed=3, ga_generations=(3, 0), restarts=2)
    runs = r.extra["restarts"]
    assert [x["seed"] for x in runs] == [3, 4]
    assert r.E_per_m == max(x["E_per_m"] for x in runs)
    single = search_type(task, "PB", "ga", seed=4, ga_generations=(3, 0))
    assert single.E_per_m == runs[1]["E_per_m"]     # seeded: a restart is the same run
