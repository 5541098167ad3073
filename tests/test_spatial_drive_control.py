"""The spatial drives' controller model: a drawn plant under the nominal controller, every hand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.suction import GripModel
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive, back_emf_damping, check_drive
from qmt_drake.sim.spatial_cosim import build_spatial_cosim, simulate_spatial
from qmt_drake.sweep.cases import build_cases
from qmt_drake.sweep.spatial_cases import build_spatial_cases, drawn_drive, perturbed_scenario
from qmt_drake.sweep.spec import load_spec
from qmt_drake.systems.joint_tracking import JointPidController, PidGains
from studies.record_goldens import normalise_graphviz
from tests.spatial_fixtures import load_or_skip


class Hold:
    """A plan that stays at q [rad] for duration_s (the spatial trajectory interface)."""

    def __init__(self, q, duration_s):
        self.q, self.duration_s = np.asarray(q, float), duration_s

    def sample(self, t):
        t = np.atleast_1d(t)
        z = np.zeros((len(t), len(self.q)))
        return np.tile(self.q, (len(t), 1)), z, z.copy()


@pytest.fixture(scope="module")
def suction():
    return load_or_skip("ur5-suction-bins")


@pytest.mark.parametrize("physics", ["weld", "contact"])
def test_controller_model_stays_nominal_when_the_plant_is_drawn(suction, physics):
    """A sweep case simulates a drawn part (here 1.5x the mass) under the controller built from the nominal
    scenario (controller_sc). The contact hand used to build its ideal controller from the drawn scenario:
    its inverse dynamics then knew the drawn mass, which a real controller cannot. The controller's plant
    (the arm with the part welded, sim/spatial_cosim.add_ideal_controller) must carry the nominal part."""
    sc = dataclasses.replace(suction, hand_physics=physics)
    drawn = perturbed_scenario(sc, {"mass_scale": 1.5})
    assert drawn.body.mass_kg == pytest.approx(1.5 * sc.body.mass_kg)
    hold = Hold(sc.q_poses_rad[0], 0.1)
    co = build_spatial_cosim(drawn, hold, controller_sc=sc)
    (ctrl,) = [s for s in co.diagram.GetSystems() if isinstance(s, InverseDynamicsController)]
    mp = ctrl.get_multibody_plant_for_control()
    assert mp.GetBodyByName("carried").default_mass() == sc.body.mass_kg
    # and without controller_sc the controller is the simulated scenario's (a run on its own model)
    co = build_spatial_cosim(drawn, hold)
    (ctrl,) = [s for s in co.diagram.GetSystems() if isinstance(s, InverseDynamicsController)]
    assert ctrl.get_multibody_plant_for_control().GetBodyByName("carried").default_mass() == drawn.body.mass_kg


def _held_voltages(hold_period_s, ki=0.0, t_end=0.012):
    """A one-joint JointPidController (Kp 2 V/rad, Ki ki, gear 1) sampled every 1 ms step and held at hold_period_s,
    fed q_des(t) = t [rad] and q = 0: its voltage at each 1 ms step (times, values)."""
    b = DiagramBuilder()
    pid = b.AddSystem(JointPidController(PidGains([2.0], [ki], [0.0]), [1.0], [100.0], control_period_s=1e-3,
                                         hold_period_s=hold_period_s))
    t = np.array([0.0, 1.0])
    ramp = b.AddSystem(TrajectorySource(PiecewisePolynomial.FirstOrderHold(t, np.vstack([t, [1.0, 1.0]]))))
    b.Connect(ramp.get_output_port(), pid.GetInputPort("desired_state"))
    b.Connect(b.AddSystem(ConstantVectorSource([0.0, 0.0])).get_output_port(), pid.GetInputPort("estimated_state"))
    log = LogVectorOutput(pid.GetOutputPort("voltage_command"), b, 1e-3)
    d = b.Build()
    sim = Simulator(d)
    sim.AdvanceTo(t_end)
    data = log.FindLog(sim.get_context())
    return data.sample_times(), data.data()[0]


@pytest.mark.parametrize("period_s", [3e-3, 1.5e-3])
def test_held_law_is_the_sample_at_the_last_instant(period_s):
    """Zero-order hold at period_s on a 1 ms update: at every step the voltage is Kp e at the last sample, and a
    sample falls on the first step at or after each k period_s (1.5 ms: steps 0, 2, 3, 5, 6, ...)."""
    t, v = _held_voltages(period_s)
    steps = np.rint(t / 1e-3).astype(int)
    sample_steps = sorted({int(np.ceil(k * period_s / 1e-3 - 1e-9)) for k in range(20)})
    last = [max(s for s in sample_steps if s <= n) for n in steps]
    np.testing.assert_allclose(v, 2.0 * np.array(last) * 1e-3, rtol=1e-12, atol=1e-15)
    assert len(set(np.round(v, 12))) < len(v)  # held between samples (not the every-step law)


def test_held_integral_grows_by_the_period_per_sample():
    """With Ki and the hold, the voltage at sample k is Kp e_k + Ki sum_{j<k} period e_j (the integral grows by
    the hold period per sample, from the errors at the samples)."""
    period, ki = 3e-3, 50.0
    t, v = _held_voltages(period, ki=ki)
    samples = np.arange(0, 13, 3) * 1e-3
    expected = {round(s, 6): 2.0 * s + ki * period * samples[samples < s - 1e-9].sum() for s in samples}
    for tk, vk in zip(t, v):
        s = max(x for x in samples if x <= tk + 1e-9)
        assert vk == pytest.approx(expected[round(s, 6)], rel=1e-12)


def _strong_grip(sc):
    """A cup that never lets go, so the hold's statics include the part."""
    return GripModel(sc.grip.radius_m, 1e4, 5.0, face_normal=sc.grip.basis[2])


