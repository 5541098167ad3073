"""The arm model: Drake plant, batched hand state (kinematics and inverse dynamics with gravity),
analytic planar IK. `ArmModel` (arm.py) is the entry point; `PlanarChain` (planar.py) and
`DrakeChain` (drake_chain.py) are its backends; `HandState` (hand_state.py) what they return."""

from qmt_drake.model.arm import ArmModel
from qmt_drake.model.hand_state import HandState
from qmt_drake.model.planar import IK_BRANCHES, PlanarChain
from qmt_drake.model.spatial_chain import SpatialChain  # any serial revolute arm, batched (spatial_chain.py)

__all__ = ["ArmModel", "HandState", "IK_BRANCHES", "PlanarChain", "SpatialChain"]
