"""sim/spatial_hold.step_into_sample: a logged acceleration is that of the step INTO its sample's state,
whether the discrete plant's output ports are sampled or live (checked against the plant's own velocity
update, v_j - v_{j-1} = h vdot_j)."""

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlant, MultibodyPlantConfig
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, Multiplexer

from qmt_drake.sim.spatial_hold import step_into_sample

PENDULUM = """<robot name="p"><link name="base"/><link name="l"><inertial><mass value="1"/>
<origin xyz="0 0 -0.5"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j" type="revolute"><parent link="base"/><child link="l"/><axis xyz="0 1 0"/>
<limit effort="100" velocity="10" lower="-10" upper="10"/></joint></robot>"""


@pytest.mark.parametrize("sampled", [True, False])
def test_the_logged_acceleration_is_the_step_into_the_sample(sampled):
    h = 1e-3
    b = DiagramBuilder()
    plant, _ = AddMultibodyPlant(MultibodyPlantConfig(time_step=h, use_sampled_output_ports=sampled), b)
    Parser(plant).AddModelsFromString(PENDULUM, "urdf")
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base"))
    plant.Finalize()
    mux = b.AddSystem(Multiplexer([2, 1]))
    b.Connect(plant.get_state_output_port(), mux.get_input_port(0))
    b.Connect(plant.get_generalized_acceleration_output_port(), mux.get_input_port(1))
    log = LogVectorOutput(mux.get_output_port(), b, h)
    sim = Simulator(b.Build())
    plant.SetPositions(plant.GetMyMutableContextFromRoot(sim.get_mutable_context()), [0.7])
    sim.AdvanceTo(0.05)
    raw = log.FindLog(sim.get_context()).data()
    d = step_into_sample(plant, raw, 2)
    v, a = d[1], d[2]
    assert np.allclose(np.diff(v)[1:], h * a[2:], rtol=1e-12, atol=1e-15)
    if not sampled:  # unshifted, the live port is one step ahead: the check above would fail
        assert not np.allclose(np.diff(v)[1:], h * raw[2, 2:], rtol=1e-6)
