"""The tray hand (a cup standing unfixed on a tray, limits/tray_contact.py) and the shipped
panda-tray-cup scenario: the 3-D tray ratios against the seed-002 planar tray conditions and closed
forms, the TOPP-RA rows, loading and one-line refusals, every planner re-checked at 10x the check rate
and reaching every task pose (Drake FK), and the co-simulation with the cup in friction contact."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2 as G
from qmt_drake.errors import QmtInputError
from qmt_drake.limits.base import RowOptions
from qmt_drake.limits.tray_contact import TrayContactTerm, TrayCup
from qmt_drake.planners.spatial_methods import (
    plan_toppra_spatial,
)
from qmt_drake.planners.spatial_trajectory import TimeScaled, check
from qmt_drake.sim.spatial_cosim import CupSpec, simulate_spatial
from qmt_drake.spatial_task import SCENARIO_DIR, load_spatial_scenario
from qmt_drake.tray.conditions import contact_wrench, kinematics_from_hand_state, tray_ratios
from tests.spatial_fixtures import edited_copy, load_or_skip, plans_of_every_method

SHIPPED = SCENARIO_DIR / "panda-tray-cup.yaml"
CUP = TrayCup(radius_m=0.04, height_m=0.10, mass_kg=0.3, friction=0.4)
GRAVITY = np.array([0.0, 0.0, -G])
UP = np.array([0.0, 0.0, 1.0])


def _states(rng, S: int, planar: bool, level: bool) -> dict:
    """Random hand states: in the x-z plane (rotations about y) or general 3-D; level: R = I."""
    if planar:
        th = np.zeros(S) if level else rng.uniform(-0.3, 0.3, S)
        c, s = np.cos(th), np.sin(th)
        R = np.zeros((S, 3, 3))
        R[:, 0, 0], R[:, 0, 2], R[:, 1, 1], R[:, 2, 0], R[:, 2, 2] = c, s, 1.0, -s, c
        w, al = np.zeros((S, 3)), np.zeros((S, 3))
        w[:, 1], al[:, 1] = rng.normal(0, 2.0, S), rng.normal(0, 20.0, S)
        a = rng.normal(0, 4.0, (S, 3))
        a[:, 1] = 0.0
    else:
        q = rng.normal(size=(S, 4)) * [1.0, 0.1, 0.1, 0.1]
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        x, y, z, u = q[:, 1], q[:, 2], q[:, 3], q[:, 0]
        R = np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * u), 2 * (x * z + y * u)], -1),
                      np.stack([2 * (x * y + z * u), 1 - 2 * (x * x + z * z), 2 * (y * z - x * u)], -1),
                      np.stack([2 * (x * z - y * u), 2 * (y * z + x * u), 1 - 2 * (x * x + y * y)], -1)], 1)
        w, al, a = rng.normal(0, 2.0, (S, 3)), rng.normal(0, 20.0, (S, 3)), rng.normal(0, 4.0, (S, 3))
    return {"rotation": R, "angular_velocity_rad_s": w, "angular_acceleration_rad_s2": al,
            "linear_acceleration_m_s2": a}


@pytest.mark.parametrize("planar, level", [(True, True), (True, False), (False, False)])
def test_tray_ratios_equal_the_seed_tray_conditions(planar, level):
    """limits/tray_contact (contact_wrench.contact_wrench at the hand origin, turned into the face
    basis) against tray/conditions.py (its own Newton-Euler about the centre of mass, then moved to
    the base): the same slide, tip and lift ratios on random accelerations."""
    rng = np.random.default_rng(7)
    st = _states(rng, 400, planar, level)
    term = TrayContactTerm(CUP, GRAVITY, face_axis=UP)
    bottle = CupSpec.from_cup(CUP)  # the seed's BottleSpec with the cup's solid-cylinder inertia
    kin = kinematics_from_hand_state(SimpleNamespace(**st), [0.0, 0.0, CUP.h_G])
    seed = tray_ratios(contact_wrench(kin, bottle, GRAVITY), bottle)
    mine = term.columns(st)
    ok = np.isfinite(seed["slide"])
    assert ok.mean() > 0.5  # most samples push on the cup: the comparison is not all inf
    for j, k in enumerate(("slide", "tip", "lift")):
        np.testing.assert_allclose(mine[ok, j], seed[k][ok], rtol=1e-10, atol=1e-12, err_msg=k)
        assert np.all(np.isinf(mine[~ok, j]) == np.isinf(seed[k][~ok]))


def test_level_tray_closed_forms_and_inscribed_rows():
    """A level tray accelerating horizontally by a: slide a / (mu g), tip a h_G / (r g), lift 0; the
    TOPP-RA rows never allow a wrench the circles refuse, and allow every one within cos(pi/K) of them."""
    term = TrayContactTerm(CUP, GRAVITY, face_axis=UP)
    a = np.linspace(0.0, 5.0, 11)
    S = len(a)
    st = {"rotation": np.repeat(np.eye(3)[None], S, 0), "angular_velocity_rad_s": np.zeros((S, 3)),
          "angular_acceleration_rad_s2": np.zeros((S, 3)),
          "linear_acceleration_m_s2": np.stack([a * 0.6, a * 0.8, np.zeros(S)], axis=1)}
    r = term.columns(st)
    np.testing.assert_allclose(r[:, 0], a / (CUP.friction * G), rtol=1e-12)
    np.testing.assert_allclose(r[:, 1], a * CUP.h_G / (CUP.radius_m * G), rtol=1e-12)
    np.testing.assert_allclose(r[:, 2], 0.0, atol=1e-12)
    F, g = term.toppra_rows(RowOptions())
    st = _states(np.random.default_rng(3), 4000, False, False)
    rows_ok = np.all(term.toppra_w(st) @ F.T <= g + 1e-12, axis=1)
    ratio = term.columns(st).max(axis=1)
    assert rows_ok.any() and (~rows_ok).any()
    assert np.all(ratio[rows_ok] <= 1.0 + 1e-12)
    assert np.all(rows_ok[ratio <= np.cos(np.pi / CUP.pyramid_edges) - 1e-9])


@pytest.fixture(scope="module")
def sc():
    return load_or_skip("panda-tray-cup")


@pytest.fixture(scope="module")
def plans(sc):
    return plans_of_every_method(sc)


def _variant(tmp_path: Path, edit) -> Path:
    return edited_copy(SHIPPED, tmp_path, edit)


def test_scenario_loads_the_cup_as_the_carried_body(sc):
    assert sc.n_dof == 7 and sc.hand_kind == "tray" and sc.hand_term().name == "tray"
    np.testing.assert_allclose(sc.body.com_m, [0.0, 0.0, 0.05])
    assert sc.body.mass_kg == 0.3
    for q, p in zip(sc.q_poses_rad, sc.poses_m):
        ep, ea = sc.ik.errors(q, p, normal=UP)
        assert ep < 1e-6 and ea < 1e-6


@pytest.mark.parametrize("edit, message", [
    (lambda r: r["hand"]["cup"].update(radius_m=0.0), r"hand.cup.radius_m must be positive"),
    (lambda r: r["hand"]["cup"].update(radius_m=-0.04), r"hand.cup.radius_m must be positive"),
    (lambda r: r["hand"]["cup"].update(mass_kg=0), r"hand.cup.mass_kg must be positive"),
    (lambda r: r["hand"].update(friction=0.0), r"hand.friction must be positive"),
    (lambda r: r["hand"].update(friction=-0.4), r"hand.friction must be positive"),
    (lambda r: r["hand"].update(margin=1.5), r"hand.margin must lie in"),
    (lambda r: r["hand"].update(pyramid_edges=2), r"hand.pyramid_edges must be >= 3"),
    (lambda r: r["hand"]["cup"].update(com_height_m=0.2), r"com_height_m 0.2 must lie inside the cup"),
    (lambda r: r["hand"]["cup"].update(radius_m=0.1), r"radius_m 0.1 is too large for the tray"),
    (lambda r: r["hand"]["cup"].update(diameter_m=0.1), r"hand.cup: unknown key 'diameter_m'"),
    (lambda r: r["hand"].pop("cup"), r"hand: missing key 'cup'"),
    (lambda r: r.update(payload={"mass_kg": 1.0}), r"a tray hand carries its cup .* drop the payload"),
    (lambda r: r["hand"].update(kind="gripper"), "hand.kind 'gripper' is not one of suction, magnet, tray"),
    (lambda r: r["task"].update(face_normal=[-0.5, 0.0, 1.0]), r"the cup cannot stand still on the tray"),
])
def test_bad_tray_sections_refused_in_one_line(sc, tmp_path, edit, message):
    with pytest.raises(QmtInputError, match=message) as e:
        load_spatial_scenario(_variant(tmp_path, edit))
    assert "\n" not in str(e.value)


def test_margin_and_centre_of_mass_height_reach_the_term(sc, tmp_path):
    def edit(raw):
        raw["hand"]["margin"] = 0.8
        raw["hand"]["cup"]["com_height_m"] = 0.03
    v = load_spatial_scenario(_variant(tmp_path, edit))
    np.testing.assert_allclose(v.body.com_m, [0.0, 0.0, 0.03])
    t, t0 = v.hand_term(), TrayContactTerm(TrayCup(0.04, 0.10, 0.3, 0.4, com_height_m=0.03), GRAVITY)
    st = _states(np.random.default_rng(5), 200, False, False)
    r, r0 = t.columns(st), t0.columns(st)
    ok = np.isfinite(r0[:, 0])
    np.testing.assert_allclose(r[ok, :2], r0[ok, :2] / 0.8, rtol=1e-12)  # mu and r scaled by the margin
    np.testing.assert_allclose(r[:, 2], r0[:, 2], rtol=1e-12)


def test_a_tray_across_the_hand_frame_plans_and_is_carried(tmp_path):
    """face_axis y (the tray's normal along the TCP's y axis): the cup's body, the term's basis and
    the co-simulation's tray weld all turn with it; Drake's contact agrees with the plan's ratio."""
    v = load_spatial_scenario(_variant(tmp_path, lambda r: r["arm"].update(face_axis=[0.0, 1.0, 0.0])))
    np.testing.assert_allclose(v.body.com_m, [0.0, 0.05, 0.0])
    p = plan_toppra_spatial(v, n_grid=400)
    assert p.recheck["max"] <= 1.0 and p.recheck["tray"] > 0.95
    r = simulate_spatial(v, p.trajectory)
    assert r["outcome"] == "carried" and abs(r["max_grip_ratio_while_held"] - p.recheck["tray"]) < 0.02


