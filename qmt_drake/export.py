"""A plan (of any arm: planar or spatial) as a controller sees it: a stream of samples at the controller's rate, written as CSV
or a ROS 2 JointTrajectory, and re-checked as the controller interpolates it.

    report = export_plan(sc, plan, fmt="ros2", rate_hz=125, out="plan.yaml", interp="linear")

The stream: samples at t_k = k / rate, k = 0 .. ceil(T rate), every one uniformly spaced (the ones at or
past the plan's end T hold the end pose at rest), positions (rad) and, in the ROS 2 form, the
velocities (rad/s) and accelerations (rad/s^2) of the plan at t_k and time_from_start {sec, nanosec}.

The controller's interpolation between the samples, each a trajectory with spatial_trajectory's
sample() protocol so the scenario's own limit check (spatial_trajectory.check: joint speed,
acceleration, torque with the carried part, the hand's ratio) and the co-simulation take it as they
take a plan:

- `cubic`: the cubic Hermite through the samples' positions and velocities (what ROS 2's
  joint_trajectory_controller does when velocities are given): Drake's CubicHermite, a PolynomialTrajectory;
- `linear` (`LinearStream`): positions joined by straight lines, so the velocity is each interval's
  chord slope and steps at every sample; the acceleration is that step over one stream period,
  (v_k - v_(k-1)) / dt, held over interval k (what a controller differentiating its reference once
  a period sees; a step is no finite acceleration at any finer scale), and the stop at the end
  (-v_last / dt) at the last sample.

The check samples the interpolated stream at CHECK_FACTOR (10) times the stream rate, or at the
scenario's re-check rate if that is finer, and states its peak jerk there (qmt_drake/jerk.py). A scenario
with obstacles also gets the interpolated stream's clearance (limits/clearance.py, at its re-check rate): a
stream between sparse samples cuts corners (the UR5 bin task's 1 Hz linear stream keeps every limit and
puts the box 81 mm into a tote's wall), and a stream that collides does not hold.
`hold` (--hold) first slows the plan (TimeScaled) by the time scale at which its stream keeps the limits.
"""

from __future__ import annotations

import math
import os

import numpy as np
import yaml
from pydrake.trajectories import PiecewisePolynomial

from qmt_drake.api_checks import number, path_arg
from qmt_drake.budgets import Estimate, check_budget
from qmt_drake.errors import QmtInputError
from qmt_drake.jerk import peak_jerk
from qmt_drake.limits.clearance import clearance
from qmt_drake.outputs import check_output_path, write_text_atomic
from qmt_drake.plan import Plan, a_kind, recheck
from qmt_drake.plan_files import scenario_kind_of
from qmt_drake.planners.spatial_trajectory import TimeScaled, check
from qmt_drake.timescale import smallest_holding_scale
from qmt_drake.trajectory import JointTrajectory, PolynomialTrajectory

FORMATS = ("ros2", "csv")
INTERPOLATIONS = ("linear", "cubic")
CHECK_FACTOR = 10
# a spatial check sample (UR5, 6 joints: chain dynamics and the suction rows): 39 us, 2.8 kB in the batch (measured
# by `check` on 3974 / 39722 samples of a TOPP-RA plan); the stream and the plan are checked, the jerk sampled: x3
CHECK_S_PER_SAMPLE = 3 * 40e-6
CHECK_BYTES_PER_SAMPLE = 3e3
CLEARANCE_S_PER_SAMPLE = 0.5e-3  # Drake's signed distance of the UR5 and its box from two totes: ~0.4 ms a sample
HOLD_MAX_SCALE = 3.0  # --hold: the slowest time scale tried
HOLD_REL_TOL = 1e-3


def stream_times(duration_s: float, rate_hz: float) -> np.ndarray:
    """t_k = k / rate_hz, k = 0 .. ceil(duration rate) (the last at or past the end)."""
    n = int(math.ceil(duration_s * rate_hz - 1e-9))
    return np.arange(n + 1) / rate_hz


