"""The one planner registry (qmt_drake/planners/registry.py): every method of every scenario kind is a
row reached through registry.plan; the CLI and the API give the same plan for the same arguments; a
method a kind does not plan, an unknown option and a bad value are refused in one line (exit 2)."""

import importlib
import json

import pytest

from qmt_drake.api import load_scenario, plan_with
from qmt_drake.apps.cli import main
from qmt_drake.errors import QmtInputError
from qmt_drake.outputs import jsonable
from qmt_drake.planners import registry

SCENARIOS = {registry.TRANSFER: "thesis-ch4", registry.SPATIAL: "ur5-magnet-part", registry.ENERGY: "ohsaka-fig3"}


@pytest.fixture(scope="module")
def scenarios():
    return {kind: load_scenario(name) for kind, name in SCENARIOS.items()}


def _main(capsys, *argv):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def test_one_table_plans_every_kind():
    rows = registry.rows()
    assert {m.kind for m in rows} == set(registry.KINDS)
    assert len({(m.kind, m.name) for m in rows}) == len(rows)  # a method once per kind
    assert registry.names(registry.TRANSFER) == ("ga", "optimum", "thesis", "toppra", "toppra-drake", "ruckig", "trajopt",
                                                 "snopt", "ipopt", "steepest", "collocation")
    assert registry.names(registry.SPATIAL) == ("toppra", "ruckig", "family_optimum", "ga", "trajopt", "toppra-drake",
                                                "snopt", "ipopt", "steepest", "collocation")
    assert registry.names(registry.ENERGY) == ("snopt", "ipopt", "steepest", "collocation", "toppra", "toppra-drake",
                                               "ruckig", "trajopt", "family_optimum", "ga")


def test_every_method_of_every_kind_is_reached_by_plan(scenarios, monkeypatch):
    """Each row's own function is what registry.plan calls (by its name and each alias), with the
    plan()'s arguments the row says it takes and nothing else."""
    for row in registry.rows():
        module, _, name = row.run.partition(":")
        calls = []

        def stub(scenario, calls=calls, row=row, **kw):
            calls.append((scenario, kw))
            return ("planned", row.kind, row.name)

        with monkeypatch.context() as m:
            m.setattr(importlib.import_module(module), name, stub)
            for word in (row.name, *row.aliases):
                got = registry.plan(scenarios[row.kind], word, seed=3, progress=print)
                assert got == ("planned", row.kind, row.name), (row.kind, word)
        assert all(sc is scenarios[row.kind] for sc, _ in calls)
        own = {"seed": 3, "progress": print, "method": row.name}
        assert all(kw == {k: own[k] for k in row.passes} for _, kw in calls), (row.kind, row.name, calls)


def test_options_are_typed_from_the_signatures():
    ga = registry.find(registry.SPATIAL, "ga").options()
    assert ga["generations"] == {"type": "int", "default": 150, "range": (1, 10 ** 9)}
    assert ga["checkpoint_path"]["default"] is None and ga["family"]["default"] == "via_cubic"
    assert "max_generations" in registry.find(registry.TRANSFER, "ga").options()
    assert set(registry.find(registry.ENERGY, "snopt").options()) >= {"c1", "c2", "m", "divisions", "pattern"}
    assert registry.find(registry.SPATIAL, "optimum").name == "family_optimum"
    assert registry.find(registry.TRANSFER, "family_optimum").name == "optimum"


@pytest.mark.parametrize("kind", registry.KINDS)
def test_a_method_of_another_kind_is_refused_naming_this_kinds_methods(scenarios, kind):
    for other in sorted({m.name for m in registry.rows()} - set(registry.names(kind))
                        - {a for m in registry.rows(kind) for a in m.aliases}):
        with pytest.raises(QmtInputError) as e:
            plan_with(other, scenarios[kind])
        msg = str(e.value)
        assert "\n" not in msg and f"take {'|'.join(registry.names(kind))}" in msg, msg


