"""The spatial co-simulation's logged hold check (sim/spatial_hold.py) against the former per-step Python
monitors (kept here as the test-only reference: a LeafSystem evaluating the hand's limit term on the
part's body pose, spatial velocity and acceleration ports at every step, and a Simulator monitor that
stops the run at the first state with a ratio above 1; the tray's TrayBottleMonitor): on the same
plans, the same outcome, detach time, final arm and part state and tracking, and the same ratios to
rounding. The cost against the Drake-primitives floor: python -m studies.bench_cosim_floor."""

import numpy as np
import pytest
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.framework import EventStatus, LeafSystem
from pydrake.systems.primitives import LogVectorOutput

from qmt_drake.limits.tray_contact import TrayContactTerm
from qmt_drake.sim import spatial_cosim, spatial_hold
from qmt_drake.sim.spatial_cosim import TIME_STEP_S, simulate_spatial
from qmt_drake.sim.spatial_hold import rotation_from_quaternion
from qmt_drake.systems.tray_object import TrayBottleMonitor, seated_pose_on_tray
from tests.spatial_fixtures import load_or_skip


class PerStepHoldMonitor(LeafSystem):
    """The former HoldMonitor: every step the hand term's ratio from Drake's body ports; latches
    (detached, time, largest ratio while held)."""

    def __init__(self, plant, part_body, term) -> None:
        super().__init__()
        self.part, self.term = part_body, term
        self.poses = self.DeclareAbstractInputPort("poses", plant.get_body_poses_output_port().Allocate())
        self.vels = self.DeclareAbstractInputPort("velocities",
                                                  plant.get_body_spatial_velocities_output_port().Allocate())
        self.accs = self.DeclareAbstractInputPort("accelerations",
                                                  plant.get_body_spatial_accelerations_output_port().Allocate())
        self.DeclareDiscreteState(3)  # detached, its time, the largest ratio while held
        self.ratio_port = self.DeclareStateOutputPort("ratio", self.DeclareDiscreteState(1))  # the last ratio
        self.DeclarePeriodicDiscreteUpdateEvent(TIME_STEP_S, 0.0, self._update)

    def _update(self, context, discrete_state):
        x = context.get_discrete_state(0).CopyToVector()
        i = int(self.part.index())
        X, V, A = self.poses.Eval(context)[i], self.vels.Eval(context)[i], self.accs.Eval(context)[i]
        state = {"rotation": X.rotation().matrix()[None], "angular_velocity_rad_s": V.rotational()[None],
                 "angular_acceleration_rad_s2": A.rotational()[None],
                 "linear_acceleration_m_s2": A.translational()[None]}
        r = float(np.max(self.term.columns(state)))
        if x[0] < 0.5:
            x[2] = max(x[2], r)
            if r > 1.0:
                x[0], x[1] = 1.0, context.get_time()
        discrete_state.get_mutable_vector(0).SetFromVector(x)
        discrete_state.get_mutable_vector(1).SetFromVector([r])


def simulate_the_former_way(monkeypatch, sc, traj, **kw) -> dict:
    """simulate_spatial with the per-step monitor and the stop at the step after the detachment."""
    made = {}
    real_hold_log = spatial_cosim.HoldLog

    def hold_log(builder, plant, part, term, time_step_s):
        mon = made["mon"] = builder.AddSystem(PerStepHoldMonitor(plant, part, term))
        builder.Connect(plant.get_body_poses_output_port(), mon.poses)
        builder.Connect(plant.get_body_spatial_velocities_output_port(), mon.vels)
        builder.Connect(plant.get_body_spatial_accelerations_output_port(), mon.accs)
        return real_hold_log(builder, plant, part, term, time_step_s)

    def run(sim, diagram, hold, t_end_s, release):
        ctx = sim.get_mutable_context()
        mctx = made["mon"].GetMyContextFromRoot(ctx)
        sim.set_monitor(lambda c: EventStatus.ReachedTermination(made["mon"], "detached")
                        if mctx.get_discrete_state(0)[0] > 0.5 else EventStatus.DidNothing())
        sim.AdvanceTo(t_end_s)
        x = mctx.get_discrete_state(0).CopyToVector()
        if x[0] > 0.5:
            sim.clear_monitor()
            release(ctx)
            sim.AdvanceTo(t_end_s)
        return x[0] > 0.5, float(x[1]) if x[0] > 0.5 else None, float(x[2])

    with monkeypatch.context() as m:
        m.setattr(spatial_cosim, "HoldLog", hold_log)
        m.setattr(spatial_cosim, "run_until_detached", run)
        return simulate_spatial(sc, traj, **kw)