def stream_samples(traj, rate_hz: float):
    """(t, q, qd, qdd) of the stream (module docstring); past the end: the end pose at rest."""
    t = stream_times(traj.duration_s, rate_hz)
    q, qd, qdd = traj.sample(np.minimum(t, traj.duration_s))
    after = t >= traj.duration_s
    qd[after], qdd[after] = 0.0, 0.0
    return t, q, qd, qdd


class LinearStream(JointTrajectory):
    """Positions joined by straight lines (module docstring), sample() as spatial_trajectory's kinds (clipped
    into [0, T], the stop at T: holds_end_value) and evaluate() on the stream's samples as breakpoints (the
    planar limit report and spatial_trajectory.between_pieces refine between them)."""

    holds_end_value = True

    def __init__(self, t, q) -> None:
        self.t, self.q = np.asarray(t, float), np.asarray(q, float)
        if len(self.t) < 2:
            raise QmtInputError("a stream needs at least 2 samples; raise the rate")
        self.dt = float(self.t[1] - self.t[0])
        self.v = np.diff(self.q, axis=0) / self.dt  # interval k's velocity
        self.a = np.diff(np.vstack([np.zeros_like(self.v[:1]), self.v]), axis=0) / self.dt  # its step at t_k
        self.duration_s = float(self.t[-1])
        self.breakpoints_s = self.t
        self.n_dof = self.q.shape[1]

    def evaluate(self, t_s, t_piece_s):
        """Interval k's line, k the interval holding t_piece_s; at rest (t_piece_s >= the end) the stop."""
        t = np.clip(np.atleast_1d(np.asarray(t_s, float)), 0.0, self.duration_s)
        tp = np.broadcast_to(t_piece_s, t.shape)
        k = np.clip(np.floor(tp / self.dt + 1e-9).astype(int), 0, len(self.v) - 1)
        q = self.q[k] + self.v[k] * (t - self.t[k])[:, None]
        qd, qdd = self.v[k].copy(), self.a[k].copy()
        rest = tp >= self.duration_s
        qd[rest], qdd[rest] = 0.0, -self.v[-1] / self.dt
        return q, qd, qdd

    def sample(self, t):
        t = np.clip(np.atleast_1d(np.asarray(t, float)), 0.0, self.duration_s)
        k = np.clip(np.floor(t / self.dt + 1e-9).astype(int), 0, len(self.v) - 1)
        q = self.q[k] + self.v[k] * (t - self.t[k])[:, None]
        qd, qdd = self.v[k].copy(), self.a[k].copy()
        end = t >= self.duration_s
        qd[end], qdd[end] = 0.0, -self.v[-1] / self.dt
        return q, qd, qdd


def interpolated(t, q, qd, interp: str, planar: bool = False):
    """The controller's interpolation of the stream: LinearStream or the cubic Hermite (the one
    PolynomialTrajectory; sampled the spatial way, clipped into [0, T], for a spatial target)."""
    if interp == "linear":
        return LinearStream(t, q)
    if interp == "cubic":
        pp = PiecewisePolynomial.CubicHermite(t, q.T, qd.T)
        return PolynomialTrajectory(pp, holds_end_value=not planar)
    raise QmtInputError(f"--interp {interp!r}: give {'|'.join(INTERPOLATIONS)}")


def _planar(sc) -> bool:
    """A planar scenario (config Scenario: its LimitSet, the one planar re-check); else a spatial one."""
    return hasattr(sc, "limit_set")


def _own_check(sc) -> bool:
    """A target that brings its own stream check (energy/stream.EnergyStreamTarget: the energy-time arm's
    joint torques), with its joint_names and recheck_rate_hz and no jerk limit."""
    return hasattr(sc, "stream_check")


def own_recheck_rate(sc) -> float:
    return sc.sampling.check_rate_hz if _planar(sc) else sc.recheck_rate_hz


def joint_names(sc) -> list[str]:
    return list(sc.arm.joint_names) if _planar(sc) else list(sc.joint_names)


