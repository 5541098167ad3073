"""Actuators drive the joints they are named for (issue 28, item 1).

Drake makes a URDF's actuators in the order of its <transmission> elements and skips a transmission
it does not support; the controllers write one torque per joint in chain order. A UR5 whose
transmissions are listed out of order, or whose wrist has a differential transmission, must be
driven exactly like the shipped UR5 (same outcome, same final joint error), and the by-name
mapping must route a joint-order torque to the right joint even on a plant whose actuators are not
in joint order (the old index wiring would not)."""

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from qmt_drake.errors import QmtInputError
from qmt_drake.model.actuator_order import (
    actuator_joint_names,
    connect_joint_torques,
    joint_to_actuation_matrix,
)
from qmt_drake.model.arm import ArmModel
from qmt_drake.model.urdf_check import example_robot_urdf, load_arm_plant
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import SCENARIO_DIR, load_spatial_scenario
from qmt_drake.trajectory import CallableTrajectory

SHUFFLE = [4, 0, 2, 5, 1, 3]  # transmission k of the shuffled file is the shipped file's SHUFFLE[k]
CHAIN = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
         "wrist_3_joint"]


def _ur5_root():
    try:
        urdf, _, _ = example_robot_urdf("ur5")
    except QmtInputError as exc:
        pytest.skip(str(exc))
    return ET.parse(urdf).getroot()


def shuffled_urdf(tmp_path):
    root = _ur5_root()
    trs = root.findall("transmission")
    for t in trs:
        root.remove(t)
    for k in SHUFFLE:
        root.append(trs[k])
    p = tmp_path / "ur5_shuffled.urdf"
    p.write_text(ET.tostring(root, encoding="unicode"))
    return p


def differential_wrist_urdf(tmp_path):
    """wrist_1 and wrist_2 on one DifferentialTransmission (as TIAGo's wrist), which Drake skips."""
    root = _ur5_root()
    trs = {t.find("joint").get("name"): t for t in root.findall("transmission")}
    for j in ("wrist_1_joint", "wrist_2_joint"):
        root.remove(trs[j])
    diff = ET.SubElement(root, "transmission", name="wrist_trans")
    ET.SubElement(diff, "type").text = "transmission_interface/DifferentialTransmission"
    for k, j in enumerate(("wrist_1_joint", "wrist_2_joint")):
        a = ET.SubElement(diff, "actuator", name=f"wrist_motor_{k}")
        ET.SubElement(a, "mechanicalReduction").text = "1.0"
        ET.SubElement(ET.SubElement(diff, "joint", name=j), "hardwareInterface").text = "EffortJointInterface"
    p = tmp_path / "ur5_differential.urdf"
    p.write_text(ET.tostring(root, encoding="unicode"))
    return p


def drake_actuator_order(urdf) -> list[str]:
    """The joints of the actuators Drake's parser makes, in the actuation port's order (the old wiring)."""
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(urdf))
    plant.Finalize()
    return [plant.get_joint_actuator(i).joint().name() for i in plant.GetJointActuatorIndices()]


def scenario_with(urdf, tmp_path):
    raw = yaml.safe_load((SCENARIO_DIR / "ur5-suction-bins.yaml").read_text())
    raw["arm"] = {"urdf": str(urdf), "hand_frame": "tool0"}
    p = tmp_path / f"{urdf.stem}.yaml"
    p.write_text(yaml.safe_dump(raw))
    return load_spatial_scenario(p)


def lift(sc, duration_s=1.0):
    """A quintic rest-to-rest move from the pick pose to the pose above it (the scenario's first carry)."""
    q0, q1 = sc.q_poses_rad[0], sc.q_poses_rad[1]

    def f(t, order):
        s = np.clip(t / duration_s, 0.0, 1.0)[:, None]
        shape = [10 * s**3 - 15 * s**4 + 6 * s**5, (30 * s**2 - 60 * s**3 + 30 * s**4) / duration_s,
                 (60 * s - 180 * s**2 + 120 * s**3) / duration_s**2][order]
        return (q0 if order == 0 else 0.0) + shape * (q1 - q0)

    return CallableTrajectory(f, duration_s, [], len(q0))


@pytest.fixture(scope="module")
def shipped():
    _ur5_root()  # skips without example-robot-data
    sc = load_spatial_scenario("ur5-suction-bins")
    return sc, simulate_spatial(sc, lift(sc))


def test_drake_orders_actuators_by_transmission_and_skips_a_differential(tmp_path):
    """The premise: a plain parse puts the shuffled file's actuators out of chain order and gives the
    differential wrist none, so the old index wiring sent joint k's torque to another joint."""
    assert drake_actuator_order(shuffled_urdf(tmp_path)) == [CHAIN[k] for k in SHUFFLE] != CHAIN
    assert drake_actuator_order(differential_wrist_urdf(tmp_path)) == [j for j in CHAIN if "wrist_1" not in j
                                                                        and "wrist_2" not in j]


