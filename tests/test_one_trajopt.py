"""One trajopt (planners/trajopt_core.py): a single KinematicTrajectoryOptimization construction in the
package, the planar and the spatial trajopt both solve through it, the tray's limit rows carry correct
gradients (checked against differences of the rows themselves), and a trajopt plan of the tray holds
every limit on a 10x finer resampling than its own re-check."""

import ast
from pathlib import Path

import numpy as np
import pytest

import qmt_drake
from qmt_drake.planners import trajopt_core
from qmt_drake.planners.baselines.trajopt_plan import plan_trajopt
from qmt_drake.transfer_scenario import load_scenario

PACKAGE = Path(qmt_drake.__file__).parent
QUICK = {"num_control_points": 10, "constraint_samples": 40}


def _calls(name):
    """(module path, line) of every call of `name` (a bare name or an attribute) in the package."""
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call):
                f = node.func
                called = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None
                if called == name:
                    out.append((str(path.relative_to(PACKAGE)), node.lineno))
    return out


def test_one_construction_of_the_program():
    sites = _calls("KinematicTrajectoryOptimization")
    assert [s[0] for s in sites] == ["planners/trajopt_core.py"], sites


class _Stop(Exception):
    pass


@pytest.mark.parametrize("name", ["thesis-ch3", "crane-tray", "ur5-suction-bins"])
def test_planar_and_spatial_trajopt_solve_through_the_core(monkeypatch, name):
    """Each entry hands a TrajoptProblem to trajopt_core.solve (stopped there: the solve is not run)."""
    from qmt_drake import load_scenario as load_any
    from qmt_drake.planners import registry
    seen = []

    def spy(problem):
        seen.append(problem)
        raise _Stop

    monkeypatch.setattr(trajopt_core, "solve", spy)
    sc = load_any(name)
    with pytest.raises(_Stop):
        registry.plan(sc, "trajopt")
    (p,) = seen
    assert isinstance(p, trajopt_core.TrajoptProblem)
    assert p.fractions[0] == 0.0 and p.fractions[-1] == 1.0 and len(p.fractions) == len(p.path_rad)
    # the kind supplies its own rows: the thesis arm its moment, the tray its limit set's, the UR5 its tilt
    kinds = {"thesis-ch3": (1, 0, 0), "crane-tray": (0, 1, 0), "ur5-suction-bins": (0, 0, 40)}
    assert (len(p.ratio_rows), len(p.limit_rows), len(p.path_constraints)) == kinds[name]


def test_limit_rows_gradient_matches_differences_of_the_rows():
    """The AutoDiff Jacobian of LimitRows (central differences of w, chain rule through the spline and
    T) against plain central differences of the rows' values in the decision variables."""
    from pydrake.autodiffutils import ExtractGradient, InitializeAutoDiff
    from pydrake.math import BsplineBasis
    sc = load_scenario("crane-tray")
    ls = sc.limit_set
    terms, F, g = ls.toppra_rows()
    rows = trajopt_core.LimitRows(lambda q, qd, qdd: ls.toppra_w(terms, q, qd, qdd), F, g, None)
    n, ncp = sc.arm.n_dof, 8
    basis = BsplineBasis(4, ncp)
    s = np.linspace(0.0, 1.0, 7)
    f, m = trajopt_core._limit_rows_constraint(rows, basis, s, n, ncp)
    rng = np.random.default_rng(3)
    x = np.r_[rng.uniform(-0.5, 0.5, n * ncp) + np.tile([0.3, -1.2, 0.9], ncp)[:n * ncp], 0.8]
    J = ExtractGradient(f(InitializeAutoDiff(x[:, None])[:, 0]))
    assert J.shape == (m, x.size)
    h = 1e-6
    num = np.stack([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(x.size)], axis=1)
    np.testing.assert_allclose(J, num, rtol=1e-4, atol=1e-5 * np.abs(num).max())


def test_tray_trajopt_holds_every_limit_between_samples():
    sc = load_scenario("crane-tray")
    plan = plan_trajopt(sc, **QUICK)
    assert plan.extra["limit_rows"] == "limit_set" and plan.extra["solver"]["success"]
    assert plan.feasible, plan.extra.get("infeasible")
    # independent of the plan's own (refined) re-check: 10x its rate, plain samples
    fine = sc.limit_set.report(plan.trajectory, 10 * sc.sampling.check_rate_hz, refine=False)
    assert fine.joint_range_ok
    assert max(fine.peak_ratios.values()) <= 1.0, fine.peak_ratios
    for term in ("tray_slide", "tray_tip", "tray_lift"):
        assert term in fine.peak_ratios
    # ends at the task's tray points, at rest
    T = plan.motion_time_s
    q, qd, _ = plan.sample(np.array([0.0, T]))
    np.testing.assert_allclose(qd, 0.0, atol=1e-9)