def limit_check(sc, traj, rate_hz: float) -> dict:
    """The scenario's own re-check of traj at rate_hz as {'max', 'binding', each term's peak ratio}: the
    spatial one (spatial_trajectory.check) or the planar LimitSet's (plan.recheck: every local maximum
    refined between the samples; a joint leaving its range reads as an infinite 'joint_range' ratio)."""
    if _own_check(sc):
        return sc.stream_check(traj, rate_hz)
    if not _planar(sc):
        return check(sc, traj, rate_hz)
    rep = recheck(sc, traj, rate_hz)
    out = {k: float(v) for k, v in rep.peak_ratios.items()}
    if not rep.joint_range_ok:
        out["joint_range"] = math.inf
    binding = max(out, key=out.get) if out else "none"
    return {**out, "max": out.get(binding, 0.0), "binding": binding,
            "refined_local_maxima": rep.refined_local_maxima}


def stream_jerk(sc, traj, rate_hz: float) -> dict:
    """peak_jerk against the scenario's jerk limit; a planar or energy-time scenario states none (ratio None)."""
    if not (_planar(sc) or _own_check(sc)):
        return peak_jerk(sc, traj, rate_hz)
    n = max(int(math.ceil(traj.duration_s * rate_hz)), 2)
    t = np.linspace(0.0, traj.duration_s, n + 1)
    j = np.abs(np.diff(traj.sample(t)[2], axis=0)).max(axis=0) / (t[1] - t[0])
    return {"peak_jerk_rad_s3": j, "peak_jerk_ratio": None, "jerk_rate_hz": float(rate_hz)}


def check_rate(sc, rate_hz: float) -> float:
    return max(CHECK_FACTOR * rate_hz, own_recheck_rate(sc))


def check_stream_options(fmt: str, rate_hz, interp: str) -> None:
    """One line for a bad format, interpolation or rate (before anything is loaded)."""
    if fmt not in FORMATS:
        raise QmtInputError(f"--format {fmt!r}: give {'|'.join(FORMATS)} (ros2: a JointTrajectory YAML)")
    if interp not in INTERPOLATIONS:
        raise QmtInputError(f"--interp {interp!r}: give {'|'.join(INTERPOLATIONS)}")
    number(rate_hz, "--rate", positive=True, fix="give the controller's rate in Hz (UR: 125 or 500, Franka: 1000)")


def _obstacles(sc) -> bool:
    return bool(getattr(sc, "obstacles", ()))  # spatial scenarios with world.obstacles (planar arms have none)


def check_export_inputs(sc, duration_s: float, fmt: str, rate_hz, interp: str, *, allow_large: bool = False) -> None:
    """check_stream_options, a rate that samples the plan, then the budget of the stream's check
    (budgets.check_budget) over the stream's own length (up to one period past the plan's end)."""
    check_stream_options(fmt, rate_hz, interp)
    if 1.0 / rate_hz > duration_s:  # the stream is the start and the end pose: the plan's path between is gone
        raise QmtInputError(f"--rate {rate_hz:g}: one period ({1.0 / rate_hz:.3g} s) is longer than the {duration_s:.3g} s "
                            "plan, so the stream would hold only its start and end pose; give the controller's rate "
                            "(125 to 1000 Hz typical)")
    end_s = math.ceil(duration_s * rate_hz - 1e-9) / rate_hz  # stream_times' last sample, not its array (1e9 Hz)
    n = end_s * check_rate(sc, rate_hz)
    seconds = n * CHECK_S_PER_SAMPLE + (end_s * own_recheck_rate(sc) * CLEARANCE_S_PER_SAMPLE if _obstacles(sc) else 0.0)
    check_budget(Estimate(n * CHECK_BYTES_PER_SAMPLE, seconds,
                          f"export at {rate_hz:g} Hz of a {duration_s:.3g} s plan ({n:.3g} check samples at "
                          f"{check_rate(sc, rate_hz):g} Hz)", "give the controller's rate (125 to 1000 Hz typical)"),
                 allow_large=allow_large)


