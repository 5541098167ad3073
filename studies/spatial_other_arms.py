"""Arms nobody here wrote a scenario for: a suction pick-and-place built around each arm's own posture
(UR3, UR10, Kinova Jaco j2s6s200, xArm7, Unitree Z1 from example-robot-data; the generated arm6),
planned by TOPP-RA and the family optima on the via path and on the straight lines, the line plan
co-simulated (tests/test_spatial_other_arms.py asserts what this prints).

    .venv/bin/python -m studies.spatial_other_arms

Prints a Markdown table: carry length (m), TOPP-RA on the via path and on the lines, the via and line
family optima (s), the line plan's largest distance to the straight lines at 1 kHz (um, Drake FK),
the co-simulation's outcome.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

from qmt_drake.errors import QmtInputError
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant
from qmt_drake.model.urdf_package import example_face_axis
from qmt_drake.planners.spatial_methods import plan_family_optimum, plan_toppra_spatial
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from studies.spatial_path_deviation import line_errors

ARM6 = Path(__file__).resolve().parents[1] / "models" / "spatial" / "arm6.urdf"
# a bent, non-singular posture per arm (rad) around which the task is built
SEEDS = {"ur3": [-0.6, -1.3, 1.6, -1.9, -1.57, 0.0], "ur10": [-0.6, -1.3, 1.6, -1.9, -1.57, 0.0],
         "kinova": [0.0, 2.9, 1.3, -2.1, 1.4, 0.0], "xarm7": [0.0, 0.3, 0.0, 1.2, 0.0, 0.9, 0.0],
         "z1": [0.0, 1.2, -1.0, -0.3, 0.0, 0.0], "arm6": [0.3, 0.5, 1.0, 0.0, 0.8, 0.0]}


def arm_scenario(name: str, tmp_path: Path) -> Path:
    """A suction pick-and-place scenario file for arm `name` (SEEDS) around its posture at the seed
    (task_around)."""
    if name == "arm6":
        path, hand, lock = ARM6, "hand", ()
        arm = {"urdf": str(ARM6), "hand_frame": "hand"}
    else:
        path, hand, lock = example_robot_urdf(name)  # QmtInputError without example-robot-data
        arm = {"package": f"example-robot-data/{name}"}
    plant, H, names = load_arm_plant(path, hand, lock_joints=lock)
    n = len(names)
    actuators = {"velocity_limit_rad_s": plant.GetVelocityUpperLimits().tolist(),
                 "acceleration_limit_rad_s2": [10.0] * n, "jerk_limit_rad_s3": [200.0] * n,
                 "torque_limit_Nm": plant.GetEffortUpperLimits().tolist(), "gear_ratio": [100.0] * n,
                 "rotor_inertia_kgm2": [1e-5] * n}
    return task_around(name, plant, H, arm, actuators, SEEDS[name], tmp_path)


def task_around(name: str, plant, H, arm: dict, actuators: dict, seed, tmp_path: Path, *,
                face_normal=None) -> Path:
    """The scenario file `name`.yaml in tmp_path: poses around the hand's position at the seed (pick,
    lift by 15 % of its distance from the world origin, carry sideways by 25 %, lower), the face
    normal `face_normal` (world) or the hand's own there (the arm's face_axis, default its known arm's or z),
    the `arm` and `actuators` sections as given, a 0.3 kg part 3 cm out along the face axis on a 40 N
    suction cup."""
    seed = np.asarray(seed, float)
    known = example_face_axis(arm["package"]) if "package" in arm else None  # a known arm's tool axis
    axis = np.asarray(arm.get("face_axis", known if known is not None else (0.0, 0.0, 1.0)), float)
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, seed)
    X = H.CalcPoseInWorld(ctx)
    p = X.translation()
    normal = X.rotation().matrix() @ axis if face_normal is None else np.asarray(face_normal, float)
    reach = float(np.linalg.norm(p))
    side = np.cross([0.0, 0.0, 1.0], p)
    side = 0.25 * reach * side / np.linalg.norm(side)
    lift = np.array([0.0, 0.0, 0.15 * reach])
    poses = [p, p + lift, p + lift + side, p + side]
    raw = {"kind": "spatial_transfer", "name": f"{name}-suction", "arm": arm, "actuators": actuators,
           "payload": {"mass_kg": 0.3, "com_m": (0.03 * axis).tolist(), "inertia_kgm2": [2e-4, 2e-4, 1e-4]},
           "hand": {"kind": "suction", "cup_radius_m": 0.015, "vacuum_force_N": 40.0, "friction": 0.5},
           "task": {"seed_rad": seed.tolist(), "face_normal": normal.tolist(),
                    "poses_m": [x.tolist() for x in poses], "transfer_points": 3},
           "limits": {"check_rate_hz": 200}}
    out = tmp_path / f"{name}.yaml"
    out.write_text(yaml.safe_dump(raw))
    return out


def main(argv=None) -> int:
    print("| arm | DOF | carry m | TOPP-RA via path s | via optimum s | TOPP-RA lines s | line optimum s | "
          "off the line um | line plan |")
    print("|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in sorted(SEEDS):
            try:
                sc = load_spatial_scenario(arm_scenario(name, Path(tmp)))
            except QmtInputError as exc:
                print(f"spatial_other_arms: error: {exc}", file=sys.stderr)
                return 2
            line_family = {"family": "line_cubic_velocity"}
            t_via, t_line = plan_toppra_spatial(sc), plan_toppra_spatial(sc, **line_family)
            opt_via, opt_line = plan_family_optimum(sc), plan_family_optimum(sc, **line_family)
            outcome = simulate_spatial(sc, opt_line.trajectory)["outcome"]
            carry = float(np.linalg.norm(sc.poses_m[2] - sc.poses_m[1]))
            print(f"| {name} | {sc.n_dof} | {carry:.3f} | {t_via.duration_s:.4f} | {opt_via.duration_s:.4f} | "
                  f"{t_line.duration_s:.4f} | {opt_line.duration_s:.4f} | {line_errors(sc, opt_line)[0] * 1e6:.2f} | "
                  f"{outcome} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
