"""Tray limits as LimitTerms (tray/limit_terms.py) on the crane-tray scenario: the contact wrench against
Drake's inverse dynamics with the bottle welded, the ratio columns against Drake's kinematics, the
toppra rows against the columns, the batched toppra parameters against toppra's own per-grid-point
evaluation, and TOPP-RA / the GA's feasibility against closed forms of a level tray on a line."""

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2 as GRAVITY_M_S2
from qmt_drake.limits.base import RowOptions
from qmt_drake.transfer_scenario import load_scenario
from qmt_drake.tray.conditions import contact_wrench, tray_kinematics, tray_ratios

SC = load_scenario("crane-tray")
LS = SC.limit_set
BOTTLE = SC.bottle
MARGIN = SC.hand.plan_margin


def _random_states(k, seed=3):
    rng = np.random.default_rng(seed)
    lo, hi = SC.arm.joint_lower_rad, SC.arm.joint_upper_rad
    q = lo + (hi - lo) * rng.random((k, 3))
    return q, rng.uniform(-2, 2, (k, 3)), rng.uniform(-6, 6, (k, 3))


def test_tray_wrench_matches_drake_inverse_dynamics_with_the_bottle_welded():
    # Independent: Drake's CalcInverseDynamics of the arm with and without the bottle welded on the
    # tray; the torque difference is J_O' (wrench on the bottle at O, world). Ours: the planar
    # backend's HandState and Newton-Euler in conditions.py (the terms' path).
    plants = []
    for with_bottle in (False, True):
        plant = MultibodyPlant(0.0)
        arm = Parser(plant).AddModels(str(SC.urdf_path))[0]
        if with_bottle:
            body = plant.AddRigidBody("bottle", arm, BOTTLE.spatial_inertia())
            plant.WeldFrames(plant.GetFrameByName("tray"), body.body_frame(), RigidTransform())
        plant.Finalize()
        plants.append(plant)
    contact = LS.term("tray_slide").contact
    q, qd, qdd = _random_states(4)
    w_T = contact.wrench(SC.arm.hand_state(q, qd, qdd))
    assert np.max(np.abs(w_T[:, 5])) > 0.1  # a real load, not a trivially zero wrench
    for k in range(len(q)):
        tau = []
        for plant in plants:
            ctx = plant.CreateDefaultContext()
            plant.SetPositions(ctx, q[k])
            plant.SetVelocities(ctx, qd[k])
            # zero applied forces leave gravity out of CalcInverseDynamics: add its generalized force
            tau.append(plant.CalcInverseDynamics(ctx, qdd[k], MultibodyForces(plant))
                       - plant.CalcGravityGeneralizedForces(ctx))
        plant = plants[0]
        ctx = plant.CreateDefaultContext()
        plant.SetPositions(ctx, q[k])
        tray = plant.GetFrameByName("tray")
        R = plant.CalcRelativeTransform(ctx, plant.world_frame(), tray).rotation().matrix()
        J = plant.CalcJacobianSpatialVelocity(ctx, JacobianWrtVariable.kV, tray, np.zeros(3), plant.world_frame(),
                                              plant.world_frame())
        wrench_W = np.concatenate([R @ w_T[k, :3], R @ w_T[k, 3:]])
        np.testing.assert_allclose(tau[1] - tau[0], J.T @ wrench_W, rtol=1e-9, atol=1e-12)


def test_columns_equal_the_ratios_from_drakes_kinematics():
    q, qd, qdd = _random_states(20, seed=5)
    cols = LS.columns(q, qd, qdd)
    planning = LS.term("tray_slide").contact.planning_bottle()  # mu and r_c x margin
    ref = tray_ratios(contact_wrench(tray_kinematics(q, qd, qdd, [0, 0, BOTTLE.com_height_m]), planning), planning)
    for name, key in (("tray_slide", "slide"), ("tray_tip", "tip"), ("tray_lift", "lift")):
        got = cols[:, LS.slices[name]][:, 0]
        finite = np.isfinite(ref[key])
        np.testing.assert_allclose(got[finite], ref[key][finite], rtol=1e-9, atol=1e-12)
        assert np.array_equal(np.isfinite(got), finite)


def test_toppra_rows_hold_exactly_when_the_columns_do():
    # In the arm's plane the tangential force and the centre of pressure lie on the tray's x axis,
    # where the polygons have a vertex: the linear form is then exact, not just conservative.
    q, qd, qdd = _random_states(400, seed=7)
    qd, qdd = 0.3 * qd, 0.3 * qdd
    state = SC.arm.hand_state(q, qd, qdd)
    cols = LS.columns(q, qd, qdd)
    for name in ("tray_slide", "tray_tip", "tray_lift"):
        term = LS.term(name)
        F, g = term.toppra_rows(RowOptions(tray_polygon_sides=4))
        viol = np.max(term.toppra_w(state) @ F.T - g, axis=1)
        col = cols[:, LS.slices[name]][:, 0]
        clear = np.abs(col - 1.0) > 1e-9
        assert np.any(col[clear] > 1) and np.any(col[clear] < 1)  # both sides are exercised
        np.testing.assert_array_equal(viol[clear] <= 1e-12, col[clear] <= 1.0)