def _graph(sc, drive):
    co = build_spatial_cosim(sc, Hold(sc.q_poses_rad[0], 0.05), drive=drive, actuator="dc_motor")
    return normalise_graphviz(co.diagram.GetGraphvizString())


def test_control_period_at_the_plant_step_is_the_default_drive(suction):
    """control_period_s None (default) or equal to the plant step: the same diagram (the compiled every-step law,
    the loop damping folded into the plant), hence the same numbers. A longer period runs the held law (the
    Python controller) with only the back EMF folded into the plant behind a voltage amplifier, nothing behind the
    current amplifier (the default: its current loop cancels the back EMF); explicit folds nothing."""
    q0 = suction.q_poses_rad[0]
    default = SpatialMotorDrive.for_scenario(suction, q0, "full")
    at_step = SpatialMotorDrive.for_scenario(suction, q0, "full", control_period_s=1e-3)
    assert _graph(suction, default) == _graph(suction, at_step)
    assert "motor_actuation" in _graph(suction, default)
    held = SpatialMotorDrive.for_scenario(suction, q0, "full", control_period_s=4e-3, amplifier="voltage")
    assert held.sampled(1e-3) and not at_step.sampled(1e-3)
    np.testing.assert_array_equal(held.plant_damping_Nms(1e-3), back_emf_damping(held.params))
    current = SpatialMotorDrive.for_scenario(suction, q0, "full", control_period_s=4e-3)
    np.testing.assert_array_equal(current.plant_damping_Nms(1e-3), 0.0)
    np.testing.assert_array_equal(dataclasses.replace(current, control_period_s=None).plant_damping_Nms(1e-3),
                                  default.loop_damping_Nms)  # the amplifier is a held law's only
    assert np.all(held.plant_damping_Nms(1e-3) <= held.loop_damping_Nms)  # (Kd = 0 where the back EMF alone
    assert np.any(held.plant_damping_Nms(1e-3) < held.loop_damping_Nms)  # damps the joint critically)
    np.testing.assert_array_equal(dataclasses.replace(default, explicit=True).plant_damping_Nms(1e-3), 0.0)
    with pytest.raises(QmtInputError, match=r"control period 0.5 ms: .* at least the plant step 1 ms") as e:
        build_spatial_cosim(suction, Hold(q0, 0.05), drive=dataclasses.replace(default, control_period_s=5e-4))
    assert "\n" not in str(e.value)
    with pytest.raises(QmtInputError, match="at most 10 ms"):
        SpatialMotorDrive.for_scenario(suction, q0, "full", control_period_s=0.02)


@pytest.mark.parametrize("period_s, explicit, amplifier", [(4e-3, False, "voltage"), (4e-3, False, "current"),
                                                           (None, True, "current")])