class RestThenMove:
    """Rest at q0 for rest_s, then a quintic rest-to-rest move by dq [rad] in move_s (spatial trajectory)."""

    def __init__(self, q0, dq, rest_s, move_s) -> None:
        self.q0, self.dq = np.asarray(q0, float), np.asarray(dq, float)
        self.rest_s, self.move_s = rest_s, move_s
        self.duration_s = rest_s + move_s

    def sample(self, t):
        s = np.clip((np.atleast_1d(np.asarray(t, float)) - self.rest_s) / self.move_s, 0.0, 1.0)[:, None]
        p = 10 * s**3 - 15 * s**4 + 6 * s**5
        v = (30 * s**2 - 60 * s**3 + 30 * s**4) / self.move_s
        a = (60 * s - 180 * s**2 + 120 * s**3) / self.move_s**2
        return self.q0 + p * self.dq, v * self.dq, a * self.dq


def _same(new: dict, old: dict) -> None:
    assert new["outcome"] == old["outcome"]
    assert new["lost_at_s"] == old["lost_at_s"]  # the same step's time, to the bit
    assert new["max_grip_ratio_while_held"] == pytest.approx(old["max_grip_ratio_while_held"], rel=1e-13, abs=0)
    for key in ("final_goal_error_rad", "part_distance_from_cup_at_end_m", "max_tracking_error_rad",
                "rms_tracking_error_rad", "final_tracking_error_rad", "max_tracking_error_per_joint_rad"):
        assert new[key] == old[key], key  # the same simulated states: the weld held until the same step


@pytest.mark.parametrize("name, dq1, rest_s, detaches", [
    ("ur5-suction-bins", 0.02, 0.05, False),  # held
    ("ur5-suction-bins", 0.8, 0.33, True),  # lost in the second check chunk: the run goes back to 0.25 s
    ("ur5-magnet-part", 0.8, 0.0, True),  # lost in the first steps
])
def test_logged_hold_check_equals_the_per_step_monitor(monkeypatch, name, dq1, rest_s, detaches):
    sc = load_or_skip(name)
    dq = np.zeros(sc.n_dof)
    dq[0] = dq1
    traj = RestThenMove(sc.q_poses_rad[0], dq, rest_s, 0.25)
    monkeypatch.setattr(spatial_cosim, "TAIL_S", 0.05)  # short runs: the tail only has to exist
    new = simulate_spatial(sc, traj)
    old = simulate_the_former_way(monkeypatch, sc, traj)
    assert (new["outcome"] == "detached") == detaches
    if detaches:
        assert new["lost_at_s"] > (rest_s if rest_s > 0.25 else 0.0)
    _same(new, old)


def test_check_chunks_of_one_step_change_nothing(monkeypatch):
    """The chunk length is a cost choice only: a detachment found in a long chunk (gone back to its
    start) and one found step by step give the same run."""
    sc = load_or_skip("ur5-suction-bins")
    dq = np.zeros(sc.n_dof)
    dq[0] = 0.8
    traj = RestThenMove(sc.q_poses_rad[0], dq, 0.05, 0.2)
    monkeypatch.setattr(spatial_cosim, "TAIL_S", 0.02)
    long = simulate_spatial(sc, traj)
    monkeypatch.setattr(spatial_hold, "CHECK_CHUNK_S", TIME_STEP_S / 2)
    short = simulate_spatial(sc, traj)
    assert long["outcome"] == "detached"
    assert long == short


