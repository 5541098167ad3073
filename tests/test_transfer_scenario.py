"""The transfer scenario without hooks (issue 27 item 1): config/ gives plain data, the built objects
come from transfer_scenario.TransferScenario (plain imports of builders.py), and the loader's checks that
need the arm run wherever plain data is built."""

import dataclasses
import pickle

import numpy as np
import pytest

from qmt_drake import builders
from qmt_drake.api import _scenario_arg
from qmt_drake.config.scenario import Scenario, load_transfer_data
from qmt_drake.errors import QmtInputError
from qmt_drake.transfer_scenario import TransferScenario, build_transfer_scenario, load_scenario


def test_the_data_has_no_built_object_and_the_built_scenario_the_same_fingerprint():
    data = load_transfer_data("thesis-ch4")
    assert type(data) is Scenario
    assert not any(hasattr(data, k) for k in ("arm", "limit_set", "bottle", "gear_ratio"))
    sc = load_scenario("thesis-ch4")
    assert isinstance(sc, TransferScenario) and sc.fingerprint() == data.fingerprint()
    assert type(sc.data()) is Scenario and sc.data().fingerprint() == data.fingerprint()  # plain data back


def test_built_objects_once_per_object_rebuilt_after_pickle_and_replace():
    sc = load_scenario("thesis-ch4")
    assert sc.arm is sc.arm and sc.limit_set.arm is sc.arm
    back = pickle.loads(pickle.dumps(sc))
    assert "arm" not in vars(back)  # the Drake objects are not pickled ...
    assert back.arm is not sc.arm and back.arm.n_dof == sc.arm.n_dof  # ... but rebuilt from the data
    heavier = dataclasses.replace(sc, payload=dataclasses.replace(sc.payload, mass_kg=2 * sc.payload.mass_kg))
    assert isinstance(heavier, TransferScenario) and "arm" not in vars(heavier)
    q, qd, qdd = np.zeros(sc.arm.n_dof), np.zeros(sc.arm.n_dof), np.ones(sc.arm.n_dof)
    # the carried part is welded into the arm: a heavier part needs more torque (no stale arm)
    assert not np.allclose(heavier.arm.joint_torque(q, qd, qdd), sc.arm.joint_torque(q, qd, qdd))
    assert builders.build_arm(sc).n_dof == sc.arm.n_dof


def test_plain_data_is_checked_against_its_arm_when_built():
    data = load_transfer_data("thesis-ch4")
    bad = dataclasses.replace(data, limits=dataclasses.replace(data.limits, motor_torque_limit_Nm=np.ones(1)))
    with pytest.raises(QmtInputError, match="motor_torque_limit_Nm has 1 entries but the arm"):
        build_transfer_scenario(bad)
    with pytest.raises(QmtInputError, match="motor_torque_limit_Nm has 1 entries but the arm"):
        _scenario_arg(bad, "plan_with")  # the API builds plain data it is given, with the same checks
    assert isinstance(_scenario_arg(data, "plan_with"), TransferScenario)


def test_uncertainty_distributions_checked_at_load_without_a_registered_validator():
    u = {"uncertainty": {"parameters": {"no_such_parameter": {"dist": "normal", "mean": 1.0, "std": 0.1}}}}
    assert load_transfer_data("thesis-ch4", overrides=u).uncertainty  # the data layer checks the shape only
    with pytest.raises(QmtInputError, match="unknown parameter 'no_such_parameter'"):
        load_scenario("thesis-ch4", overrides=u)