def test_every_plan_holds_at_ten_times_the_check_rate_and_reaches_every_pose(sc, plans):
    for name, p in plans.items():
        r = check(sc, p.trajectory, 10 * sc.check_rate_hz)
        assert r["max"] <= 1.0, (name, r)
        assert r["n_samples"] >= 10 * sc.check_rate_hz * p.duration_s
        q, _, _ = p.trajectory.sample(p.pose_times_s)
        for qk, pk in zip(q, sc.poses_m):
            ep, ea = sc.ik.errors(qk, pk, normal=UP)
            assert ep < 1e-6 and ea < 1e-6, name
    # TOPP-RA is time-optimal on its path and the tray binds somewhere on it (not only the joints)
    assert plans["toppra"].duration_s == min(p.duration_s for p in plans.values())
    assert plans["toppra"].recheck["tray"] > 0.95


def test_cosim_toppra_carried_and_one_and_a_half_times_faster_lost(sc, plans):
    fast = TimeScaled(plans["toppra"].trajectory, 0.67)
    assert check(sc, fast, sc.recheck_rate_hz)["tray"] > 1.0
    held = simulate_spatial(sc, plans["toppra"].trajectory)
    lost = simulate_spatial(sc, fast)
    assert held["outcome"] == "carried" and held["final_goal_error_rad"] < 1e-3
    assert held["final_slide_m"] < 1e-3
    # the cup's simulated contact wrench (Drake's point contact) against the plan's Newton-Euler one
    assert abs(held["max_grip_ratio_while_held"] - plans["toppra"].recheck["tray"]) < 0.02
    assert lost["outcome"] in ("slid_off", "tipped") and not lost["held"]
    assert lost["max_slide_m"] > 0.08  # the base centre left the 16 cm tray
