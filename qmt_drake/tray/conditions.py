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
fixed path; with the cone and the ring replaced by K-gons (`slide_rows`, `tip_rows`) the limits are
F w <= g with constant F (K + K + 1 rows) and g (`linear_form`). The ratio formulas and the K-gon
rows live in limits/tray_contact.py (shared with the spatial tray hand) and are imported here. The terms
(qmt_drake/tray/limit_terms.py) use these functions for the GA, the re-check and TOPP-RA.

Kinematics: `kinematics_from_hand_state` reads the batched HandState of the planning arm (the
project's planar backend; what the limits/ terms use). `tray_kinematics` computes the same with
Drake's own algorithms sample by sample (CalcJacobianSpatialVelocity, CalcBiasSpatialAcceleration
on models/crane_x7_planar.urdf): the independent reference for tests and the co-simulation checks.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2
from qmt_drake.limits.tray_contact import lift_ratio, slide_ratio, slide_rows, tip_ratio, tip_rows
from qmt_drake.model.arm import add_urdf
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.tray.crane_ik import URDF_PATH

GRAVITY_W = np.array([0.0, 0.0, -STANDARD_GRAVITY_M_S2])  # default; a scenario's world passes its own


@dataclass(frozen=True)
class TrayKinematics:
    """Per-sample tray kinematics (S samples), world frame, SI."""

    R_WT: np.ndarray  # (S, 3, 3)
    a_G: np.ndarray  # (S, 3) acceleration of the bottle's centre of mass (moving with the tray)
    omega: np.ndarray  # (S, 3) tray angular velocity
    alpha: np.ndarray  # (S, 3) tray angular acceleration


@lru_cache(maxsize=2)
def _arm_plant(urdf: str):
    plant = MultibodyPlant(0.0)
    add_urdf(plant, urdf)
    plant.Finalize()
    return plant, plant.CreateDefaultContext()


def tray_kinematics(q, qd, qdd, p_TG, urdf=None) -> TrayKinematics:
    """ADAPTER (the only Drake call here): (S, 3) joint samples -> TrayKinematics of the point G
    fixed in the tray frame at p_TG [m] (the bottle's centre of mass when seated)."""
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


def level_tray_acceleration_cap_m_s2(bottle: BottleSpec, margin: float = 1.0,
                                     g_m_s2: float = STANDARD_GRAVITY_M_S2) -> float:
    """The largest horizontal acceleration [m/s^2] of a level tray that keeps the bottle: margin *
    min(mu, r_c / h_G) * g (no slide: mu g; no tip: g r_c / h_G), the bang-bang bound's acceleration."""
    return float(margin * min(bottle.friction, bottle.tip_ratio) * g_m_s2)


def tray_ratios(wrench: np.ndarray, bottle: BottleSpec) -> dict:
    """Ratio columns (S,) each, <= 1 feasible: slide, tip, lift (module docstring)."""
    return {"slide": slide_ratio(wrench, bottle.friction), "tip": tip_ratio(wrench, bottle.contact_radius_m),
            "lift": lift_ratio(wrench, bottle.mass_kg)}


def linear_form(bottle: BottleSpec, sides: int = 16, min_normal_force_N: float = 0.0, *, inscribed: bool = True,
                vertex_on_x: bool = False):
    """(F (2 sides + 1, 6), g) with F w <= g for w = (M_O, F) in the tray frame: the polygons of
    the friction cone (`slide_rows`) and of the ring (`tip_rows`), and F_n >= f_min."""
    S = slide_rows(bottle.friction, sides, inscribed, vertex_on_x)
    T = tip_rows(bottle.contact_radius_m, sides, inscribed, vertex_on_x)
    F = np.zeros((2 * sides + 1, 6))
    F[:sides, 3:6] = S
    F[sides:2 * sides, [0, 1, 5]] = T
    F[-1, 5] = -1.0
    g = np.zeros(2 * sides + 1)
    g[-1] = -min_normal_force_N
    return F, g


def kinematics_from_hand_state(state, p_TG) -> TrayKinematics:
    """TrayKinematics of the point G fixed in the hand (tray) frame at p_TG [m], from a batched
    HandState (model/hand_state.py; the hand frame is the tray frame): rigid-body transport
    a_G = a_O + al x r + w x (w x r), r = R_WT p_TG."""
    R = state.rotation
    r = np.einsum("sij,j->si", R, np.asarray(p_TG, float))
    w, al = state.angular_velocity_rad_s, state.angular_acceleration_rad_s2
    a_G = state.linear_acceleration_m_s2 + np.cross(al, r) + np.cross(w, np.cross(w, r))
    return TrayKinematics(R, a_G, w, al)