def check_export_call(sc, plan, out, hold, allow_large) -> None:
    """export_plan's objects from a Python caller, one line each (a name for sc, a plan file's path for plan,
    an int for out, a plan of another scenario reached an AttributeError or a numpy broadcast error)."""
    target = getattr(sc, "E", sc) if _own_check(sc) else sc  # energy/stream.EnergyStreamTarget: its Experiment
    if isinstance(sc, (str, bytes, os.PathLike)):
        raise QmtInputError(f"export_plan: scenario {sc!r} is a name; pass load_scenario({str(sc)!r})")
    kind = scenario_kind_of(target)
    if not isinstance(plan, Plan):
        raise QmtInputError(f"export_plan: plan {plan!r:.60} is not a Plan; pass plan_with(...) or load_plan(PATH)")
    if plan.scenario_kind != kind or getattr(plan.scenario, "name", None) != sc.name:
        raise QmtInputError(f"export_plan: the {plan.method} plan is {a_kind(plan.scenario_kind)} plan for scenario "
                            f"{getattr(plan.scenario, 'name', '?')}, not for {a_kind(kind)} scenario {sc.name}")
    path_arg(out, "export_plan: out", "stream file")
    check_output_path(out, "export_plan: out")
    for name, flag in (("hold", hold), ("allow_large", allow_large)):
        if not isinstance(flag, bool):
            raise QmtInputError(f"export_plan: {name} {flag!r} must be True or False")


def ros2_joint_trajectory(joint_names, t, q, qd, qdd) -> dict:
    """A trajectory_msgs/JointTrajectory mapping (ROS 2 field names)."""
    sec = np.floor(t + 1e-12).astype(int)
    nsec = np.round((t - sec) * 1e9).astype(int)
    carry = nsec >= 1_000_000_000
    sec, nsec = sec + carry, np.where(carry, nsec - 1_000_000_000, nsec)
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""}, "joint_names": list(joint_names),
            "points": [{"positions": q[k].tolist(), "velocities": qd[k].tolist(), "accelerations": qdd[k].tolist(),
                        "effort": [], "time_from_start": {"sec": int(sec[k]), "nanosec": int(nsec[k])}}
                       for k in range(len(t))]}


def write_stream(path, fmt: str, joint_names, t, q, qd, qdd) -> None:
    """The stream as CSV (time_s and the joint names, rad) or a ROS 2 JointTrajectory YAML, atomically."""
    if fmt == "csv":
        rows = [",".join(["time_s"] + list(joint_names))]
        rows += [",".join([repr(float(tk))] + [repr(float(v)) for v in qk]) for tk, qk in zip(t, q)]
        write_text_atomic(path, "\n".join(rows) + "\n")
    else:
        dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)  # libyaml's emitter when built: ~10x faster
        write_text_atomic(path, yaml.dump(ros2_joint_trajectory(joint_names, t, q, qd, qdd), Dumper=dumper,
                                          sort_keys=False))


def stream_check(sc, stream, rate_hz: float, *, clearance_if_over: bool = True) -> dict:
    """The scenario's limit check of the interpolated stream at check_rate(rate_hz) ('check_rate_hz' added),
    and with obstacles its clearance at the scenario's re-check rate ('clearance_m', 'clearance_pair').
    clearance_if_over=False skips the clearance (Drake's signed distance, the costly part) of a stream
    that already breaks a limit: --hold's bisection only needs it where the limits hold."""
    rate = check_rate(sc, rate_hz)
    out = {**limit_check(sc, stream, rate), "check_rate_hz": rate}
    if _obstacles(sc) and (clearance_if_over or out["max"] <= 1.0):
        c = clearance(sc, stream, own_recheck_rate(sc))
        out.update(clearance_m=float(c["clearance_m"]), clearance_pair=list(c["clearance_pair"]),
                   clearance_time_s=float(c["clearance_time_s"]))
    return out


def stream_holds(rc: dict) -> bool:
    """A stream check holds: every limit (ratio <= 1) and, with obstacles, clear of them."""
    return bool(rc["max"] <= 1.0 and rc.get("clearance_m", 0.0) >= 0.0)


