"""The spatial co-simulation's hold check with no Python system in the loop (sim/spatial_cosim.py).

The check only observes until the part is lost, so instead of a Python system called every plant step
(the former HoldMonitor, a periodic discrete update), `HoldLog` logs every step in C++ (one
VectorLogSink behind a Multiplexer) the free part's state [q_WP (quaternion w x y z, position); w_WP,
v_WP] and its generalized acceleration [alpha_WP; a_WP] (world axes: the part is a free body, so these
are its spatial velocity and acceleration at its origin, the hand frame H's origin while the weld holds),
and `ratios` evaluates the hand's limit term on all logged steps at once (`term.columns`, the batched
evaluation the planners' re-check uses: ONE implementation of the contact wrench and the grip rows).

Samples: the log holds at t_j = j h the state x_j the plant reached at t_j and its sampled acceleration
of the step into t_j. The former monitor's update at t_k saw x_{k+1} (Drake steps the discrete plant in
an unrestricted update, dispatched before the discrete updates of the same time), so the log's sample
j is that update's at t_{j-1}: samples 1 ... N are checked and a detachment seen in sample j is
reported at t_{j-1}, as before. The rotation comes
from the logged quaternion by Drake's formula (RotationMatrix(Quaternion): 2 / |q|^2 scaling, so a
quaternion off unit length by rounding gives Drake's matrix, to a few units in the last place: Eigen
rounds in another order), and numpy's batched products may round the last bit differently from a
one-sample call: the ratio agrees with the per-step monitor's to ~1e-15 relative, the detach time, the
outcome and every simulated state exactly (tests/test_cosim_floor.py runs both).

`run_until_detached`: the simulator advances in CHECK_CHUNK_S chunks and, after each, the samples
logged since the last check are evaluated (every step: a decimated check could miss the one-step
excursion of a TOPP-RA plan's jump in joint acceleration). The former monitor stopped the run at t_j,
the weld on until x_j, and let the part go from there. So at each chunk's start the time and state are
copied aside (a few hundred numbers, the plant's sampled outputs included); when a chunk reveals a
detachment in sample j, the run goes back to that copy (logs cut to before it), advances to t_j with the
weld still on, switches the weld off and runs to the end: the states, the outcome and the detach time
are those of the per-step monitor's run (the controller's integral of the error, the only continuous
state, is integrated in other pieces, and its gain is zero).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.analysis import InitializeParams
from pydrake.systems.primitives import LogVectorOutput, Multiplexer, VectorLogSink

from qmt_drake.limits.clearance import clearance_of_states
from qmt_drake.outcome import with_collision
from qmt_drake.systems.payload import six_dof_joint_of
from qmt_drake.systems.scalar_ops import NUMPY
from qmt_drake.systems.transfer_monitor import motion_from_joint

CHECK_CHUNK_S = 0.25  # how often the logged steps are checked; a detachment costs at most one chunk re-run


def rotation_from_quaternion(q_wxyz) -> np.ndarray:
    """(S, 3, 3) rotation matrices of (S, 4) quaternions [w, x, y, z], by Drake's formula
    (math::RotationMatrix(Eigen::Quaternion): scaled by 2 / |q|^2, exact for a non-unit quaternion)."""
    q = np.atleast_2d(np.asarray(q_wxyz, float))
    w, x, y, z = q.T
    s = 2.0 / (x * x + y * y + z * z + w * w)
    sx, sy, sz = s * x, s * y, s * z
    swx, swy, swz = sx * w, sy * w, sz * w
    sxx, sxy, sxz, syy, syz, szz = sx * x, sy * x, sz * x, sy * y, sz * y, sz * z
    return np.stack([1.0 - syy - szz, sxy - swz, sxz + swy,
                     sxy + swz, 1.0 - sxx - szz, syz - swx,
                     sxz - swy, syz + swx, 1.0 - sxx - syy], axis=1).reshape(-1, 3, 3)


def step_into_sample(plant, data: np.ndarray, n_state: int) -> np.ndarray:
    """The logged [state; acceleration] columns with sample j's acceleration that of the step INTO x_j.
    That is what a discrete plant's sampled acceleration port gives; with live ports (a drive whose law
    has a state of its own switches them on: spatial_actuation.SpatialMotorDrive.prepare_plant) the port
    gives the step OUT of x_j, so the accelerations are moved one sample later (sample 0 keeps its own)."""
    if plant.has_sampled_output_ports() or data.shape[1] < 2:
        return data
    out = data.copy()
    out[n_state:, 1:] = data[n_state:, :-1]
    return out


class HoldLog:
    """Every plant step, the free part's state (13) and generalized acceleration (6) side by side."""

    def __init__(self, builder, plant, part_body, term, time_step_s: float) -> None:
        inst = part_body.model_instance()
        if plant.num_positions(inst) != 7 or plant.num_velocities(inst) != 6:
            raise ValueError("HoldLog: the part must be a free body alone in its model instance")
        self.term, self.plant = term, plant
        mux = builder.AddNamedSystem("part_motion", Multiplexer([13, 6]))
        builder.Connect(plant.get_state_output_port(inst), mux.get_input_port(0))
        builder.Connect(plant.get_generalized_acceleration_output_port(inst), mux.get_input_port(1))
        self.logger = LogVectorOutput(mux.get_output_port(), builder, time_step_s)

    def ratios(self, root_context, start: int = 0, stop: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(times, ratios) of the logged samples start:stop: the hand term's largest column."""
        log = self.logger.FindLog(root_context)
        d = step_into_sample(self.plant, log.data(), 13)
        t, d = log.sample_times()[start:stop], d[:, start:stop]
        state = {"rotation": rotation_from_quaternion(d[0:4].T), "angular_velocity_rad_s": d[7:10].T,
                 "angular_acceleration_rad_s2": d[13:16].T, "linear_acceleration_m_s2": d[16:19].T}
        if len(t) == 0:
            return t, np.zeros(0)
        return t, np.max(self.term.columns(state), axis=1)


class TrayLog:
    """The tray hand's per-step log (sim/spatial_cosim.simulate_tray_hand): the whole plant's state and
    generalized acceleration every step, in C++. After the run: the cup's slide and tilt on the tray from
    its 6-DOF joint's coordinates (its pose in the tray frame; tilt by transfer_monitor.motion_from_joint,
    as the planar co-simulation's log summary), and the tray term's ratio of the cup's contact wrench
    from its world pose, spatial velocity and acceleration, which Drake computes for each logged state
    on a scratch context (no closed loop runs Python: this pass is after it, once per sample). The
    ratios equal the former per-step monitor's to ~1e-11 relative (the tray ratio divides by the normal
    force: near lift-off it magnifies the last bits of the acceleration; tests/test_cosim_floor.py)."""

    def __init__(self, builder, plant, cup_body, time_step_s: float) -> None:
        self.plant, self.cup = plant, cup_body
        self.nx, nv = plant.num_multibody_states(), plant.num_velocities()
        self.q0 = six_dof_joint_of(plant, cup_body).position_start()
        mux = builder.AddNamedSystem("tray_motion", Multiplexer([self.nx, nv]))
        builder.Connect(plant.get_state_output_port(), mux.get_input_port(0))
        builder.Connect(plant.get_generalized_acceleration_output_port(), mux.get_input_port(1))
        self.logger = LogVectorOutput(mux.get_output_port(), builder, time_step_s)

    def slide_tilt(self, root_context) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times (S,), slide (2, S) [m] of the cup's base from its seat at the tray frame's origin, tilt (S,) [rad])."""
        log = self.logger.FindLog(root_context)
        q = log.data()[self.q0:self.q0 + 7]
        return log.sample_times(), q[4:6].copy(), motion_from_joint(tuple(q), NUMPY)[1]

    def ratios(self, root_context, term, start_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(update times, ratios): sample j as the former monitor's update at t_{j-1} (HoldLog's
        samples), for the updates at or after start_s."""
        log = self.logger.FindLog(root_context)
        t, d = log.sample_times(), step_into_sample(self.plant, log.data(), self.nx)
        j = np.flatnonzero(t[:-1] >= start_s) + 1
        ctx = self.plant.CreateDefaultContext()
        i = int(self.cup.index())
        R, w, al, a = (np.zeros((len(j), 3, 3)), np.zeros((len(j), 3)), np.zeros((len(j), 3)), np.zeros((len(j), 3)))
        for m, k in enumerate(j):
            # Drake's sampled body acceleration of the step into x_k: the step's vdot through the
            # kinematics of the state it started from, x_{k-1} (its J vdot + Jdot v)
            self.plant.SetPositionsAndVelocities(ctx, d[:self.nx, k - 1])
            A = self.plant.CalcSpatialAccelerationsFromVdot(ctx, d[self.nx:, k])[i]
            al[m], a[m] = A.rotational(), A.translational()
            self.plant.SetPositionsAndVelocities(ctx, d[:self.nx, k])
            R[m] = self.plant.EvalBodyPoseInWorld(ctx, self.cup).rotation().matrix()
            w[m] = self.plant.EvalBodySpatialVelocityInWorld(ctx, self.cup).rotational()
        state = {"rotation": R, "angular_velocity_rad_s": w, "angular_acceleration_rad_s2": al,
                 "linear_acceleration_m_s2": a}
        return t[j - 1], (np.max(term.columns(state), axis=1) if len(j) else np.zeros(0))


