"""model/arm_model.build_arm_model: the one entry from an arm's plain data to its chain; the planar
backend is the thesis arms' PlanarChain (same numbers), the spatial one the scenario's SpatialChain."""

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.hands import hand_plugin
from qmt_drake.model.arm_model import ArmData, build_arm_model
from qmt_drake.model.planar import PlanarChain
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.scenario_data import load_scenario_data
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.transfer_scenario import load_scenario


def test_planar_backend_is_the_thesis_arms_chain():
    sc = load_scenario("thesis-ch4")
    built = build_arm_model(ArmData(sc.urdf_path, sc.hand_frame), hand_plugin(sc).carried_inertia(sc), planar=True,
                            gravity_m_s2=sc.world.gravity_m_s2)
    assert isinstance(built.chain, PlanarChain) and built.n_dof == sc.arm.n_dof
    rng = np.random.default_rng(7)
    q, qd, qdd = (rng.uniform(-1, 1, (20, built.n_dof)) for _ in range(3))
    for a, b in zip(built.chain.acceleration_and_torque(q, qd, qdd), sc.arm.planar.acceleration_and_torque(q, qd, qdd)):
        assert np.array_equal(a, b)


def test_spatial_backend_is_the_scenarios_chain():
    data = load_scenario_data("ur5-suction-bins")
    act = data.actuators.given
    built = build_arm_model(ArmData(data.arm.urdf, data.arm.hand_frame, data.arm.lock_joints), data.payload,
                            gear_ratio=act.get("gear_ratio"), rotor_inertia_kgm2=act.get("rotor_inertia_kgm2"),
                            drive_required=data.actuators.motor is not None)
    sc = load_spatial_scenario("ur5-suction-bins")
    assert isinstance(built.chain, SpatialChain) and built.joint_names == sc.joint_names
    q, qd = sc.q_path_rad, np.full_like(sc.q_path_rad, -0.2)
    a, b = built.chain.evaluate(q, qd, qd), sc.chain.evaluate(q, qd, qd)
    assert all(np.array_equal(a[k], b[k]) for k in b)


def test_a_spatial_arm_has_no_planar_model_and_a_wrong_count_is_named():
    data = load_scenario_data("ur5-magnet-part")
    with pytest.raises(QmtInputError, match="no planar model"):
        build_arm_model(ArmData(data.arm.urdf, data.arm.hand_frame), None, planar=True, drive_required=False)
    with pytest.raises(QmtInputError, match=r"mine\.yaml: actuators\.gear_ratio has 2 entries; give 6"):
        build_arm_model(ArmData(data.arm.urdf, data.arm.hand_frame), None, gear_ratio=np.ones(2),
                        where="mine.yaml: actuators")