def _stream_of(sc, traj, rate_hz: float, interp: str):
    t, q, qd, qdd = stream_samples(traj, rate_hz)
    stream = interpolated(t, q, qd, interp, _planar(sc))
    return (t, q, qd, qdd), stream, stream_check(sc, stream, rate_hz)


def _holds_at(sc, traj, rate_hz: float, interp: str, *, clear_too: bool = True) -> bool:
    """The stream of traj keeps every limit and, when clear_too, clears the obstacles (the clearance, Drake's
    signed distance and the costly part, is computed only where the limits hold)."""
    t, q, qd, _ = stream_samples(traj, rate_hz)
    stream = interpolated(t, q, qd, interp, _planar(sc))
    if not clear_too:
        return bool(limit_check(sc, stream, check_rate(sc, rate_hz))["max"] <= 1.0)
    return stream_holds(stream_check(sc, stream, rate_hz, clearance_if_over=False))


def hold_scale(sc, traj, rate_hz: float, interp: str, *, k_max: float = HOLD_MAX_SCALE, rel_tol: float = HOLD_REL_TOL):
    """The time scale k in [1, k_max] (bisection to rel_tol) at which the stream of traj played k times
    slower keeps every limit as interpolated and clears the obstacles; each k tried is checked, and the one
    returned holds. The ratio is not monotone in k (the samples fall elsewhere on the plan), so a smaller k
    may hold too. The limits are bisected first without the clearance; only if the scale found there does
    not clear is the bisection continued with it (a scale that clears and holds is at least the limits' one)."""
    if _holds_at(sc, traj, rate_hz, interp):
        return 1.0
    if not _holds_at(sc, TimeScaled(traj, k_max), rate_hz, interp):
        raise QmtInputError(f"--hold: the stream at {rate_hz:g} Hz breaks a limit or collides even {k_max:g} times "
                            "slower; raise the rate or use the other --interp")
    k = smallest_holding_scale(
        1.0, k_max, lambda k: _holds_at(sc, TimeScaled(traj, k), rate_hz, interp, clear_too=False), rel_tol)
    if not _obstacles(sc) or _holds_at(sc, TimeScaled(traj, k), rate_hz, interp):
        return k
    return smallest_holding_scale(k, k_max, lambda k: _holds_at(sc, TimeScaled(traj, k), rate_hz, interp), rel_tol)


def export_plan(sc, plan, fmt: str, rate_hz: float, out, interp: str = "cubic", *, hold: bool = False,
                allow_large: bool = False) -> dict:
    """Write `plan` (a SpatialPlan of sc) as the stream (module docstring) and re-check the stream as
    `interp` interpolates it; hold: first slow the plan by hold_scale so that the stream keeps the limits.
    The report: the stream's re-check beside the plan's own at the same rate, peak jerks, the scale."""
    check_export_call(sc, plan, out, hold, allow_large)
    check_export_inputs(sc, plan.duration_s * (HOLD_MAX_SCALE if hold else 1.0), fmt, rate_hz, interp,
                        allow_large=allow_large)
    k = hold_scale(sc, plan.trajectory, rate_hz, interp) if hold else 1.0
    traj = plan.trajectory if k == 1.0 else TimeScaled(plan.trajectory, k)
    (t, q, qd, qdd), stream, rc = _stream_of(sc, traj, rate_hz, interp)
    write_stream(out, fmt, joint_names(sc), t, q, qd, qdd)
    own = limit_check(sc, plan.trajectory, check_rate(sc, rate_hz))
    return {"scenario": sc.name, "method": plan.method, "format": fmt, "rate_hz": float(rate_hz), "interp": interp,
            "out": str(out), "n_samples": int(len(t)), "stream_end_s": float(t[-1]), "plan_duration_s": plan.duration_s,
            "hold_scale": k, "stream_recheck": rc, "stream_holds": stream_holds(rc), "plan_recheck_same_rate": own,
            "stream_peak_jerk": stream_jerk(sc, stream, rc["check_rate_hz"]),
            "plan_peak_jerk": stream_jerk(sc, plan.trajectory, own_recheck_rate(sc)), "stream": stream}
