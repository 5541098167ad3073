"""One trajectory protocol (issue 27 item 3): every trajectory class of the package is a
qmt_drake.trajectory.JointTrajectory (found over the source by ast), and one trajectory of each kind
(planar family, spatial TOPP-RA on the via cubic, the via cubic itself, the spatial line family, Ruckig
spatial, seed 001's Fourier, time-scaled) keeps the protocol: sample() agrees with central finite
differences of its own q (qd) and qd (qdd), evaluate() with sample() inside a piece, and breakpoints_s is
sorted from 0 to the duration. The spatial ones are re-checked on their own pieces (between_pieces), the
refined maxima at least the densely sampled ones."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

import qmt_drake
from qmt_drake.plan_files import load_plan
from qmt_drake.planners.spatial_families import spatial_family
from qmt_drake.planners.spatial_methods import plan_toppra_spatial
from qmt_drake.planners.spatial_ruckig import ruckig_rest_to_rest, ruckig_segment_limits
from qmt_drake.planners.spatial_trajectory import (
    RuckigTrajectory,
    TimeScaled,
    ToppraTrajectory,
    between_pieces,
    check,
)
from qmt_drake.trajectory import JointTrajectory
from tests.spatial_fixtures import load_or_skip

PACKAGE = Path(qmt_drake.__file__).resolve().parent
GOLDEN = Path(__file__).resolve().parent / "golden"
H_S = 1e-5  # central-difference step [s]: truncation ~ H^2 q'''/6, rounding ~ 1e-16 |q| / H, both << FD_TOL
FD_TOL = 1e-6  # |finite difference - sample| <= FD_TOL (1 + |value|) [rad/s, rad/s^2]


def _assigns_duration(cls: ast.ClassDef) -> bool:
    return any(isinstance(n, ast.Attribute) and n.attr == "duration_s" and isinstance(n.ctx, ast.Store)
               and isinstance(n.value, ast.Name) and n.value.id == "self" for n in ast.walk(cls))


def _classes():
    """{name: (base names, module path, is a trajectory)} of every class in the package; a trajectory: a class
    with a sample() or an evaluate(t, t_piece) method that sets self.duration_s (a motion of a duration;
    plans, families and distributions sample too but hold or describe trajectories; a Ruckig profile's
    evaluate(t), the tip's or the joints', is a part of one)."""
    out, alias = {}, {}
    for f in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(f.read_text())
        for node in tree.body:
            if isinstance(node, ast.Assign) and isinstance(node.value, ast.Name) and len(node.targets) == 1 \
                    and isinstance(node.targets[0], ast.Name):
                alias[node.targets[0].id] = node.value.id
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                methods = {n.name for n in node.body if isinstance(n, ast.FunctionDef)
                           and (n.name != "evaluate" or len(n.args.args) >= 3)}
                out[node.name] = ([ast.unparse(b).split(".")[-1] for b in node.bases], str(f.relative_to(PACKAGE)),
                                  bool(methods & {"sample", "evaluate"}) and _assigns_duration(node))
    return out, alias


def test_every_trajectory_class_is_a_joint_trajectory():
    classes, alias = _classes()

    def is_joint_trajectory(name, seen=()):
        name = alias.get(name, name)
        if name == "JointTrajectory":
            return True
        return name in classes and name not in seen and any(is_joint_trajectory(b, seen + (name,))
                                                            for b in classes[name][0])

    trajectories = [n for n, (_, _, traj) in classes.items() if traj]
    outside = [(n, classes[n][1]) for n in trajectories if not is_joint_trajectory(n)]
    assert len(trajectories) >= 15  # the ast search finds them (LinearStream, ToppraTrajectory, ...)
    assert {"ToppraTrajectory", "SegmentTrajectory", "LinearStream", "FourierTrajectory"} <= set(trajectories)
    assert outside == []


def _old_plan(case: str, tmp_path: Path):
    path = tmp_path / f"{case}.json"
    path.write_text(json.dumps(json.loads((GOLDEN / f"{case}.json").read_text())["plan_json"]))
    return load_plan(path).trajectory


@pytest.fixture(scope="module")
def kinds(tmp_path_factory):
    """name -> (trajectory, spatial scenario or None)."""
    tmp = tmp_path_factory.mktemp("old")
    out = {"planar_family": (_old_plan("ch3-thesis", tmp), None),
           "energy_fourier": (_old_plan("ohsaka-fig3-snopt", tmp), None)}
    sc = load_or_skip("ur5-suction-bins")
    toppra = plan_toppra_spatial(sc, n_grid=300).trajectory
    toppra = toppra.inner if isinstance(toppra, TimeScaled) else toppra  # the profile before its hold scale
    out["spatial_toppra"] = (toppra, sc)
    out["spatial_toppra_scaled"] = (TimeScaled(toppra, 1.7), sc)
    m = len(sc.q_poses_rad) - 1
    out["spatial_via_cubic"] = (spatial_family(sc, "via_cubic").trajectory(np.full(m, 0.8)), sc)
    out["spatial_line"] = (spatial_family(sc, "line_cubic_velocity").trajectory(np.tile([0.35, 0.2], m)), sc)
    v, a, j = ruckig_segment_limits(sc, 1.0)
    Q = sc.q_poses_rad
    out["spatial_ruckig"] = (RuckigTrajectory([ruckig_rest_to_rest(qa, qb, v, a, j) for qa, qb in zip(Q[:-1], Q[1:])]),
                             sc)
    assert isinstance(toppra, ToppraTrajectory)
    return out


KINDS = ("planar_family", "energy_fourier", "spatial_toppra", "spatial_toppra_scaled", "spatial_via_cubic",
         "spatial_line", "spatial_ruckig")


@pytest.mark.parametrize("kind", KINDS)
def test_one_protocol(kind, kinds):
    traj, _ = kinds[kind]
    assert isinstance(traj, JointTrajectory)
    T, bp = traj.duration_s, np.asarray(traj.breakpoints_s)
    assert bp[0] == 0.0 and abs(bp[-1] - T) <= 1e-12 * T and np.all(np.diff(bp) >= 0.0) and bp.size >= 2
    # random times at least 3 steps away from every breakpoint (a jump or kink there is no derivative)
    t = np.random.default_rng(3).uniform(0.0, T, 400)
    t = t[np.min(np.abs(t[:, None] - bp[None, :]), axis=1) > 3 * H_S][:60]
    assert t.size >= 20
    q, qd, qdd = traj.sample(t)
    n = traj.n_dof
    assert q.shape == qd.shape == qdd.shape == (t.size, n)
    qp, qdp, _ = traj.sample(t + H_S)
    qm, qdm, _ = traj.sample(t - H_S)
    np.testing.assert_allclose((qp - qm) / (2 * H_S), qd, rtol=0, atol=FD_TOL * (1 + np.abs(qd).max()))
    np.testing.assert_allclose((qdp - qdm) / (2 * H_S), qdd, rtol=0, atol=FD_TOL * (1 + np.abs(qdd).max()))
    # evaluate() with the piece of t itself is sample() (away from breakpoints no one-sided shift applies)
    for got, want in zip(traj.evaluate(t, t), (q, qd, qdd)):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * (1 + np.abs(want).max()))
    # at rest (t_piece >= T) evaluate() gives the end position, still (the Fourier formula's own end rates are
    # zero to ~1e-12 by its boundary conditions, seed 001 eq. 2 and 6), and sample() the same position at T
    q_rest, qd_rest, qdd_rest = traj.evaluate(np.array([T]), np.array([T]))
    np.testing.assert_allclose(q_rest[0], traj.sample(np.array([T]))[0][0], rtol=0, atol=1e-12)
    assert np.abs(qd_rest).max() <= 1e-9 and np.abs(qdd_rest).max() <= 1e-9


@pytest.mark.parametrize("kind", [k for k in KINDS if k.startswith("spatial")])
def test_one_recheck_between_samples(kind, kinds):
    """Every spatial kind is re-checked on its own pieces; its refined peak is at least the largest of 5x
    denser samples (the maxima between samples are found, not only the samples)."""
    traj, sc = kinds[kind]
    rate = sc.check_rate_hz
    on_pieces = between_pieces(sc, traj, rate)
    assert on_pieces is not None and on_pieces["n_samples"] >= len(traj.breakpoints_s)
    dense = check(sc, traj, 5 * rate)["max_timed"]
    assert on_pieces["max_timed"] >= dense - 1e-9
