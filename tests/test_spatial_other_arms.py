"""Arms nobody here wrote a scenario for: a pick-and-place task built around each arm's own posture
(UR3, UR10, Kinova Jaco j2s6s200, xArm7, Unitree Z1 from example-robot-data; the generated arm6) must
plan with TOPP-RA and the straight-line family, hold every limit on the re-check, reach every task
pose (Drake FK), keep the hand on the straight lines, and be carried in the co-simulation."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from qmt_drake.errors import QmtInputError
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant
from qmt_drake.planners.spatial_families import LINE_TOL_M
from qmt_drake.planners.spatial_methods import plan_family_optimum, plan_toppra_spatial
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from tests.test_spatial_families import line_errors

ARM6 = Path(__file__).resolve().parents[1] / "models" / "spatial" / "arm6.urdf"
# a bent, non-singular posture per arm (rad) around which the task is built
SEEDS = {"ur3": [-0.6, -1.3, 1.6, -1.9, -1.57, 0.0], "ur10": [-0.6, -1.3, 1.6, -1.9, -1.57, 0.0],
         "kinova": [0.0, 2.9, 1.3, -2.1, 1.4, 0.0], "xarm7": [0.0, 0.3, 0.0, 1.2, 0.0, 0.9, 0.0],
         "z1": [0.0, 1.2, -1.0, -0.3, 0.0, 0.0], "arm6": [0.3, 0.5, 1.0, 0.0, 0.8, 0.0]}


def arm_scenario(name: str, tmp_path: Path) -> Path:
    """A suction pick-and-place scenario file for arm `name`: poses around the hand's position at the
    seed (pick, lift by 15 % of its reach, carry sideways by 25 %, lower), the hand's own face normal
    there, the URDF's speed and effort limits."""
    if name == "arm6":
        path, hand, lock = ARM6, "hand", ()
        arm = {"urdf": str(ARM6), "hand_frame": "hand"}
    else:
        try:
            path, hand, lock = example_robot_urdf(name)
        except QmtInputError as exc:
            pytest.skip(str(exc))
        arm = {"package": f"example-robot-data/{name}"}
    plant, H, names = load_arm_plant(path, hand, lock_joints=lock)
    n, seed = len(names), np.array(SEEDS[name])
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, seed)
    X = H.CalcPoseInWorld(ctx)
    p, normal = X.translation(), X.rotation().matrix()[:, 2]
    reach = float(np.linalg.norm(p))
    side = np.cross([0.0, 0.0, 1.0], p)
    side = 0.25 * reach * side / np.linalg.norm(side)
    lift = np.array([0.0, 0.0, 0.15 * reach])
    poses = [p, p + lift, p + lift + side, p + side]
    raw = {"kind": "spatial_transfer", "name": f"{name}-suction", "arm": arm,
           "actuators": {"velocity_limit_rad_s": plant.GetVelocityUpperLimits().tolist(),
                         "acceleration_limit_rad_s2": [10.0] * n, "jerk_limit_rad_s3": [200.0] * n,
                         "torque_limit_Nm": plant.GetEffortUpperLimits().tolist(), "gear_ratio": [100.0] * n,
                         "rotor_inertia_kgm2": [1e-5] * n},
           "payload": {"mass_kg": 0.3, "com_m": [0.0, 0.0, 0.03], "inertia_kgm2": [2e-4, 2e-4, 1e-4]},
           "hand": {"kind": "suction", "cup_radius_m": 0.015, "vacuum_force_N": 40.0, "friction": 0.5},
           "task": {"seed_rad": seed.tolist(), "face_normal": normal.tolist(),
                    "poses_m": [x.tolist() for x in poses], "transfer_points": 3},
           "limits": {"check_rate_hz": 200}}
    out = tmp_path / f"{name}.yaml"
    out.write_text(yaml.safe_dump(raw))
    return out


@pytest.mark.parametrize("name", sorted(SEEDS))
def test_an_arm_nobody_wrote_a_scenario_for_plans_and_carries(name, tmp_path):
    sc = load_spatial_scenario(arm_scenario(name, tmp_path))
    toppra = plan_toppra_spatial(sc, n_grid=400)
    line = plan_family_optimum(sc, family="line_cubic_velocity")
    for plan in (toppra, line):
        assert plan.recheck["max"] <= 1.0
        assert plan.pose_error[:, 0].max() < 1e-6 and plan.pose_error[:, 1].max() < 1e-6
    assert line_errors(sc, line, rate_hz=500.0)[0] < LINE_TOL_M
    assert toppra.duration_s < line.duration_s  # the line family stops at every pose; TOPP-RA's path does not
    res = simulate_spatial(sc, line.trajectory)
    assert res["held"] and res["outcome"] == "carried"
