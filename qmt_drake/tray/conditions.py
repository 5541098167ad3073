"""Tray limits as pure numpy physics: no slide, no tip, no lift-off of a bottle resting on the tray.

The bottle is taken to move with the tray (the limit is where that stops being possible). Given,
per sample, the tray's rotation R_WT, the bottle centre of mass's acceleration a_G, and the tray's
angular velocity w and acceleration al (all in the world frame), Newton-Euler gives the contact
wrench the tray must apply at the centre O of the bottle's base (tray frame T, z_T the surface
normal):
    F   = m (a_G - g)                                   (world), F_T = R_WT' F
    M_G = I_W al + w x (I_W w),  I_W = R_WT I_T R_WT'   (about G)
    M_O = M_G + r_OG x F,        r_OG = h_G z_T          (about O; the contact wrench at O)
Limits (tray frame):
    slide:  |F_t| <= mu F_n               F_t = (F_x, F_y), F_n = F_z
    tip:    |p_zmp| <= r_c                p_zmp = (-M_Oy, M_Ox) / F_n (centre of pressure)
    lift:   F_n > 0
Ratio columns (<= 1 feasible, for the GA and sampling checks): slide |F_t| / (mu F_n), tip
|p_zmp| / r_c, lift 1 - F_n / (m g) (> 1 when the tray pulls).

Linear form for TOPP-RA: the wrench w = (M_O, F) in T is linear in qdd and quadratic in qd on a
fixed path; with the cone and the ring replaced by inscribed K-gons the limits are F w <= g with
constant F (K + K + 1 rows) and g (`linear_form`). `toppra_constraint` wraps them as a toppra
SecondOrderConstraint whose inverse dynamics is `contact_wrench` of `tray_kinematics`.

`tray_kinematics` is the ONE adapter to Drake (CalcJacobianSpatialVelocity,
CalcBiasSpatialAcceleration on models/crane_x7_planar.urdf); the lead swaps it for the batched
hand-state backend (qmt_drake/model/ hand_state).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from qmt_drake.systems.tray_object import GRAVITY_M_S2, BottleSpec

GRAVITY_W = np.array([0.0, 0.0, -GRAVITY_M_S2])


@dataclass(frozen=True)
class TrayKinematics:
    """Per-sample tray kinematics (S samples), world frame, SI."""

    R_WT: np.ndarray  # (S, 3, 3)
    a_G: np.ndarray  # (S, 3) acceleration of the bottle's centre of mass (moving with the tray)
    omega: np.ndarray  # (S, 3) tray angular velocity
    alpha: np.ndarray  # (S, 3) tray angular acceleration


@lru_cache(maxsize=2)
def _arm_plant(urdf: str):
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(urdf)
    plant.Finalize()
    return plant, plant.CreateDefaultContext()


def tray_kinematics(q, qd, qdd, p_TG, urdf=None) -> TrayKinematics:
    """ADAPTER (the only Drake call here): (S, 3) joint samples -> TrayKinematics of the point G
    fixed in the tray frame at p_TG [m] (the bottle's centre of mass when seated)."""
    from pydrake.multibody.tree import JacobianWrtVariable
    from qmt_drake.tray.cosim import URDF_PATH
    plant, ctx = _arm_plant(str(urdf or URDF_PATH))
    frame = plant.GetFrameByName("tray")
    W = plant.world_frame()
    q, qd, qdd = (np.atleast_2d(np.asarray(a, float)) for a in (q, qd, qdd))
    S = q.shape[0]
    R = np.empty((S, 3, 3))
    a_G, omega, alpha = np.empty((S, 3)), np.empty((S, 3)), np.empty((S, 3))
    p = np.asarray(p_TG, float).reshape(3, 1)
    for k in range(S):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, qd[k])
        J = plant.CalcJacobianSpatialVelocity(ctx, JacobianWrtVariable.kV, frame, p, W, W)
        bias = plant.CalcBiasSpatialAcceleration(ctx, JacobianWrtVariable.kV, frame, p, W, W)
        A = J @ qdd[k] + np.concatenate([bias.rotational(), bias.translational()])
        R[k] = plant.CalcRelativeTransform(ctx, W, frame).rotation().matrix()
        omega[k] = J[:3] @ qd[k]
        alpha[k], a_G[k] = A[:3], A[3:]
    return TrayKinematics(R, a_G, omega, alpha)


def bottle_inertia_T(bottle: BottleSpec) -> np.ndarray:
    """(3, 3) central inertia of the bottle in its (= the tray's, when seated upright) frame."""
    return np.asarray(bottle.spatial_inertia().Shift(np.array([0.0, 0.0, bottle.com_height_m]))
                      .CalcRotationalInertia().CopyToFullMatrix3())