@pytest.mark.parametrize("make", [shuffled_urdf, differential_wrist_urdf])
def test_load_arm_plant_makes_one_actuator_per_chain_joint_in_chain_order(make, tmp_path):
    plant, H, names = load_arm_plant(make(tmp_path), "tool0")
    assert names == CHAIN
    assert actuator_joint_names(plant, H.model_instance()) == CHAIN
    assert np.array_equal(joint_to_actuation_matrix(plant, H.model_instance(), CHAIN), np.eye(6))
    shipped_plant, _, _ = load_arm_plant(example_robot_urdf("ur5")[0], "tool0")
    for j in CHAIN:  # each keeps what Drake made of its own transmission (the effort limit of its joint)
        a = next(plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices() if
                 plant.get_joint_actuator(i).joint().name() == j)
        b = next(shipped_plant.get_joint_actuator(i) for i in shipped_plant.GetJointActuatorIndices() if
                 shipped_plant.get_joint_actuator(i).joint().name() == j)
        if make is differential_wrist_urdf and j in ("wrist_1_joint", "wrist_2_joint"):
            continue  # added here: unlimited, like the Panda's
        assert (a.name(), a.effort_limit()) == (b.name(), b.effort_limit())


def test_joint_torques_reach_their_joints_on_a_plant_with_actuators_out_of_order(tmp_path):
    """connect_joint_torques on Drake's own out-of-order plant: the accelerations are M^-1 (tau + tau_g)
    with tau in chain order. The old direct connection gives other accelerations."""
    tau = np.array([3.0, -2.0, 1.5, 0.7, -0.4, 0.2])

    def accelerations(by_name: bool):
        builder = DiagramBuilder()
        plant = builder.AddSystem(MultibodyPlant(0.0))
        model = Parser(plant).AddModels(str(shuffled_urdf(tmp_path)))[0]
        plant.Finalize()
        src = builder.AddSystem(ConstantVectorSource(tau))
        if by_name:
            connect_joint_torques(builder, plant, model, CHAIN, src.get_output_port())
        else:
            builder.Connect(src.get_output_port(), plant.get_actuation_input_port(model))
        diagram = builder.Build()
        ctx = diagram.CreateDefaultContext()
        pctx = plant.GetMyContextFromRoot(ctx)
        plant.SetPositions(plant.GetMyMutableContextFromRoot(ctx), [0.3, -1.0, 1.2, -0.8, 0.5, 0.1])
        qdd = plant.EvalTimeDerivatives(pctx).CopyToVector()[6:]
        expected = np.linalg.solve(plant.CalcMassMatrix(pctx), tau + plant.CalcGravityGeneralizedForces(pctx))
        return qdd, expected

    qdd, expected = accelerations(by_name=True)
    assert np.allclose(qdd, expected, rtol=1e-10, atol=1e-10)
    qdd_old, expected = accelerations(by_name=False)
    assert not np.allclose(qdd_old, expected, rtol=1e-3, atol=1e-3)


@pytest.mark.parametrize("make", [shuffled_urdf, differential_wrist_urdf])
@pytest.mark.parametrize("actuator", ["ideal", "dc_motor"])
def test_cosimulation_of_a_reordered_urdf_matches_the_shipped_arm(make, actuator, shipped, tmp_path):
    """Same plan, same outcome and final joint error as the shipped UR5 (before the fix: shuffled
    transmissions made the TOPP-RA plan 'detached', 2.7 rad from its goal)."""
    sc0, res0 = shipped
    if actuator != "ideal":
        res0 = simulate_spatial(sc0, lift(sc0), actuator=actuator)
    sc = scenario_with(make(tmp_path), tmp_path)
    res = simulate_spatial(sc, lift(sc), actuator=actuator)
    assert res0["outcome"] == "carried"
    assert res["outcome"] == res0["outcome"]
    assert res["final_goal_error_rad"] == pytest.approx(res0["final_goal_error_rad"], rel=1e-6, abs=1e-12)
    assert res["max_tracking_error_rad"] == pytest.approx(res0["max_tracking_error_rad"], rel=1e-6)


def test_a_planar_arm_with_transmissions_out_of_order_is_refused_naming_them(tmp_path):
    """The planar co-simulation writes torques base to tip into Drake's actuation input: a URDF whose
    transmissions are listed in another order is refused in one line (it used to drive other joints)."""
    root = ET.parse(Path(__file__).resolve().parents[1] / "models" / "three_link_ch2.urdf").getroot()
    trs = root.findall("transmission")
    assert len(trs) == 3
    for t in trs:
        root.remove(t)
    for t in trs[::-1]:
        root.append(t)
    p = tmp_path / "three_link_reversed.urdf"
    p.write_text(ET.tostring(root, encoding="unicode"))
    with pytest.raises(QmtInputError, match="list the transmissions in that order"):
        ArmModel.from_urdf(p)