def test_batched_toppra_parameters_equal_toppras_per_gridpoint_evaluation():
    import toppra as ta

    from qmt_drake.tray.waypoints import line_waypoints
    _, theta = line_waypoints((0.04, 0.4), (0.4, 0.4), 40)
    s = np.linspace(0.0, 1.0, 41)
    path = ta.SplineInterpolator(s, theta)
    batched = LS.toppra_constraint(tray_polygon_sides=8).compute_constraint_params(path, s)
    plain = LS.toppra_constraint(tray_polygon_sides=8, batched=False).compute_constraint_params(path, s)
    # the same rows A u + B x + C <= 0 at every grid point: the batched ones multiplied out (F the
    # identity, g zero) and scaled to unit norm in (u, x) (limits/toppra_form.py), toppra's plain
    # ones F (a u + b x + c) <= g; equal after normalising each row of both
    assert np.array_equal(batched[3], np.eye(len(batched[3]))) and not np.any(batched[4])

    def rows(params):
        a, b, c, F, g = params[:5]
        F = np.broadcast_to(F, (len(a),) + np.shape(F)[-2:])
        g = np.broadcast_to(g, (len(a),) + np.shape(g)[-1:])
        A, B = np.einsum("nkm,nm->nk", F, a), np.einsum("nkm,nm->nk", F, b)
        return A, B, np.einsum("nkm,nm->nk", F, c) - g

    def normalised(A, B, C):
        nrm = np.hypot(A, B)
        return np.stack([A, B, C]) / np.where(nrm > 0, nrm, 1.0)

    np.testing.assert_allclose(normalised(*rows(batched)), normalised(*rows(plain)), rtol=1e-10, atol=1e-12)
    A, B, _ = rows(batched)
    nrm = np.hypot(A, B)
    np.testing.assert_allclose(nrm[nrm > 1e-9], 1.0, rtol=1e-12)


def _bang_bang_s():
    return 2.0 * math.sqrt(0.36 / (MARGIN * BOTTLE.friction * GRAVITY_M_S2))


def test_toppra_through_the_shared_planner_meets_the_bang_bang_closed_form():
    # Level tray on a horizontal line: the bottle sees only the line acceleration a, slide holds
    # while |a| <= margin mu g (tip needs r_c/h_G = 0.66 g: it does not bind), so the fastest
    # motion is bang-bang, T = 2 sqrt(L / (margin mu g)).
    from qmt_drake.planners.baselines.toppra_plan import plan_toppra
    plan = plan_toppra(SC, grid_points=200, measure_polygon_cost=False)
    assert plan.feasible
    assert plan.motion_time_s == pytest.approx(_bang_bang_s(), rel=5e-3)
    assert plan.check.peak_ratios["tray_slide"] <= 1.0
    assert plan.check.peak_ratios["tray_slide"] > 0.99


def test_ga_feasibility_of_the_line_family_follows_the_slide_closed_form():
    # Line family (eq. 2-10..2-14): peak acceleration 3 L / (2 T1 (T1 + T2)); level tray, no
    # rotation: slide ratio = a / (margin mu g) exactly.
    from qmt_drake.problem import PlanningProblem
    prob = PlanningProblem(SC)
    genes = np.array([[0.3, 0.05], [0.5, 0.2], [1.0, 0.5], [2.4995, 0.001]])
    peaks = prob.peaks(genes, exact=True)
    a_peak = 3 * 0.36 / (2 * genes[:, 0] * genes.sum(axis=1))
    expect = a_peak / (MARGIN * BOTTLE.friction * GRAVITY_M_S2)
    slide = peaks.peaks[:, LS.slices["tray_slide"]][:, 0]
    np.testing.assert_allclose(slide, expect, rtol=1e-4)
    feasible = peaks.feasible
    assert not feasible[0] and feasible[2] and feasible[3]
    assert feasible[1] == bool(np.max(peaks.peaks[1, LS.ratio_mask]) <= 1.0)


def test_gravity_has_one_owner_the_scenarios_world():
    """Half the gravity in `world` halves the static motor torques AND the bottle's weight in the
    tray terms of the same limit set (before, the tray wrench used a constant g)."""
    import numpy as np

    from qmt_drake.transfer_scenario import load_scenario
    full = load_scenario("crane-tray")
    half = load_scenario("crane-tray", overrides={"world": {"gravity_m_s2": [0.0, 0.0, -4.905]}})
    q = np.array([[1.2, -2.0, 0.8]])
    z = np.zeros_like(q)
    np.testing.assert_allclose(half.arm.joint_torque(q, z, z), 0.5 * full.arm.joint_torque(q, z, z), rtol=1e-12)
    c_full = full.limit_set.term("tray_slide").contact
    c_half = half.limit_set.term("tray_slide").contact
    assert c_half.weight_N == 0.5 * c_full.weight_N
    assert half.limits.moment_limit_Nm == 0.5 * full.limits.moment_limit_Nm
