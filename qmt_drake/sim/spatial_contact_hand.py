"""The spatial co-simulation's contact hand (`hand.physics: contact`): the part a free body held by physics.

sim/spatial_cosim.simulate_spatial's default hand (`hand.physics: weld`) welds the part to the hand and
declares it detached the first millisecond its required wrench leaves the hand's limit. Here nothing
holds the part but contact and a pull, so a loss is simulated, not declared:

- its build (sim/contact_hand_build.py): the face frame F on the hand, the part P a free body on a
  6-DOF joint from F (gap = -z, slide = |(x, y)|), the magnet's or the suction rim's contact geometry and
  pull, SAP's relaxation time matched to the Hunt-Crossley dissipation.
- point contact, MultibodyPlant's discrete lagged approximation (the planar hands', sim/plant.py) at the
  co-simulation's 1 ms; the arm holds its start for CONTACT_SETTLE_S while the contact takes up the load,
  then plays the plan (times below are from the plan's start).
- the arrival (`arrival_error`): the part may still rock on its rim when the plan's hold at the goal
  (spatial_cosim.TAIL_S) ends, and the arm, under a law without a model of the rocking part, rocks with it
  (UR5 suction at x1.0212, 0.5 ms lagged: +-1.2 mrad at about 2.5 Hz, decaying over about 2 s to a
  steady 0.08 mrad), so the error at one instant is a phase of that oscillation. The run goes on past the
  tail in ARRIVAL_CHUNK_S chunks, the arm holding the goal, until every joint position has varied by less
  than ARRIVAL_STEADY_FRACTION of the arrival tolerance over the last ARRIVAL_WINDOW_S (at most
  ARRIVAL_MAX_WAIT_S; not when the part is already lost), and the arrival error is the largest goal error
  over that last window (steady or not: no phase decides it). The wait is reported (arrival_wait_s,
  arrival_steady); the part must stay held through it.

Monitoring after the run from logged signals (VectorLogSink, no Python system in the loop): the part's
joint state every step (the arrival's wait reads the logged arm state between chunks). Lost ("detached",
qmt_drake/outcome.py) at the first step the gap exceeds LOST_GAP_M or the slide LOST_SLIDE_M; slipped when
held but the final slide exceeds SLIP_TOLERANCE_M.
Diagnostics (`_diagnostics`): the hand's limit ratio (the weld's threshold, the planners' constraint) of
the hand motion this run actually made while the part was held (logged arm state and acceleration
through sc.chain), its largest value and the first time it passed 1: where the threshold would have
declared a loss; for the magnet also the rigid-body hold condition of its contact ring and pull.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import ContactModel, DiscreteContactApproximation
from pydrake.systems.primitives import LogVectorOutput

from qmt_drake.limits.suction import SuctionTerm, cached_grip
from qmt_drake.outcome import ARRIVAL_TOLERANCE_DC_MOTOR_RAD, transfer_outcome
from qmt_drake.sim.contact_hand_build import (
    RIM_DISSIPATION_S_PER_M,
    RIM_STIFFNESS_N_PER_M,
    add_contact_hand,
    add_pull,
    hand_pull,
)
from qmt_drake.sim.spatial_actuation import tracking_report
from qmt_drake.sim.spatial_hold import HandPart
from qmt_drake.sim.spatial_recording import SpatialRecording
from qmt_drake.systems.payload import allow_contact

CONTACT_SETTLE_S = 0.2  # the arm holds the start while the contact takes up the part's load
LOST_GAP_M = 5.0e-3  # lost: the part's face more than this from the hand's face ...
LOST_SLIDE_M = 10.0e-3  # ... or slid more than this along it
SLIP_TOLERANCE_M = 5.0e-3  # held to the end but ended further than this from its seat: slipped
# the arrival (module docstring): steady when every joint varied less than this fraction of the tolerance ...
ARRIVAL_STEADY_FRACTION = 0.1
ARRIVAL_WINDOW_S = 0.5  # ... over this window (longer than the rocking's period, 0.3-0.5 s) ...
ARRIVAL_CHUNK_S = 0.1  # ... checked after each such chunk past the plan's tail ...
ARRIVAL_MAX_WAIT_S = 4.0  # ... for at most this long
# what the contact hand's runs mean (studies key stored runs by it): 2 = SAP's relaxation time matched to the
# Hunt-Crossley dissipation and the arrival measured steady (session 18); 1 = before
CONTACT_HAND_REVISION = 2


def classify_contact_run(t, q_part, lost_gap_m: float = LOST_GAP_M, lost_slide_m: float = LOST_SLIDE_M):
    """From the logged part joint positions (7, S) [quaternion w x y z, p_FP] at times t (S,): (lost word or
    None, time lost, gap (S,) [m], slide (S,) [m], tilt (S,) [rad])."""
    gap, slide = -q_part[6], np.hypot(q_part[4], q_part[5])
    w = np.abs(q_part[0]) / np.linalg.norm(q_part[:4], axis=0)
    tilt = 2.0 * np.arccos(np.clip(w, 0.0, 1.0))
    lost = (gap > lost_gap_m) | (slide > lost_slide_m)
    if lost.any():
        return "detached", float(t[int(np.argmax(lost))]), gap, slide, tilt
    return None, None, gap, slide, tilt


class ContactHand(HandPart):
    """The contact hand part (module docstring), for spatial_cosim.assemble: the part held by contact and a
    pull, its loss simulated. grip: the suction cup's GripModel (the co-simulation's finer rim: its
    rim_points, radius, friction, pull). rim_*: the suction rim's total stiffness [N/m] and Hunt-Crossley
    dissipation [s/m]; coil_current_A: the magnet's current instead of the calibrated one. Result keys as
    the weld's, plus the pull at the seat, the contact's gap, slide and tilt and the threshold diagnostic
    (max_grip_ratio_while_held: the threshold's largest ratio on this run's hand motion while held)."""

    kind, settle_s, monitor, approximation = "spatial_contact", CONTACT_SETTLE_S, None, DiscreteContactApproximation.kLagged

    def __init__(self, sc, grip=None, *, rim_stiffness_N_per_m: float = RIM_STIFFNESS_N_PER_M,
                 rim_dissipation_s_per_m: float = RIM_DISSIPATION_S_PER_M, coil_current_A: float | None = None) -> None:
        if sc.hand_kind not in ("magnet", "suction"):
            raise ValueError(f"contact hand: hand kind {sc.hand_kind!r} is neither magnet nor suction")
        self.sc, self.grip, self.coil_current_A = sc, grip, coil_current_A
        self.rim = (rim_stiffness_N_per_m, rim_dissipation_s_per_m)

    def configure(self, plant) -> None:  # (after its approximation, kLagged: the planar hands')
        plant.set_contact_model(ContactModel.kPoint)

    def add(self, builder, plant, H) -> None:
        self.pull, self.current = hand_pull(self.sc, self.grip, self.coil_current_A)
        (self.scene_graph, self.part, self.joint, self.spec,
         self.relaxation_time_s) = add_contact_hand(builder, plant, H, self.sc, self.grip, *self.rim, self.pull)

    def recording(self, builder, plant, arm):
        return SpatialRecording.add(builder, plant, arm, self.scene_graph)

    def connect(self, builder, plant, H, rec, continuous: bool) -> None:
        self.connect_scene_graph(builder, plant, rec)
        allow_contact(plant, self.scene_graph, H.body(), self.part)
        # the ideal actuator's controller integrates its error (continuous state); the dc_motor drive has none
        add_pull(builder, plant, self.joint, self.spec, self.grip, self.current, continuous=continuous)

    def add_monitor(self, builder, plant, arm, h: float) -> None:
        self.n_arm = plant.num_positions(arm)
        self.loggers = {"part_state": LogVectorOutput(plant.get_state_output_port(self.part.model_instance()),
                                                      builder, h),
                        "arm_acceleration": LogVectorOutput(plant.get_generalized_acceleration_output_port(arm),
                                                            builder, h),
                        "arm_state_for_arrival": LogVectorOutput(plant.get_state_output_port(arm), builder, h)}

    def advance(self, sim, diagram, t_end: float) -> None:
        """To the tail's end, then on while the arm is not steady (module docstring, the arrival)."""
        sim.AdvanceTo(t_end)
        ctx = sim.get_context()
        wait = 0.0
        while wait < ARRIVAL_MAX_WAIT_S - 1e-9 and not self._steady(ctx):
            wait = min(wait + ARRIVAL_CHUNK_S, ARRIVAL_MAX_WAIT_S)
            sim.AdvanceTo(t_end + wait)
        self.arrival_wait_s = wait

    def _steady(self, ctx) -> bool:
        """The part lost (no arrival to wait for), or every arm joint within ARRIVAL_STEADY_FRACTION of the
        arrival tolerance over the last ARRIVAL_WINDOW_S."""
        part = self.loggers["part_state"].FindLog(ctx)
        if classify_contact_run(part.sample_times(), part.data()[:7])[0] is not None:
            return True
        log = self.loggers["arm_state_for_arrival"].FindLog(ctx)
        t, q = log.sample_times(), log.data()[:self.n_arm]
        w = q[:, t >= t[-1] - ARRIVAL_WINDOW_S + 1e-9]
        return bool((w.max(axis=1) - w.min(axis=1)).max() < ARRIVAL_STEADY_FRACTION * ARRIVAL_TOLERANCE_DC_MOTOR_RAD)

    def ports(self, plant) -> dict:
        return {"part_state": plant.get_state_output_port(self.part.model_instance())}

    def finish(self, ctx, plant, H, err, logs, drive, traj, t_end) -> dict:
        sc = self.sc
        log = self.loggers["part_state"].FindLog(ctx)
        t = log.sample_times() - CONTACT_SETTLE_S
        lost, lost_at, gap, slide, tilt = classify_contact_run(t, log.data()[:7])
        moving = t >= 0.0
        held = moving & (t < lost_at) if lost is not None else moving
        slipped = lost is None and bool(slide[-1] > SLIP_TOLERANCE_M)
        err_now, err = err, arrival_error(logs["arm_state"].FindLog(ctx), logs["desired_state"].FindLog(ctx), sc.n_dof)
        outcome = transfer_outcome(lost, slipped, err, ARRIVAL_TOLERANCE_DC_MOTOR_RAD)
        threshold = _diagnostics(sc, self.grip, self.spec, self.pull, logs["arm_state"].FindLog(ctx),
                                 self.loggers["arm_acceleration"].FindLog(ctx), lost_at)
        return {"outcome": outcome, "held": outcome == "carried", "lost_at_s": lost_at, "hand_physics": "contact",
                "final_goal_error_rad": err, "goal_error_at_end_rad": err_now, "arrival_wait_s": self.arrival_wait_s,
                "arrival_steady": self.arrival_wait_s < ARRIVAL_MAX_WAIT_S - 1e-9 or self._steady(ctx),
                "relaxation_time_s": self.relaxation_time_s, "duration_s": traj.duration_s, "pull_N": self.pull,
                "max_gap_while_held_m": float(gap[held].max(initial=0.0)),
                "max_slide_while_held_m": float(slide[held].max(initial=0.0)),
                "max_tilt_while_held_rad": float(tilt[held].max(initial=0.0)),
                "final_slide_on_face_m": float(slide[-1]),
                "final_gap_m": float(gap[-1]), "max_slide_m": float(slide[moving].max(initial=0.0)),
                "max_gap_m": float(gap[moving].max(initial=0.0)),  # the loss included (margin_runs.spatial_margin)
                "part_distance_from_cup_at_end_m": float(np.linalg.norm(log.data()[4:7, -1])),
                "max_grip_ratio_while_held": threshold["threshold_max_ratio"],  # the weld's key: its threshold, held
                **threshold, "actuator": "ideal" if drive is None else "dc_motor",
                **tracking_report(logs, ctx, traj.duration_s + CONTACT_SETTLE_S, sc, drive)}