def _cut_logs(diagram, root_context, before_s: float) -> None:
    """Drop every logged sample at or after `before_s` (every VectorLogSink of the diagram)."""
    for sys in diagram.GetSystems():
        if not isinstance(sys, VectorLogSink):
            continue
        log = sys.GetMutableLog(sys.GetMyMutableContextFromRoot(root_context))
        t = log.sample_times()
        keep = t < before_s
        if keep.all():
            continue
        times, data = t[keep].copy(), log.data()[:, keep].copy()
        log.Clear()
        for k in range(len(times)):
            log.AddData(times[k], data[:, k])


def run_until_detached(sim, diagram, hold: HoldLog, t_end_s: float, release) -> tuple[bool, float | None, float]:
    """Advance sim to t_end_s; at the first logged state whose hold ratio exceeds 1 call release(root_context)
    (module docstring). Returns (detached, t_detach_s, largest ratio while held: up to and including the
    detaching state)."""
    ctx = sim.get_mutable_context()
    sim.Initialize()  # what the first AdvanceTo would do; the copies below start from initialized states
    saved = diagram.CreateDefaultContext()
    checked, largest = 1, -np.inf  # the first sample not yet checked (x_0 is the start, not a step's result)
    t = ctx.get_time()
    while t < t_end_s:
        saved.SetTimeStateAndParametersFrom(ctx)
        t_start, t = t, min(t + CHECK_CHUNK_S, t_end_s)
        sim.AdvanceTo(t)
        times = hold.logger.FindLog(ctx).sample_times()
        if t >= t_end_s and times[-1] != t_end_s:
            raise RuntimeError("run_until_detached: the final time is not a plant step time")
        _, r = hold.ratios(ctx, checked, len(times))
        over = np.flatnonzero(r > 1.0)
        if len(over) == 0:
            largest = max(largest, float(r.max(initial=-np.inf)))
            checked = len(times)
            continue
        j = checked + int(over[0])
        largest = max(largest, float(r[:over[0] + 1].max()))
        t_lost, t_j = float(times[j - 1]), float(times[j])  # the former monitor's update time, and x_j's
        if t_j < t:  # back to the chunk's start: the weld holds until x_j is reached
            ctx.SetTimeStateAndParametersFrom(saved)
            _cut_logs(diagram, ctx, t_start)
            sim.Initialize(InitializeParams(suppress_initialization_events=True))  # logs t_start again
            sim.AdvanceTo(t_j)
        release(ctx)
        sim.AdvanceTo(t_end_s)
        return True, t_lost, largest
    return False, None, largest