@pytest.mark.parametrize("call, needle", [
    (lambda s: plan_with("ga", s[registry.SPATIAL], bogus=1), "plan_with option bogus: not an option of the spatial (3-D) ga"),
    (lambda s: plan_with("ga", s[registry.TRANSFER], generations=2.5), "generations 2.5 must be an integer"),
    (lambda s: plan_with("ga", s[registry.TRANSFER], population=8), "population is the scenario's ga.population"),
    (lambda s: plan_with("toppra", s[registry.SPATIAL], c1=1.0), "(the planners that take it: planar snopt, ipopt, steepest and "
                                                               "collocation; spatial (3-D) snopt, ipopt, steepest and collocation; "
                                                               "energy-time snopt, ipopt, steepest and collocation)"),
    (lambda s: plan_with("nope", s[registry.ENERGY]), "'nope' is unknown"),
    (lambda s: registry.plan(s[registry.SPATIAL], "toppra", seed=-1), "seed -1 must be >= 0"),
])
def test_api_refusals_are_one_line(scenarios, call, needle):
    with pytest.raises(QmtInputError) as e:
        call(scenarios)
    assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)


@pytest.mark.parametrize("argv, needle", [
    (["plan", "thesis-ch4", "--option", "bogus=1"], "--option bogus: not an option of the planar ga planner"),
    (["plan", "ohsaka-fig3", "--method", "thesis"], "--method thesis plans planar (kind: transfer) scenarios, not "
                                                    "energy-time ones; energy-time scenarios take snopt|"),
    (["plan", "ohsaka-fig3", "--generations", "3"], "--generations: not an option of the energy-time snopt planner"),
    (["plan", "thesis-ch4", "--c1", "2"], "--c1: not an option of the planar ga planner (the planners that take it: planar snopt"),
    (["plan", "ur5-magnet-part", "--method", "toppra", "--seed", "2"], "--seed: the spatial transfer toppra planner "
                                                                      "draws no random numbers"),
    (["plan", "ur5-magnet-part", "--method", "ga", "--option", "generations=0"], "--option generations 0 must be >= 1"),
    (["plan", "ohsaka-fig3", "--carried"], "--carried: the energy-time arm (seed 001) carries no payload"),
])
def test_cli_refusals_are_one_line_exit_2(capsys, argv, needle):
    rc, _, err = _main(capsys, *argv)
    assert rc == 2 and needle in err and err.count("\n") == 1, err


_TIMES = {"planner_wall_s", "planning_s", "wall_s", "toppra_solve_s", "plan_wall_s", "search_wall_s"}


def _untimed(d):
    """A plan document without its wall-clock times (the only numbers two runs may not share)."""
    if isinstance(d, dict):
        return {k: _untimed(v) for k, v in d.items() if k not in _TIMES}
    if isinstance(d, list):
        return [_untimed(v) for v in d]
    return d


@pytest.mark.parametrize("kind, method, flags, options", [
    (registry.TRANSFER, "thesis", [], {}),
    (registry.TRANSFER, "ruckig", ["--option", "jerk_limit=20"], {"jerk_limit": 20}),
    (registry.SPATIAL, "toppra", ["--option", "n_grid=200"], {"n_grid": 200}),
    (registry.ENERGY, "snopt", ["--pattern=-+-"], {"pattern": (-1, 1, -1)}),
])
def test_cli_and_api_give_the_same_plan(capsys, tmp_path, kind, method, flags, options):
    path = tmp_path / "p.json"
    rc, _, err = _main(capsys, "plan", SCENARIOS[kind], "--method", method, *flags, "--json", path, "--quiet")
    assert rc == 0, err
    api = json.loads(json.dumps(jsonable(plan_with(method, SCENARIOS[kind], **options).to_json_dict())))
    assert _untimed(json.loads(path.read_text())) == _untimed(api)
