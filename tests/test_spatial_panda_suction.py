"""An arm whose URDF declares no actuators (example-robot-data's Panda) with a suction cup, a hand the
shipped Panda scenario does not use: load_arm_plant gives every chain joint an actuator, TOPP-RA
plans the task, and the co-simulation carries the part to the goal."""

from pathlib import Path

from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant
from qmt_drake.planners.spatial_methods import plan_toppra_spatial
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario

SHIPPED = Path(__file__).resolve().parents[1] / "models" / "scenarios" / "panda-tray-cup.yaml"
SUCTION = """payload:
  mass_kg: 0.5
  com_m: [0.0, 0.0, 0.05]
  inertia_kgm2: [0.001, 0.001, 0.001]
hand:
  kind: suction
  cup_radius_m: 0.02
  vacuum_force_N: 40.0
  friction: 0.5
  rim_points: 8
  pyramid_edges: 4
"""


def test_every_chain_joint_of_the_panda_gets_an_actuator():
    urdf, hand, lock = example_robot_urdf("panda")
    plant, _, names = load_arm_plant(urdf, hand, lock_joints=lock)
    assert len(names) == 7 and plant.num_actuators() == 7
    assert [plant.get_joint_actuator(i).joint().name() for i in plant.GetJointActuatorIndices()] == names


def test_a_panda_with_a_suction_cup_plans_and_carries(tmp_path):
    text = SHIPPED.read_text()
    text = text[:text.index("hand:\n")] + SUCTION + text[text.index("task:\n"):]
    text = (text.replace("name: panda-tray-cup", "name: panda-suction")
            .replace("face_normal: [0.0, 0.0, 1.0]", "face_normal: [0.0, 0.0, -1.0]")
            .replace("seed_rad: [0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.8]", "seed_rad: [0.0, 0.3, 0.0, -2.2, 0.0, 2.5, 0.8]"))
    path = tmp_path / "panda-suction.yaml"
    path.write_text(text)
    sc = load_spatial_scenario(path)
    plan = plan_toppra_spatial(sc)
    assert plan.recheck["max"] <= 1.0 and plan.recheck["suction"] > 0.1  # the cup's limit is in the plan
    r = simulate_spatial(sc, plan.trajectory)
    assert r["outcome"] == "carried" and r["final_goal_error_rad"] < 1e-3
    assert r["max_grip_ratio_while_held"] < 1.0
