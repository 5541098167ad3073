"""Inverse dynamics with gravity of a planar serial arm in a vertical plane, batched, with exact
derivatives with respect to q, qd and qdd.

Model: seed 001's eq. (1), tau = M(q) qdd + C(q, qd) + g(q), for a chain of revolute joints in
the plane (X1 horizontal, X2 up; gravity along -X2, see README.md) with point/rod links and an
optional point mass at the tip. The numbers come from the URDF through a Drake MultibodyPlant
(`VerticalArm.from_urdf`), so the plant is the single source of the parameters.

`inverse_dynamics_with_gravity(q, qd, qdd)` is the ONE adapter the planners call. It calls the
project's planar recursion (`PlanarChain` in model/planar.py, read from the same URDF), which gives
the exact derivatives too by running the same recursion on forward-mode tangents
(`PlanarChain.torque_and_derivatives`); tests/test_energy_dynamics.py checks tau against Drake's
`CalcInverseDynamics` and the derivatives against Drake's `MultibodyPlant<AutoDiffXd>`
(`drake_inverse_dynamics`, `drake_inverse_dynamics_jacobians`) to 1e-9 relative on random states.
`VerticalArm` keeps the paper's per-link parameters (lengths, rods, tip mass) for the kinematic
helpers (centre of gravity, stick figures).

Units: rad, rad/s, rad/s^2, N m. Shapes: q, qd, qdd (S, n); tau (S, n); jacobians (S, n, n),
entry [s, i, j] = d tau_i / d x_j at sample s.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, InitializeAutoDiff
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JointIndex, MultibodyForces, MultibodyForces_

from qmt_drake.config.scenario import MODELS_DIR  # noqa: E402
from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2 as GRAVITY_M_S2  # the one value
from qmt_drake.model.arm import ArmModel, add_urdf

OHSAKA_URDF = MODELS_DIR / "three_link_vertical_ohsaka.urdf"
# Drake's default gravity (UniformGravityFieldElement); the paper does not print its g.


@dataclass(frozen=True)
class VerticalArm:
    """Planar parameters of a serial arm in a vertical plane (all SI).

    gravity_up_sign: +1 means gravity acts along -X2 (X2 points up, the default reading of the
    paper); -1 flips gravity to +X2 (the literal "X2 is the gravity direction" reading), used only
    to test which reading the paper's numbers support.
    """

    length_m: np.ndarray        # (n,) joint to next joint (last: joint to tip point)
    mass_kg: np.ndarray         # (n,)
    com_m: np.ndarray           # (n,) centre of mass along the link from its joint
    izz_com_kgm2: np.ndarray    # (n,) in-plane moment of inertia about the centre of mass
    tip_mass_kg: float
    gravity_m_s2: float = GRAVITY_M_S2
    gravity_up_sign: float = 1.0
    urdf_path: Path | None = None

    @property
    def n_dof(self) -> int:
        return len(self.length_m)

    @property
    def reach_m(self) -> float:
        return float(np.sum(self.length_m))

    @property
    def gravity_vector(self) -> np.ndarray:
        return np.array([0.0, -self.gravity_up_sign * self.gravity_m_s2])

    @property
    def chain(self):
        """The project's PlanarChain of this arm's URDF (kinematics: one implementation)."""
        return _planar_chain(str(self.urdf_path or OHSAKA_URDF))

    def with_gravity_sign(self, sign: float) -> VerticalArm:
        return replace(self, gravity_up_sign=float(sign))

    @classmethod
    def from_urdf(cls, path: str | Path = OHSAKA_URDF) -> VerticalArm:
        plant = make_plant(str(path))
        ctx = plant.CreateDefaultContext()
        joints = [plant.get_joint(JointIndex(i)) for i in range(plant.num_joints())]
        joints = [j for j in joints if j.num_velocities() > 0]
        L, M, C, I = [], [], [], []  # noqa: E741 - I: the links' inertias, as in the paper
        for k, j in enumerate(joints):
            body = j.child_body()
            nxt = (joints[k + 1] if k + 1 < len(joints) else plant.GetJointByName("tip_weld")).frame_on_parent()
            L.append(float(nxt.GetFixedPoseInBodyFrame().translation()[0]))
            M.append(body.default_mass())
            C.append(float(body.default_com()[0]))
            # in-plane inertia about the com: the joint axis is -y, so I_yy
            G = body.default_unit_inertia().get_moments()[1] * body.default_mass()
            I.append(float(G - body.default_mass() * body.default_com()[0] ** 2))
        tip = plant.GetBodyByName("tip").default_mass()
        del ctx
        return cls(np.array(L), np.array(M), np.array(C), np.array(I), float(tip), urdf_path=Path(path))


@lru_cache(maxsize=4)
def make_plant(urdf: str):
    """A finalized continuous MultibodyPlant of the URDF (gravity -z, Drake's default)."""
    plant = MultibodyPlant(0.0)
    add_urdf(plant, urdf)
    plant.Finalize()
    return plant


@lru_cache(maxsize=4)
def _planar_chain(urdf: str):
    return ArmModel.from_urdf(urdf, "tip").planar


@lru_cache(maxsize=1)
def ohsaka_arm() -> VerticalArm:
    return VerticalArm.from_urdf(OHSAKA_URDF)


def inverse_dynamics_with_gravity(q, qd, qdd, arm: VerticalArm | None = None, derivatives: bool = True):
    """tau (S, n) of eq. (1) with gravity; with `derivatives`, also (dtau/dq, dtau/dqd, dtau/dqdd),
    each (S, n, n). Computed by the project's PlanarChain (model/planar.py), the one planar
    recursion; its `torque_and_derivatives` carries the tangents."""
    chain = _dynamics_chain(arm or ohsaka_arm())
    if derivatives:
        return chain.torque_and_derivatives(q, qd, qdd)
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    return chain.acceleration_and_torque(q, qd, qdd)[1]


def _dynamics_chain(arm: VerticalArm):
    """The arm's PlanarChain under the arm's gravity reading (gravity_up_sign)."""
    return _chain_under_gravity(str(arm.urdf_path or OHSAKA_URDF), tuple(arm.gravity_vector.tolist()))


@lru_cache(maxsize=8)
def _chain_under_gravity(urdf: str, g: tuple):
    # cached: the planners call this once per cost evaluation
    chain = _planar_chain(urdf)
    if np.allclose(chain.gravity_in_plane_m_s2, g, rtol=0, atol=1e-12):
        return chain
    return _flipped_chain(urdf, g)


@lru_cache(maxsize=4)
def _flipped_chain(urdf: str, g: tuple):
    return _planar_chain(urdf).with_gravity(np.array(g))


# ------------------------------------------------------------------ Drake references (tests)
def drake_inverse_dynamics(q, qd, qdd, urdf: str | Path = OHSAKA_URDF, gravity_up_sign: float = 1.0):
    """Drake's CalcInverseDynamics with gravity, sample by sample (the independent reference)."""
    plant = make_plant(str(urdf))
    ctx = plant.CreateDefaultContext()
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    out = np.empty_like(q)
    forces = MultibodyForces(plant)
    for k in range(q.shape[0]):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, qd[k])
        forces.SetZero()
        if gravity_up_sign == 1.0:
            plant.CalcForceElementsContribution(ctx, forces)  # gravity as Drake applies it
            out[k] = plant.CalcInverseDynamics(ctx, qdd[k], forces)
        else:  # flipped gravity: M qdd + C - sign * tau_g
            out[k] = (plant.CalcInverseDynamics(ctx, qdd[k], forces)
                      - gravity_up_sign * plant.CalcGravityGeneralizedForces(ctx))
    return out


def drake_inverse_dynamics_jacobians(q, qd, qdd, urdf: str | Path = OHSAKA_URDF):
    """(dtau/dq, dtau/dqd, dtau/dqdd) per sample from MultibodyPlant<AutoDiffXd>."""
    plant = make_plant(str(urdf)).ToAutoDiffXd()
    ctx = plant.CreateDefaultContext()
    q, qd, qdd = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))
    S, n = q.shape
    out = np.empty((S, n, 3 * n))
    forces = MultibodyForces_[AutoDiffXd](plant)
    for k in range(S):
        x = InitializeAutoDiff(np.concatenate([q[k], qd[k], qdd[k]])).ravel()
        plant.SetPositions(ctx, x[:n])
        plant.SetVelocities(ctx, x[n:2 * n])
        forces.SetZero()
        plant.CalcForceElementsContribution(ctx, forces)
        tau = plant.CalcInverseDynamics(ctx, x[2 * n:], forces)
        out[k] = ExtractGradient(tau)
    return out[:, :, :n], out[:, :, n:2 * n], out[:, :, 2 * n:]