def contact_wrench(kin: TrayKinematics, bottle: BottleSpec, gravity_W=GRAVITY_W) -> np.ndarray:
    """(S, 6) wrench (M_O, F) the tray applies on the bottle at its base centre, in the tray frame."""
    R = kin.R_WT
    F_W = bottle.mass_kg * (kin.a_G - np.asarray(gravity_W, float))
    I_T = bottle_inertia_T(bottle)
    I_W = R @ I_T @ np.transpose(R, (0, 2, 1))
    Iw = np.einsum("sij,sj->si", I_W, kin.omega)
    M_G = np.einsum("sij,sj->si", I_W, kin.alpha) + np.cross(kin.omega, Iw)
    r_OG = bottle.com_height_m * R[:, :, 2]
    M_O = M_G + np.cross(r_OG, F_W)
    RT = np.transpose(R, (0, 2, 1))
    return np.concatenate([np.einsum("sij,sj->si", RT, M_O), np.einsum("sij,sj->si", RT, F_W)], axis=1)


def tray_ratios(wrench: np.ndarray, bottle: BottleSpec) -> dict:
    """Ratio columns (S,) each, <= 1 feasible: slide, tip, lift (module docstring)."""
    w = np.atleast_2d(wrench)
    fn = w[:, 5]
    ft = np.hypot(w[:, 3], w[:, 4])
    safe = np.where(fn > 0, fn, np.nan)
    zmp = np.hypot(w[:, 0], w[:, 1]) / safe
    mu = bottle.friction
    slide = np.where(fn > 0, ft / (mu * safe) if mu > 0 else np.where(ft > 0, np.inf, 0.0), np.inf)
    tip = np.where(fn > 0, zmp / bottle.contact_radius_m, np.inf)
    lift = 1.0 - fn / (bottle.mass_kg * GRAVITY_M_S2)
    return {"slide": slide, "tip": tip, "lift": lift}


def linear_form(bottle: BottleSpec, sides: int = 16, min_normal_force_N: float = 0.0):
    """(F (2 sides + 1, 6), g) with F w <= g for w = (M_O, F) in the tray frame: inscribed polygons
    of the friction cone (radius mu cos(pi/K) F_n) and of the ring (r_c cos(pi/K)), and F_n >= f_min."""
    a = 2.0 * math.pi * np.arange(sides) / sides
    c, s = np.cos(a), np.sin(a)
    k = math.cos(math.pi / sides)
    rows = []
    for ci, si in zip(c, s):  # slide: d . F_t - mu k F_n <= 0
        rows.append([0, 0, 0, ci, si, -bottle.friction * k])
    for ci, si in zip(c, s):  # tip: d . p F_n = ci (-M_y) + si M_x <= r k F_n
        rows.append([si, -ci, 0, 0, 0, -bottle.contact_radius_m * k])
    rows.append([0, 0, 0, 0, 0, -1.0])  # lift: -F_n <= -f_min
    F = np.array(rows, float)
    g = np.zeros(len(rows))
    g[-1] = -min_normal_force_N
    return F, g


def toppra_constraint(bottle: BottleSpec, sides: int = 16, p_TG=None):
    """toppra SecondOrderConstraint of the tray limits (the bottle seated at the tray centre)."""
    import toppra.constraint as tc
    p = np.array([0.0, 0.0, bottle.com_height_m]) if p_TG is None else np.asarray(p_TG, float)
    F, g = linear_form(bottle, sides)

    def inv_dyn(q, qd, qdd):
        return contact_wrench(tray_kinematics(q, qd, qdd, p), bottle)[0]

    return tc.SecondOrderConstraint(inv_dyn, lambda q: F, lambda q: g, dof=3,
                                    discretization_scheme=tc.DiscretizationType.Interpolation)


def _tray_constraint_class():
    import toppra.constraint as tc
    from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate

    class TrayConstraint(tc.SecondOrderConstraint):
        """SecondOrderConstraint whose a, b, c come from three batched `contact_wrench` calls
        instead of 3 (gridpoints) Python calls of inv_dyn."""

        def __init__(self, bottle: BottleSpec, sides: int, p_TG):
            F, g = linear_form(bottle, sides)
            self._bottle, self._p = bottle, p_TG
            super().__init__(lambda q, qd, qdd: contact_wrench(tray_kinematics(q, qd, qdd, p_TG), bottle)[0],
                             lambda q: F, lambda q: g, dof=3,
                             discretization_scheme=tc.DiscretizationType.Interpolation)
            self._F, self._g = F, g

        def compute_constraint_params(self, path, gridpoints):
            p, ps, pss = path(gridpoints), path(gridpoints, 1), path(gridpoints, 2)
            z = np.zeros_like(p)
            w = lambda qd, qdd: contact_wrench(tray_kinematics(p, qd, qdd, self._p), self._bottle)  # noqa: E731
            c = w(z, z)
            a = w(z, ps) - c
            b = w(ps, pss) - c
            n = len(gridpoints)
            F = np.broadcast_to(self._F, (n, *self._F.shape)).copy()
            g = np.broadcast_to(self._g, (n, len(self._g))).copy()
            return canlinear_colloc_to_interpolate(a, b, c, F, g, None, None, gridpoints)

    return TrayConstraint


def tray_constraint(bottle: BottleSpec, sides: int = 16, p_TG=None):
    """The tray limits as a (batched) toppra SecondOrderConstraint; same physics as
    `toppra_constraint`, a and b from three batched kinematics passes."""
    p = np.array([0.0, 0.0, bottle.com_height_m]) if p_TG is None else np.asarray(p_TG, float)
    return _tray_constraint_class()(bottle, sides, p)