def test_held_and_explicit_laws_hold_gravity_at_the_closed_form(suction, period_s, explicit, amplifier):
    """The static hold without feedforward (tests/test_spatial_dc_motor's closed form): at rest the law's held
    voltage is Kp N e whatever its period, stepping or amplifier (at rest the current loop adds no back EMF), so the
    arm settles at e = R tau_g / (N^2 k_t Kp) with N k_t i = tau_g, gravity from Drake at the settled pose; Kp the
    law's (a held current law's own, SpatialMotorDrive.law_gains)."""
    sc, q0 = suction, suction.q_poses_rad[0]
    drive = SpatialMotorDrive.for_scenario(sc, q0, "none", control_period_s=period_s, explicit=explicit,
                                           amplifier=amplifier)
    r = simulate_spatial(sc, Hold(q0, 1.5), drive=drive, feedforward="none", grip=_strong_grip(sc))
    assert r["lost_at_s"] is None
    e, i = np.array(r["final_tracking_error_rad"]), np.array(r["final_current_A"])
    arm, _, _ = load_arm_plant(sc.urdf, sc.hand_frame, carried=sc.body.as_dict(), effort_limit_Nm=sc.torque_limit_Nm,
                               velocity_limit_rad_s=sc.velocity_limit_rad_s)
    ctx = arm.CreateDefaultContext()
    arm.SetPositions(ctx, q0 - e)
    tau_g = -arm.CalcGravityGeneralizedForces(ctx)
    mp = drive.params
    N, kt, R = mp.gear_ratio, mp.torque_constant_Nm_per_A, mp.resistance_ohm
    scale = np.abs(tau_g).max()
    np.testing.assert_allclose(N * kt * i, tau_g, atol=1e-4 * scale)
    np.testing.assert_allclose(e, R * tau_g / (N ** 2 * kt * drive.law_gains(1e-3).kp_V_per_rad), atol=1e-7)
    assert np.abs(e).max() > 1e-3


def test_a_sweep_draws_the_loop_period(suction):
    spec = {"name": "lp", "scenario": "ur5-suction-bins", "plans": [{"method": "toppra"}],
            "sim": {"actuator": "dc_motor", "feedforward": "shaped"}, "monte_carlo": {"cases": 4, "seed": 1},
            "parameters": {"loop_period_s": {"dist": "uniform", "low": 0.001, "high": 0.004}}}
    cases, _ = build_spatial_cases(load_spec(spec))
    periods = [c.motor_scales["loop_period_s"] for c in cases]
    assert all(1e-3 <= p <= 4e-3 for p in periods) and len(set(periods)) == 4
    assert perturbed_scenario(suction, cases[0].motor_scales) is suction  # the motors are not redrawn
    nominal = SpatialMotorDrive.for_scenario(suction, suction.q_poses_rad[0], "shaped")
    drawn = drawn_drive(nominal, suction, suction, cases[0].motor_scales)
    assert drawn.control_period_s == periods[0] and nominal.control_period_s is None


@pytest.mark.parametrize("scenario, sim, parameter, says", [
    ("ur5-suction-bins", {"actuator": "ideal"}, {"dist": "uniform", "low": 0.001, "high": 0.002},
     "motor parameters act through sim.actuator dc_motor"),
    ("ur5-suction-bins", {"actuator": "dc_motor"}, {"dist": "uniform", "low": 0.0005, "high": 0.002}, "loop_period_s"),
    ("ur5-suction-bins", {"actuator": "dc_motor"}, {"dist": "uniform", "low": 0.001, "high": 0.02}, "loop_period_s"),
    ("thesis-ch4", {}, {"dist": "uniform", "low": 0.001, "high": 0.002}, "loop_period_s"),
])
def test_a_meaningless_loop_period_is_refused_in_one_line(scenario, sim, parameter, says):
    spec = {"name": "lp", "scenario": scenario, "plans": [{"method": "toppra" if "ur5" in scenario else "thesis"}],
            "sim": sim, "monte_carlo": {"cases": 2, "seed": 1}, "parameters": {"loop_period_s": parameter}}
    with pytest.raises(QmtInputError, match=says) as e:
        (build_spatial_cases if "ur5" in scenario else build_cases)(load_spec(spec))
    assert "\n" not in str(e.value)


def test_explicit_is_refused_where_meaningless(suction):
    """--explicit needs the DC drive (the ideal actuator has no motor loop) and, as the planar one, a step of at
    most 1 ms; both refused in one line before any planning (check_drive) and when a drive is built."""
    for actuator, h, says in (("ideal", None, "the ideal actuator has no motor loop"),
                              ("dc_motor", 2e-3, "explicit motor loop is known stable up to 1 ms")):
        with pytest.raises(QmtInputError, match=says) as e:
            check_drive(suction, actuator, "full", True, h)
        assert "\n" not in str(e.value)
    check_drive(suction, "dc_motor", "full", True, 1e-3)
    with pytest.raises(QmtInputError, match="known stable up to 1 ms"):
        build_spatial_cosim(suction, Hold(suction.q_poses_rad[0], 0.05), actuator="dc_motor", explicit=True,
                            time_step_s=2e-3)