COLLISION_CHECK_EVERY = 5  # logged 1 ms states: every 5th, then state by state near the minima (limits/clearance.py)


def collision_check(sc, logs, root_context, outcome: str, lost_at_s, settle_s: float = 0.0) -> tuple[str, dict]:
    """After the run (no system in the loop): the clearance of the logged arm and its carried part from the
    scenario's obstacles until the part was lost; (outcome, facts) with outcome 'collided' when it went
    below 0 first (outcome.with_collision; collided_at_s and collision_pair: the first touch). The obstacles
    push nothing in the simulated dynamics: the first touch ends the transfer. No obstacles: (outcome, {})."""
    if not sc.obstacles:
        return outcome, {}
    log = logs["arm_state"].FindLog(root_context)
    t = log.sample_times() - settle_s
    keep = (t >= 0.0) & (t <= (np.inf if lost_at_s is None else lost_at_s))
    c = clearance_of_states(sc, t[keep], log.data()[:sc.n_dof, keep].T, every=COLLISION_CHECK_EVERY)
    first = c.pop("first_contact")
    at = None if first is None else first["time_s"]
    return with_collision(outcome, at, lost_at_s), {**c, "collided_at_s": at,
                                                    "collision_pair": None if first is None else first["pair"]}


class HandPart:
    """What a spatial hand is to spatial_cosim.assemble (the weld, the contact hand, the tray): it
    configures the plant, adds its bodies (add), its recording and connections, its monitor and its
    exported ports, seats the part (set_default, start), advances the run (advance) and classifies it
    (finish). The defaults here serve a part whose seat is its joint's default and whose run needs no
    event: advance to the end."""

    def set_default(self, plant, H) -> None:  # the part's seat is its joint's default already
        pass

    def start(self, plant, pctx, H) -> None:
        pass

    def welded_part(self):  # a free part held by a weld constraint (WeldHand), seated loaded at the start
        return None

    def advance(self, sim, diagram, t_end: float) -> None:
        sim.AdvanceTo(t_end)

    def connect_scene_graph(self, builder, plant, rec) -> None:
        """The plant's geometry wired to this part's own SceneGraph (a contact hand, the tray), and the
        recording drawn from it."""
        sg = self.scene_graph
        builder.Connect(plant.get_geometry_pose_output_port(), sg.get_source_pose_port(plant.get_source_id()))
        builder.Connect(sg.get_query_output_port(), plant.get_geometry_query_input_port())
        if rec is not None:
            rec.connect(builder, plant, geometry_connected=True)
