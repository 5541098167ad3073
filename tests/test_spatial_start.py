"""The spatial co-simulation starts in its own (drawn) plant's static equilibrium (sim/spatial_start, issue 29).

Checked independently of the solve: the torque the assembled drive applies at t = 0 is handed to a separate
continuous plant of the drawn arm with the drawn part welded to the hand (load_arm_plant(carried=...)), whose
CalcTimeDerivatives must give zero joint accelerations; and a drawn part standing still has the limit model's
static ratio from the first logged step. Each check also runs the old start (settled_start=False) and asserts
that it fails there, so none of them can pass vacuously."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from qmt_drake.model.actuator_order import actuator_joint_names
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.sim.cosim_run import run
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive
from qmt_drake.sim.spatial_cosim import build_spatial_cosim
from qmt_drake.sweep.spatial_cases import EFFICIENCY_BLEND_RAD_S, drawn_drive, perturbed_scenario
from studies.hold_floor import StandStill, at_rest_ratio, cosim_grip
from tests.spatial_fixtures import load_or_skip

DRAW = {"mass_scale": 1.2, "com_lateral_m": 0.005, "motor_torque_constant_scale": 1.1,
        "motor_resistance_scale": 0.95, "gear_efficiency": 0.95}


def _drawn_cosim(sc, drive_kind: str, duration_s: float, settled: bool, draw=None, physics=None):
    """The drawn plant (DRAW) standing still at the pick pose under the nominal drive `drive_kind`: ideal,
    pd (dc_motor, no integral), pid (integral 5 1/s), pid-sampled (and its law held at 2 ms)."""
    draw = dict(DRAW if draw is None else draw)
    if physics is not None:
        sc = dataclasses.replace(sc, hand_physics=physics)
    if sc.hand_kind == "tray":  # the cup stands on its axis
        draw.pop("com_lateral_m", None)
    q0 = np.asarray(sc.q_poses_rad[0], float)
    physical = perturbed_scenario(sc, draw)
    kw = {"controller_sc": sc, "settled_start": settled}
    if drive_kind != "ideal":
        nominal = SpatialMotorDrive.for_scenario(sc, q0, "shaped", integral_rate_per_s=0.0 if drive_kind == "pd" else 5.0)
        law = {**draw, "loop_period_s": 0.002} if drive_kind == "pid-sampled" else draw
        kw.update(drive=drawn_drive(nominal, sc, physical, law, EFFICIENCY_BLEND_RAD_S), feedforward="shaped")
    return physical, q0, build_spatial_cosim(physical, StandStill(q0, duration_s), **kw)


def _joint_accelerations_at_start(physical, co) -> np.ndarray:
    """Started (not run): the drive's torque at t = 0 on a separate continuous plant of the drawn arm with the
    drawn part welded to the hand at the co-simulation's start pose: its joint accelerations [rad/s^2]."""
    sim = Simulator(co.diagram)
    co.start(sim)
    plant, arm = co.plant, co.handles.arm_instance
    pctx = plant.GetMyContextFromRoot(sim.get_context())
    tau = plant.get_actuation_input_port(arm).Eval(pctx)
    names = actuator_joint_names(plant, arm)
    q = {n: plant.GetJointByName(n, arm).GetOnePosition(pctx) for n in names}
    carried = physical.body.as_dict() if physical.hand_kind != "tray" else physical.cup.body(physical.face_axis).as_dict()
    check, _, _ = load_arm_plant(physical.urdf, physical.hand_frame, lock_joints=physical.lock_joints, carried=carried)
    ctx = check.CreateDefaultContext()
    for n in names:
        check.GetJointByName(n).set_angle(ctx, q[n])
    order = actuator_joint_names(check, check.GetJointByName(names[0]).model_instance())
    check.get_actuation_input_port().FixValue(ctx, np.array([tau[names.index(n)] for n in order]))
    vdot = check.AllocateTimeDerivatives()
    check.CalcTimeDerivatives(ctx, vdot)
    v = vdot.get_vector().CopyToVector()[check.num_positions():]
    return np.array([v[check.GetJointByName(n).velocity_start()] for n in names])


class _Accelerating(StandStill):
    """From rest at q0, every joint accelerating at 0.5 rad/s^2 from t = 0."""

    def sample(self, t_s):
        t = np.atleast_1d(np.asarray(t_s, float))[:, None]
        a = np.full(self.n_dof, 0.5)
        return self.q0 + 0.5 * a * t**2, a * t, np.tile(a, (len(t), 1))


@pytest.fixture(scope="module")
def suction():
    return load_or_skip("ur5-suction-bins")


@pytest.mark.parametrize("drive_kind", ["ideal", "pd", "pid", "pid-sampled"])
def test_every_drive_starts_the_drawn_arm_at_rest(suction, drive_kind):
    physical, _, co = _drawn_cosim(suction, drive_kind, 0.05, settled=True)
    qdd = _joint_accelerations_at_start(physical, co)
    assert np.abs(qdd).max() < 1e-5, qdd  # measured <= 1e-9 rad/s^2 (the weld's regularisation aside)
    physical, _, old = _drawn_cosim(suction, drive_kind, 0.05, settled=False)
    assert np.abs(_joint_accelerations_at_start(physical, old)).max() > 0.1  # the old start: not at rest


