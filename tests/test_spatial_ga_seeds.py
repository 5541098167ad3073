"""studies/spatial_ga_seeds.py (issue 19's GA check) on a small budget: two seeds, 40 generations of 20.
The full check (10 seeds, 150 generations of 40, minutes) is the study itself; here: the GA with tight
timing within 0.5 % already at this budget, what must hold at any budget, and that the study's numbers
are the ones it reports."""

import json

import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.spatial_task import load_spatial_scenario
from studies import spatial_ga_seeds

# The family optimum's own accuracy: Nelder-Mead on the closed-form tight time from one start and from
# two agree to 1e-8 (2.349849 s on ur5-suction-bins); the GA's plan and the optimum are each held at
# the re-check rate by their own factor (1 + 7e-5 here), so a GA plan may come out a hair below it;
# 1e-3 is far above both and far below the 0.5 % the check is about.
OPTIMUM_TOL = 1e-3
GENERATIONS, POPULATION = 40, 20  # ~700 candidates per seed: +0.02 and +0.002 % on seeds 0 and 1


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    try:
        load_spatial_scenario("ur5-suction-bins")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    out = tmp_path_factory.mktemp("ga_seeds")
    rc = spatial_ga_seeds.main(["--seeds", "0", "1", "--generations", str(GENERATIONS), "--population", str(POPULATION),
                                "--restarts", "1", "--out", str(out)])
    assert rc == 0
    return json.loads((out / "spatial" / "ga_seeds.json").read_text())


def test_no_seed_beats_the_family_optimum_and_every_plan_holds(result):
    assert [r["seed"] for r in result["rows"]] == [0, 1]
    for r in result["rows"]:
        assert r["T_ga_s"] >= result["T_opt_s"] * (1 - OPTIMUM_TOL)  # else the optimum is not one
        assert r["recheck_max_ratio"] <= 1.0 and result["optimum_recheck_max_ratio"] <= 1.0
        assert r["generations"] <= GENERATIONS and r["evaluations"] <= GENERATIONS * POPULATION


def test_the_tight_timing_ga_lands_within_half_a_percent_at_a_small_budget(result):
    assert result["tight_timing"] and result["must_show_met"]
    assert all(r["within"] and r["hold_scale"] < 1.001 for r in result["rows"])


def test_the_reported_gap_and_count_are_the_measured_ones(result):
    for r in result["rows"]:
        assert r["gap"] == pytest.approx(r["T_ga_s"] / result["T_opt_s"] - 1, rel=1e-12)
        assert r["within"] == (abs(r["gap"]) <= spatial_ga_seeds.WITHIN)
    assert result["within_0.5pct"] == sum(r["within"] for r in result["rows"])
    assert result["must_show_met"] == (result["within_0.5pct"] >= 0.9 * len(result["rows"]))
    assert f"for {result['within_0.5pct']} of 2 seeds" in spatial_ga_seeds.table(result)


def test_bad_arguments_are_one_line(tmp_path, capsys):
    assert spatial_ga_seeds.main(["--generations", "0", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1
