"""One TOPP-RA (planners/toppra_core.py): every caller goes through `parameterise`, and what it returns
is toppra's own TOPPRA result bit for bit on each caller's problem (the planar baseline, the spatial
arms, seed 002's tray line, seed 001's time-optimal end of the front)."""

import ast
from pathlib import Path

import numpy as np
import pytest

import qmt_drake.planners.toppra_core as core
from qmt_drake.limits.toppra_form import rows_constraint

PACKAGE = Path(core.__file__).resolve().parents[1]
# the calls that solve a TOPP-RA problem, and the one module allowed to make each
SOLVERS = {"TOPPRA": set(), "compute_trajectory": set(), "compute_parameterization": set(),
           "seidel_parameterization": {"planners/toppra_core.py"}}
CALLERS = {"planners/baselines/toppra_plan.py", "planners/spatial_toppra.py", "tray/waypoints.py",
           "energy/time_optimal.py"}


def _calls(name: str) -> dict:
    """{module path relative to qmt_drake: number of calls of `name` (a function or a method)}."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        n = 0
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                f = node.func
                if (isinstance(f, ast.Name) and f.id == name) or (isinstance(f, ast.Attribute) and f.attr == name):
                    n += 1
        if n:
            out[path.relative_to(PACKAGE).as_posix()] = n
    return out


def test_every_toppra_solve_goes_through_the_one_core():
    for name, allowed in SOLVERS.items():
        assert set(_calls(name)) == allowed, (name, _calls(name))
    assert _calls("seidel_parameterization") == {"planners/toppra_core.py": 1}
    assert set(_calls("parameterise")) == CALLERS  # the four callers, nobody else


@pytest.fixture
def recorded(monkeypatch):
    """The problems the core solves while a caller runs, with the core's answers."""
    seen = []
    inner = core.seidel_parameterization

    def spy(constraints, path, grid, sd_start=0.0, sd_end=0.0):
        out = inner(constraints, path, grid, sd_start, sd_end)
        seen.append((constraints, path, np.array(grid), out))
        return out

    monkeypatch.setattr(core, "seidel_parameterization", spy)
    return seen


def _same_as_toppra(seen):
    """Each recorded problem solved again by toppra's TOPPRA driver: the same (sdd, sd) bit for bit
    and the same return code."""
    import toppra

    assert seen
    for cons, path, grid, (sdd, sd, code) in seen:
        algo = toppra.algorithm.TOPPRA(cons, path, gridpoints=grid, solver_wrapper="seidel")
        sdd_t, sd_t, _ = algo.compute_parameterization(0.0, 0.0)
        assert code == str(algo.problem_data.return_code)
        if sd is None:
            assert sd_t is None or np.isnan(sd_t).any()
            continue
        assert np.array_equal(sd, sd_t) and np.array_equal(sdd, sdd_t)


def test_the_planar_baseline_is_toppras_result(recorded):
    from qmt_drake.planners.baselines.toppra_plan import plan_toppra
    from qmt_drake.transfer_scenario import load_scenario

    plan = plan_toppra(load_scenario("thesis-ch3"), path="joint_line", grid_points=120, measure_polygon_cost=False)
    assert plan.feasible
    _same_as_toppra(recorded)


def test_the_tray_line_is_toppras_result(recorded):
    from qmt_drake.systems.tray_object import BottleSpec
    from qmt_drake.tray.waypoints import toppra_line

    _, info = toppra_line(BottleSpec.pet_500ml(friction=0.3), n=120, margin=0.8)
    assert info["feasible"]
    _same_as_toppra(recorded)


def test_the_energy_time_optimal_end_is_toppras_result(recorded):
    from qmt_drake.energy.multistart import initial_end_posture
    from qmt_drake.energy.scenario import get_experiment
    from qmt_drake.energy.time_optimal import time_optimal_on_path

    E = get_experiment("ohsaka-fig4")
    P = E.problem(m=3)
    x = P.family.initial_genes(initial_end_posture(P, (1, 1, -1)), 1.0)
    r = time_optimal_on_path(P, x, E.torque_limit_Nm, grid_points=150, check_samples=2001)
    assert "Success" in r.return_code
    _same_as_toppra(recorded)


def test_the_spatial_arm_is_toppras_result(recorded):
    from qmt_drake.planners.spatial_methods import plan_toppra_spatial
    from qmt_drake.spatial_task import load_spatial_scenario

    sc = load_spatial_scenario("ur5-magnet-part")
    plan = plan_toppra_spatial(sc, n_grid=200)
    assert plan.duration_s > 0
    _same_as_toppra(recorded)


def _line(s, order=0):
    """q(s) = s on one joint."""
    s = np.asarray(s, float)
    return np.stack([s if order == 0 else np.full(s.shape, 1.0 if order == 1 else 0.0)], -1)


def test_no_parameterisation_gives_toppras_return_code(recorded):
    """A row no state meets (qdd + 2 <= 1, broken even at rest): not controllable, toppra's code."""
    path = core.toppra_path(_line, 1, (0.0, 1.0))
    cons = [rows_constraint(lambda q, qd, qdd: qdd + 2.0, np.array([[1.0]]), np.array([1.0]), 1)]
    sol = core.parameterise(path, cons, np.linspace(0.0, 1.0, 5))
    assert not sol.ok and "not controllable" in sol.return_code
    assert sol.toppra_trajectory() is None
    _same_as_toppra(recorded)
    with pytest.raises(ValueError):
        sol.toppra_trajectory("NoSuchParametrizer")


def test_the_named_outputs_are_toppras_parametrizers():
    """|qdd| <= 1 on q = s: bang-bang, T = 2 sqrt(1 / 1) = 2 s; toppra's constant-acceleration output has
    the core's duration, its spline output the same end point."""
    path = core.toppra_path(_line, 1, (0.0, 1.0))
    cons = [rows_constraint(lambda q, qd, qdd: qdd, np.array([[1.0], [-1.0]]), np.array([1.0, 1.0]), 1)]
    sol = core.parameterise(path, cons, np.linspace(0.0, 1.0, 101))
    assert sol.ok and sol.duration_s == pytest.approx(2.0, rel=1e-3)
    const = sol.toppra_trajectory("ParametrizeConstAccel")
    assert const.duration == pytest.approx(sol.duration_s, rel=1e-12)
    assert sol.toppra_trajectory("ParametrizeConstAccel") is const  # built once
    spline = sol.toppra_trajectory("ParametrizeSpline")
    assert float(np.ravel(spline(spline.duration))[0]) == pytest.approx(1.0, abs=1e-9)