def arrival_error(arm_log, desired_log, n: int) -> float:
    """The arrival error [rad] (module docstring): the largest |q_goal - q| of the arm's n joints over the
    run's last ARRIVAL_WINDOW_S, q_goal the reference's last sample."""
    t = arm_log.sample_times()
    w = t >= t[-1] - ARRIVAL_WINDOW_S + 1e-9
    goal = desired_log.data()[:n, -1:]
    return float(np.abs(goal - arm_log.data()[:n, w]).max())


def _over(name: str, ratio, t) -> dict:
    over = np.flatnonzero(ratio > 1.0)
    return {f"{name}_max_ratio": float(np.max(ratio, initial=0.0)),
            f"{name}_first_above_1_s": float(t[over[0]]) if len(over) else None}


def _diagnostics(sc, grip, spec, pull_N: float, arm_log, acc_log, lost_at_s) -> dict:
    """The weld's threshold on this run's hand motion while the part was held (from the plan's start to
    the loss): the hand term's ratio (the planners' limit; the co-simulation's finer grip for a cup) of a
    part moving rigidly with the hand, from the logged arm state and acceleration through sc.chain; its
    largest value and the first time it passed 1. For the magnet also `ring_grip`: the suction cup's
    contact-stability set (limits/suction.GripModel) of the magnet's own contact ring (its points, radius
    and friction, a pyramid of 8 edges) with the pull at the seat: the rigid-body hold condition of the
    contact model, normal force included, which the face-plane moment limit leaves out."""
    t = arm_log.sample_times() - CONTACT_SETTLE_S
    n = sc.n_dof
    x, a = arm_log.data(), acc_log.data()
    k = (t >= 0.0) & (t < (np.inf if lost_at_s is None else lost_at_s))
    state = sc.chain.evaluate(x[:n, k].T, x[n:, k].T, a[:, k].T)
    out = _over("threshold", np.max(sc.hand_term(grip).columns(state), axis=1), t[k])
    if spec is not None:
        ring = cached_grip(spec.contact_radius_m, pull_N, spec.friction, face_normal=sc.face_axis,
                           rim_points=spec.n_contact_points, pyramid_edges=8)
        out.update(_over("ring_grip", SuctionTerm(ring, sc.body, sc.gravity_m_s2).columns(state)[:, 0], t[k]))
    return out