@pytest.mark.parametrize("physics", ["contact"])
def test_the_contact_hand_starts_at_rest(suction, physics):
    physical, _, co = _drawn_cosim(suction, "pid", 0.05, settled=True, physics=physics)
    assert np.abs(_joint_accelerations_at_start(physical, co)).max() < 1e-5
    physical, _, old = _drawn_cosim(suction, "pid", 0.05, settled=False, physics=physics)
    assert np.abs(_joint_accelerations_at_start(physical, old)).max() > 0.1


def test_the_tray_starts_at_rest():
    sc = load_or_skip("panda-tray-cup")
    draw = {"mass_scale": 1.2, "motor_torque_constant_scale": 1.1}
    physical, _, co = _drawn_cosim(sc, "pid", 0.05, settled=True, draw=draw)
    assert np.abs(_joint_accelerations_at_start(physical, co)).max() < 1e-5
    physical, _, old = _drawn_cosim(sc, "pid", 0.05, settled=False, draw=draw)
    assert np.abs(_joint_accelerations_at_start(physical, old)).max() > 0.1


@pytest.mark.parametrize(("name", "drive_kind", "lateral_m"), [("ur5-suction-bins", "pid", 0.005),
                                                               ("ur5-suction-bins", "ideal", 0.005),
                                                               ("ur5-magnet-part", "pid", 0.001)])
def test_standing_still_the_hold_ratio_is_the_static_one_from_the_first_step(name, drive_kind, lateral_m):
    """The hold check (the part's own motion, sim/spatial_hold) sees the limit model's static ratio of the
    drawn part at the start pose from its first sample: no start transient (the old start: +0.04 on this
    suction draw at 2 ms, +0.17 to +0.26 of the magnet's moment limit at 9 ms)."""
    sc = load_or_skip(name)
    for settled in (True, False):
        physical, _, co = _drawn_cosim(sc, drive_kind, 0.03, settled=settled, draw={**DRAW, "com_lateral_m": lateral_m})
        r = run(co)
        pctx = co.plant.GetMyContextFromRoot(co.simulator.get_context())
        q_start = co.handles.start["q_start_rad"] if settled else np.asarray(sc.q_poses_rad[0], float)
        static = at_rest_ratio(physical, cosim_grip(physical), q_start)
        _, ratio = co.monitor.ratios(co.simulator.get_context(), 1)
        assert r["outcome"] != "detached" and pctx is not None
        if settled:
            assert static > 0.1 and np.ptp(ratio) < 1e-6  # constant from the first sample (measured <= 1.2e-8)
            # (relative 2.5e-6 on the magnet: the part rests rotated by the weld's own static deflection)
            np.testing.assert_allclose(ratio, static, rtol=1e-5)
        else:
            assert ratio.max() > static + 0.02


def test_the_plan_start_acceleration_is_not_cancelled():
    """The equilibrium is solved with the reference at rest: a plan that accelerates at t = 0 keeps its
    acceleration (the nominal arm then starts exactly at q0 with the law's zero state), and the reference
    sources are restored after the solve."""
    sc = load_or_skip("ur5-suction-bins")
    q0 = np.asarray(sc.q_poses_rad[0], float)

    co = build_spatial_cosim(sc, _Accelerating(q0, 0.05))
    sim = Simulator(co.diagram)
    co.start(sim)
    assert co.handles.start["residual_Nm"] < 1e-6
    np.testing.assert_allclose(co.handles.start["q_start_rad"], q0, atol=1e-9)
    src_a = [s for s in co.diagram.GetSystems() if s.get_name().startswith("drake/systems/TrajectorySource")
             and s.get_output_port().size() == sc.n_dof]
    values = [s.get_output_port().Eval(s.GetMyContextFromRoot(sim.get_context())) for s in src_a]
    assert any(np.allclose(v, 0.5) for v in values)  # the plan's acceleration, restored


def test_a_held_laws_compensated_reference_is_at_rest_for_the_solve_too():
    """With the law held (2 ms) its feedforward reads the plan through HoldCompensatedReference, which
    evaluates the plan itself; the solve puts it at rest with the sources, so a plan that accelerates at
    t = 0 settles to the same integral as one standing still (the start's acceleration is the move's, not
    the hold's), and the compensated reference is restored after the solve."""
    sc = load_or_skip("ur5-suction-bins")
    q0 = np.asarray(sc.q_poses_rad[0], float)

    nominal = SpatialMotorDrive.for_scenario(sc, q0, "full", integral_rate_per_s=5.0, control_period_s=0.002)
    integrals = []
    for plan in (StandStill(q0, 0.05), _Accelerating(q0, 0.05)):
        co = build_spatial_cosim(sc, plan, drive=nominal, feedforward="full")
        sim = Simulator(co.diagram)
        co.start(sim)
        law = co.diagram.GetSubsystemByName("controller")
        integrals.append(law.GetMyContextFromRoot(sim.get_context()).get_discrete_state(law._z).CopyToVector())
        ahead = co.diagram.GetSubsystemByName("hold_compensated_reference")
    np.testing.assert_allclose(integrals[1], integrals[0], rtol=0, atol=1e-9)
    acc = ahead.GetOutputPort("desired_acceleration").Eval(ahead.GetMyContextFromRoot(sim.get_context()))
    np.testing.assert_allclose(acc, 0.5)  # the plan's acceleration, restored