def test_rotation_from_quaternion_is_drakes():
    """The part's rotation from its logged quaternion is the one Drake's pose port gives for the same
    free-body state, a quaternion off unit length included, to a few units in the last place (Eigen's
    vectorised products round in another order)."""
    plant = MultibodyPlant(0.0)
    body = plant.AddRigidBody("b", SpatialInertia.SolidSphereWithMass(1.0, 0.1))
    plant.Finalize()
    ctx = plant.CreateDefaultContext()
    rng = np.random.default_rng(3)
    q = rng.normal(size=(40, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True) * (1 + 1e-7 * rng.normal(size=(40, 1)))  # near unit, as stepped
    R = rotation_from_quaternion(q)
    worst = 0.0
    for k in range(len(q)):
        plant.SetPositions(ctx, np.r_[q[k], 0.0, 0.0, 0.0])
        ref = plant.EvalBodyPoseInWorld(ctx, body).rotation().matrix()
        worst = max(worst, float(np.abs(R[k] - ref).max()))
    assert worst <= 1e-15


SEEN = {}


def test_tray_log_equals_the_per_step_monitors(monkeypatch):
    """The tray hand: slide and tilt from the cup's joint coordinates against the former Python monitor
    (systems/tray_object.TrayBottleMonitor, through world poses) and the tray ratio from the logged states
    against the per-step monitor's, on the same run (a move fast enough to take the ratio over 1)."""
    sc = load_or_skip("panda-tray-cup")
    seen = SEEN
    real_tray_log = spatial_cosim.TrayLog

    class Both:
        def __init__(self, builder, plant, cup, period_s):
            tray = plant.GetBodyByName("tray")
            self.real = real_tray_log(builder, plant, cup, period_s)
            mon = builder.AddSystem(TrayBottleMonitor(plant, tray, cup, seated_pose_on_tray()))
            builder.Connect(plant.get_body_poses_output_port(), mon.GetInputPort("body_poses"))
            builder.Connect(plant.get_contact_results_output_port(), mon.GetInputPort("contact_results"))
            self.old = {k: LogVectorOutput(mon.GetOutputPort(k), builder, period_s) for k in ("slide", "tilt")}
            hold = self.hold = builder.AddSystem(PerStepHoldMonitor(plant, cup, TrayContactTerm(sc.cup, sc.gravity_m_s2)))
            builder.Connect(plant.get_body_poses_output_port(), hold.poses)
            builder.Connect(plant.get_body_spatial_velocities_output_port(), hold.vels)
            builder.Connect(plant.get_body_spatial_accelerations_output_port(), hold.accs)
            self.hold_log = LogVectorOutput(hold.ratio_port, builder, period_s)

        def slide_tilt(self, ctx):
            t, slide, tilt = self.real.slide_tilt(ctx)
            seen["slide"] = (slide, self.old["slide"].FindLog(ctx).data())
            seen["tilt"] = (tilt, self.old["tilt"].FindLog(ctx).data()[0])
            return t, slide, tilt

        def ratios(self, ctx, term, start_s):
            t_up, r = self.real.ratios(ctx, term, start_s)
            log = self.hold_log.FindLog(ctx)  # the monitor's ratio after its update at t_k, logged at t_{k+1}
            keep = log.sample_times()[:-1] >= start_s
            seen["ratio"] = (r, log.data()[0, 1:][keep])
            return t_up, r

    monkeypatch.setattr(spatial_cosim, "TrayLog", Both)
    monkeypatch.setattr(spatial_cosim, "TAIL_S", 0.02)
    dq = np.zeros(sc.n_dof)
    dq[0] = 0.6
    r = simulate_spatial(sc, RestThenMove(sc.q_poses_rad[0], dq, 0.0, 0.3))
    assert r["contact_ratio_first_above_1_s"] is not None
    np.testing.assert_allclose(*seen["slide"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(*seen["tilt"], rtol=0, atol=1e-14)
    new, old = seen["ratio"]
    assert len(new) == len(old) > 100
    np.testing.assert_allclose(new, old, rtol=1e-10, atol=0)  # 1.6e-11 seen: near lift-off the ratio magnifies rounding
