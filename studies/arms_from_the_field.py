"""Arms from `example-robot-data` that no shipped scenario or test used before issue 28, each with a
suction pick-and-place built around its own posture (studies/spatial_other_arms.task_around), planned
by every spatial method, every plan checked independently of the planner and co-simulated.

    .venv/bin/python -m studies.arms_from_the_field [--arms so101,pr2] [--out FILE.json] [--no-dc]

The arms (FIELD_ARMS): SO-101 (5 joints, its <transmission>s listed wrist first), TALOS's left arm
(6 joints; transmissions out of chain order, a differential wrist Drake skips, and one for a joint the
file does not have), Centauro's arm (6 joints on a wheeled-legged base, 32 joints locked), Baxter's
right arm (7 joints), PR2's right arm (7 joints on a mobile base, the torso lift locked at 0.15 m,
transmissions out of order with a differential wrist), TIAGo's arm (7 joints on a mobile base, the
torso at 0.25 m, transmissions out of order with a differential wrist; first used by this issue's
tests/test_urdf_setup.py). The URDF's own speed and effort limits; the
acceleration, jerk, gear and motor data are chosen here (below).

Per plan: the duration, the planner's re-check (10x the check rate, its binding column), the task
poses' errors (Drake FK, plan.pose_error), the largest ratio by `independent_check` at 10x the
re-check rate (Pinocchio: its own URDF parse, RNEA for the joint torques and its own frame kinematics
for the hand state fed to the scenario's hand term; joint ranges from Pinocchio's model), and the
co-simulation's outcome with ideal actuators and with the DC motors. A method that refuses is a row
with its one-line reason.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin

from qmt_drake.errors import QmtInputError
from qmt_drake.model.spatial_chain import HandSample
from qmt_drake.model.urdf_check import load_arm_plant, off_chain_locks, urdf_joint_limits
from qmt_drake.model.urdf_package import package_urdf
from qmt_drake.outputs import jsonable, write_text_atomic
from qmt_drake.planners.spatial_methods import (
    plan_family_optimum,
    plan_ga_spatial,
    plan_ruckig_spatial,
    plan_toppra_spatial,
    plan_trajopt_spatial,
)
from qmt_drake.planners.spatial_trajectory import sample_times
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from studies.spatial_other_arms import task_around

# name -> arm section (package, hand frame, locks, face axis), seed posture (rad) the task is built around,
# the face normal (world; None: the hand's own at the seed), what is new about the arm
DOWN = [0.0, 0.0, -1.0]
FIELD_ARMS = {
    "so101": ({"package": "example-robot-data/so101", "hand_frame": "gripper_frame_link", "lock": "off_chain",
               "face_axis": [1.0, 0.0, 0.0]},  # across the roll axis: along it, facing down is singular
              [0.14, 0.23, 0.82, -0.82, -0.32], DOWN, "5 joints; transmissions listed wrist first"),
    "talos_left_arm": ({"package": "example-robot-data/talos_left_arm", "hand_frame": "wrist_left_ft_tool_link",
                        "lock": "off_chain"},
                       [0.3, 0.6, -1.2, 0.3, -0.4, 0.2], None,
                       "6 joints; transmissions out of order, a differential wrist, one for a joint the file lacks"),
    "centauro": ({"package": "example-robot-data/centauro", "hand_frame": "arm1_8", "lock_joints": {"torso_yaw": 0.0},
                  "lock": "off_chain"},
                 [0.3, 0.5, 0.2, -1.2, 0.3, 0.5], None, "6 joints on a wheeled-legged mobile base"),
    "baxter": ({"package": "example-robot-data/baxter", "hand_frame": "right_gripper", "lock": "off_chain"},
               [-0.2, -0.03, 0.9, 2.09, -1.65, 0.85, 1.83], DOWN, "7 joints on a pedestal"),
    "pr2": ({"package": "example-robot-data/pr2", "hand_frame": "r_gripper_tool_frame", "face_axis": [1.0, 0.0, 0.0],
             "lock_joints": {"torso_lift_joint": 0.15}, "lock": "off_chain"},
            [-1.22, 0.01, -2.55, -1.36, -0.72, -0.4, 0.46], DOWN,
            "7 joints on a mobile base; transmissions out of order, a differential wrist; effort 30 N m "
            "(the real arm has a spring counterbalance the URDF does not model)"),
    "tiago": ({"package": "example-robot-data/tiago", "hand_frame": "arm_tool_link",
               "lock_joints": {"torso_lift_joint": 0.25}, "lock": "off_chain"},
              [1.2, -0.2, -1.5, 1.8, 1.2, 1.0, 0.0], None,
              "7 joints on a mobile base; transmissions out of order, a differential wrist (first used in "
              "this issue's tests/test_urdf_setup.py)"),
}
GEAR, ROTOR_KGM2, SUPPLY_V = 100.0, 1e-5, 48.0
METHODS = (("toppra", plan_toppra_spatial, {}), ("ruckig", plan_ruckig_spatial, {}),
           ("family_optimum", plan_family_optimum, {}),
           ("ga", plan_ga_spatial, {"generations": 15, "population": 16, "stall": 8}),
           ("trajopt", plan_trajopt_spatial, {}),
           ("toppra lines", plan_toppra_spatial, {"family": "line_cubic_velocity"}),
           ("family_optimum lines", plan_family_optimum, {"family": "line_cubic_velocity"}))
INDEPENDENT_FACTOR = 10  # the independent check samples at 10x the planner's re-check rate


def field_scenario(name: str, tmp_path: Path) -> Path:
    """The scenario file of FIELD_ARMS[name]: the URDF's speed and effort limits (not given), 10 rad/s^2,
    200 rad/s^3, gear 100 and rotor 1e-5 kg m^2 on every joint, and DC motors sized so each joint's
    effort limit is reachable at its speed limit from SUPPLY_V (back-EMF at the speed limit SUPPLY_V / 2,
    the resistive drop at the effort limit 0.3 SUPPLY_V)."""
    arm, seed, normal, _ = FIELD_ARMS[name]
    urdf, _, _ = package_urdf(arm["package"])
    locks = dict(arm.get("lock_joints", {}))
    if arm.get("lock") == "off_chain":
        locks = off_chain_locks(urdf, arm["hand_frame"], locks)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the scenario's loader gives them
        plant, H, names = load_arm_plant(urdf, arm["hand_frame"], lock_joints=locks)
    own = urdf_joint_limits(urdf, names)
    n = len(names)
    kt = 0.5 * SUPPLY_V / (GEAR * own["velocity_limit_rad_s"])
    resistance = 0.3 * SUPPLY_V / (own["effort_limit_Nm"] / (GEAR * kt))
    actuators = {"acceleration_limit_rad_s2": [10.0] * n, "jerk_limit_rad_s3": [200.0] * n,
                 "gear_ratio": [GEAR] * n, "rotor_inertia_kgm2": [ROTOR_KGM2] * n,
                 "motor": {"torque_constant_Nm_per_A": kt.tolist(), "resistance_ohm": resistance.tolist(),
                           "voltage_limit_V": SUPPLY_V}}
    return task_around(name, plant, H, arm, actuators, seed, tmp_path, face_normal=normal)


class PinocchioCheck:
    """The limit ratios of a plan from Pinocchio's own model of the URDF (every joint off the
    scenario's chain locked at the scenario's value, the part added to the hand's body): joint speed,
    acceleration and range, the joint torques by RNEA (plus the reflected rotor inertia N^2 J_r qdd
    and the URDF's joint damping), fed with Pinocchio's hand kinematics to the scenario's own limit
    terms (the motor torque and the suction grip)."""

    def __init__(self, sc) -> None:
        full = pin.buildModelFromUrdf(str(sc.urdf))
        q_ref = pin.neutral(full)
        locked = []
        for jid in range(1, full.njoints):
            name = full.names[jid]
            if name in sc.joint_names:
                continue
            locked.append(jid)
            value, jm = sc.lock_joints.get(name, 0.0), full.joints[jid]
            if jm.nq == 2:
                q_ref[jm.idx_q:jm.idx_q + 2] = np.cos(value), np.sin(value)
            elif jm.nq == 1:
                q_ref[jm.idx_q] = value
        self.model = pin.buildReducedModel(full, locked, q_ref)
        m = self.model
        self.data = m.createData()
        self.fid = m.getFrameId(sc.hand_frame)
        frame = m.frames[self.fid]
        b = sc.body
        part = pin.Inertia(b.mass_kg, np.asarray(b.com_m, float), np.asarray(b.inertia_kgm2, float))
        m.inertias[frame.parentJoint] = m.inertias[frame.parentJoint] + frame.placement.act(part)
        self.joints = [m.joints[m.getJointId(n)] for n in sc.joint_names]
        self.iv = np.array([j.idx_v for j in self.joints])
        lo, up = m.lowerPositionLimit, m.upperPositionLimit
        ranged = np.array([j.nq == 1 for j in self.joints])
        lo = np.array([lo[j.idx_q] if r else -np.inf for j, r in zip(self.joints, ranged)])
        up = np.array([up[j.idx_q] if r else np.inf for j, r in zip(self.joints, ranged)])
        self.lo, self.up = lo, up
        self.reflected = sc.drive["gear_ratio"] ** 2 * sc.drive["rotor_inertia_kgm2"]
        self.damping = np.asarray(m.damping)[self.iv]
        self.sc = sc

    def _q(self, q):
        out = np.zeros(self.model.nq)
        for k, j in enumerate(self.joints):
            if j.nq == 2:
                out[j.idx_q:j.idx_q + 2] = np.cos(q[k]), np.sin(q[k])
            else:
                out[j.idx_q] = q[k]
        return out

    def state(self, q, qd, qdd) -> HandSample:
        """The hand state and joint torques at (S, n) samples, by Pinocchio (sample by sample)."""
        m, d, S, nv = self.model, self.data, len(q), self.model.nv
        out = {k: np.empty((S, 3)) for k in ("position_m", "angular_velocity_rad_s", "linear_velocity_m_s",
                                             "angular_acceleration_rad_s2", "linear_acceleration_m_s2")}
        R, tau = np.empty((S, 3, 3)), np.empty((S, len(self.iv)))
        v, a = np.zeros(nv), np.zeros(nv)
        frame = pin.LOCAL_WORLD_ALIGNED
        for s in range(S):
            qp = self._q(q[s])
            v[self.iv], a[self.iv] = qd[s], qdd[s]
            tau[s] = pin.rnea(m, d, qp, v, a)[self.iv]
            pin.forwardKinematics(m, d, qp, v, a)
            X = pin.updateFramePlacement(m, d, self.fid)
            out["position_m"][s], R[s] = X.translation, X.rotation
            V = pin.getFrameVelocity(m, d, self.fid, frame)
            A = pin.getFrameClassicalAcceleration(m, d, self.fid, frame)
            out["linear_velocity_m_s"][s], out["angular_velocity_rad_s"][s] = V.linear, V.angular
            out["linear_acceleration_m_s2"][s], out["angular_acceleration_rad_s2"][s] = A.linear, A.angular
        tau += self.reflected * qdd + self.damping * qd
        return HandSample(rotation=R, joint_torque_Nm=tau, **out)

    def ratios(self, q, qd, qdd) -> dict:
        """({limit: its largest ratio over the samples (1 = on the limit)}, {limit: the column, e.g.
        'joint_acceleration[shoulder_lift]'}, {limit: the index of the sample where it peaks})."""
        sc = self.sc
        st = self.state(q, qd, qdd)
        mid, half = 0.5 * (self.lo + self.up), 0.5 * (self.up - self.lo)
        out = {"joint_speed": np.abs(qd) / sc.velocity_limit_rad_s,
               "joint_acceleration": np.abs(qdd) / sc.acceleration_limit_rad_s2,
               "joint_range": np.where(np.isfinite(half), np.abs(q - mid) / np.where(np.isfinite(half), half, 1.0), 0.0)}
        labels = {k: [f"{k}[{n}]" for n in sc.joint_names] for k in out}
        for term in sc.terms():
            out[term.name], labels[term.name] = term.columns(st), list(term.column_names)
        peak = {k: float(np.max(v)) for k, v in out.items()}
        where = {k: labels[k][int(np.argmax(np.max(v, axis=0)))] for k, v in out.items()}
        when = {k: int(np.argmax(np.max(v, axis=1))) for k, v in out.items()}
        return peak, where, when


def independent_check(sc, traj, rate_hz: float | None = None, checker: PinocchioCheck | None = None) -> dict:
    """The plan's limit ratios by PinocchioCheck at rate_hz (default 10x the re-check rate) over the
    whole trajectory; 'max' the largest, 'binding' its column and 'binding_time_s' when, 'rate_hz',
    'n_samples'."""
    rate = rate_hz or INDEPENDENT_FACTOR * sc.recheck_rate_hz
    t = sample_times(traj.duration_s, rate)
    r, where, when = (checker or PinocchioCheck(sc)).ratios(*traj.sample(t))
    top = max(r, key=r.get)
    return {**r, "max": r[top], "binding": where[top], "binding_time_s": float(t[when[top]]), "rate_hz": rate,
            "n_samples": int(len(t))}


def run_arm(name: str, tmp_path: Path, *, methods=METHODS, dc: bool = True, log=print) -> list[dict]:
    """Every method on arm `name`: one dict per method (a refusal as its one-line reason)."""
    sc = load_spatial_scenario(field_scenario(name, tmp_path))
    checker = PinocchioCheck(sc)
    rows = []
    for label, planner, kw in methods:
        row = {"arm": name, "dof": sc.n_dof, "method": label}
        t0 = time.perf_counter()
        try:
            plan = planner(sc, **kw)
        except QmtInputError as exc:
            row["refused"] = str(exc)
            rows.append(row)
            log(f"{name} {label}: refused: {exc}")
            continue
        ind = independent_check(sc, plan.trajectory, checker=checker)
        row.update(duration_s=plan.duration_s, hold_scale=plan.hold_scale, planning_s=time.perf_counter() - t0,
                   recheck_max=plan.recheck["max"], recheck_binding=plan.recheck["binding"],
                   recheck_rate_hz=sc.recheck_rate_hz, pose_error_m=float(plan.pose_error[:, 0].max()),
                   pose_error_rad=float(plan.pose_error[:, 1].max()), independent=ind,
                   cosim_ideal=simulate_spatial(sc, plan.trajectory)["outcome"])
        if dc and sc.motor is not None:
            row["cosim_dc_motor"] = simulate_spatial(sc, plan.trajectory, actuator="dc_motor")["outcome"]
        rows.append(row)
        log(f"{name} {label}: T = {row['duration_s']:.4f} s, independent max {ind['max']:.4f} ({ind['binding']}), "
            f"co-simulation {row['cosim_ideal']} / {row.get('cosim_dc_motor', '-')}")
    return rows


def table(rows) -> str:
    head = ("| arm | DOF | method | T s | planner re-check max (binding) | pose error m / rad | "
            "independent max at 10x (binding) | co-sim ideal | co-sim dc_motor |\n|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        if "refused" in r:
            lines.append(f"| {r['arm']} | {r['dof']} | {r['method']} | refused: {r['refused']} | | | | | |")
            continue
        ind = r["independent"]
        lines.append(f"| {r['arm']} | {r['dof']} | {r['method']} | {r['duration_s']:.4f} | "
                     f"{r['recheck_max']:.5f} ({r['recheck_binding']}) | {r['pose_error_m']:.1e} / "
                     f"{r['pose_error_rad']:.1e} | {ind['max']:.5f} ({ind['binding']}) | {r['cosim_ideal']} | "
                     f"{r.get('cosim_dc_motor', '-')} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arms", default=",".join(FIELD_ARMS), help="comma-separated names of FIELD_ARMS")
    ap.add_argument("--out", type=Path, help="write the rows as JSON here")
    ap.add_argument("--methods", help="comma-separated labels of METHODS (default all)")
    ap.add_argument("--no-dc", action="store_true", help="skip the DC-motor co-simulation")
    args = ap.parse_args(argv)
    names = [a for a in args.arms.split(",") if a]
    unknown = [a for a in names if a not in FIELD_ARMS]
    if unknown:
        print(f"arms_from_the_field: error: unknown arms {unknown}; choose from {list(FIELD_ARMS)}", file=sys.stderr)
        return 2
    methods = [m for m in METHODS if args.methods is None or m[0] in args.methods.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            try:
                rows += run_arm(name, Path(tmp), methods=methods, dc=not args.no_dc,
                                log=lambda s: print(s, file=sys.stderr))
            except QmtInputError as exc:
                print(f"arms_from_the_field: error: {name}: {exc}", file=sys.stderr)
                return 2
    print(table(rows))
    if args.out:
        write_text_atomic(args.out, json.dumps(jsonable({"arms": {n: FIELD_ARMS[n][3] for n in names}, "rows": rows}), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
