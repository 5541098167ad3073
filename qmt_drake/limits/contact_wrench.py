"""The carried body's contact wrench in 3-D, and the magnet hand's moment limit built on it.

A body held by the hand (magnet face, suction cup, gripper) moves with the hand frame H. Given per
sample the hand's rotation R_WH, angular velocity w, angular acceleration al and the classical
acceleration a_H of H's origin (world, e.g. from SpatialChain.evaluate or a HandState), and the
gravity vector g, Newton-Euler gives the wrench the hand must apply to the body at H's origin:

    r  = R_WH c                                    (centre of mass c in H)
    f  = m (a_H + al x r + w x (w x r) - g)
    n  = I_W al + w x (I_W w) + r x f,   I_W = R_WH I_c R_WH^T   (about H's origin)

returned in H's axes as w_H = [n; f] (S, 6), moment first as in Drake's SpatialForce (and as in
tray/conditions.py's contact wrench, the special case of a body on the tray's z axis). It is affine
in qdd and quadratic in qd on a fixed path, so any limit linear in it is a toppra constraint.

MagnetMomentTerm: the thesis's payload-moment limit (seed 000, eq. 2-24) in 3-D: the moment about
the attraction face's centre in the face plane, |P_u n|, with u the face normal (hand axes), held
while <= the moment limit. With the part's centre of mass on the face normal and no hand rotation
off that normal it is m_o r_G |P_u (a - g)|, and on the thesis's horizontal arms m_o r_G |a| (the
PayloadMomentTerm of limits/payload_moment.py; tests/test_spatial_contact.py checks both equal).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from qmt_drake.limits.base import LimitTerm
from qmt_drake.limits.payload_moment import PayloadMomentTerm

FIELDS = ("rotation", "angular_velocity_rad_s", "angular_acceleration_rad_s2", "linear_acceleration_m_s2")


@dataclass(frozen=True)
class CarriedBody:
    """A rigid body held by the hand: mass (kg), centre of mass (m, hand frame H) and central inertia
    (kg m^2, H's axes)."""

    mass_kg: float
    com_m: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia_kgm2: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))

    def as_dict(self) -> dict:
        """The form SpatialChain(carried=...) and load_arm_plant(carried=...) take."""
        return {"mass_kg": float(self.mass_kg), "com_m": np.asarray(self.com_m, float),
                "inertia_kgm2": np.asarray(self.inertia_kgm2, float)}


def _get(state, name):
    return state[name] if isinstance(state, dict) else getattr(state, name)


def contact_wrench(state, gravity_m_s2, body: CarriedBody) -> np.ndarray:
    """(S, 6) wrench [n; f] (N m, N) the hand applies to `body` at H's origin, in H's axes (module
    docstring). `state`: a HandState or SpatialChain.evaluate's dict (fields FIELDS)."""
    R, w, al, a = (np.atleast_2d(_get(state, k)) if k != "rotation" else np.asarray(_get(state, k))
                   for k in FIELDS)
    R = R.reshape(-1, 3, 3)
    g = np.asarray(gravity_m_s2, float).reshape(3)
    r = R @ np.asarray(body.com_m, float)
    f = body.mass_kg * (a + np.cross(al, r) + np.cross(w, np.cross(w, r)) - g)
    RT = np.transpose(R, (0, 2, 1))
    I_c = np.asarray(body.inertia_kgm2, float)
    # moments in H's axes: I_c (R^T al) + (R^T w) x I_c (R^T w) + (R^T r) x (R^T f)
    wl, all_, fl = (np.einsum("sij,sj->si", RT, x) for x in (w, al, f))
    n = all_ @ I_c.T + np.cross(wl, wl @ I_c.T) + np.cross(np.asarray(body.com_m, float), fl)
    return np.concatenate([n, fl], axis=1)


def face_basis(normal) -> np.ndarray:
    """(3, 3) rows t1, t2, u: an orthonormal basis of H's axes with u the unit face normal."""
    u = np.asarray(normal, float) / np.linalg.norm(normal)
    t1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    return np.array([t1, np.cross(u, t1), u])


class MagnetMomentTerm(LimitTerm):
    """The face-plane moment of the carried part's contact wrench over the thesis's moment limit."""

    name = "magnet_moment"
    kind = "ratio"
    scaling = "none"
    column_names = ("magnet_moment",)
    toppra_rows = PayloadMomentTerm.toppra_rows  # |w| <= 1 as an inscribed polygon (the same rows)

    def __init__(self, body: CarriedBody, moment_limit_Nm: float, gravity_m_s2,
                 face_normal=(0.0, 0.0, 1.0)) -> None:
        self.body = body
        self.moment_limit_Nm = float(moment_limit_Nm)
        self.gravity_m_s2 = np.asarray(gravity_m_s2, float).reshape(3)
        self.basis = face_basis(face_normal)

    def face_moment_Nm(self, state) -> np.ndarray:
        """(S, 2) moment about the face centre along t1, t2 (the face plane)."""
        n = contact_wrench(state, self.gravity_m_s2, self.body)[:, :3]
        return n @ self.basis[:2].T

    def moment_Nm(self, state) -> np.ndarray:
        m = self.face_moment_Nm(state)
        return np.hypot(m[:, 0], m[:, 1])

    def columns(self, state) -> np.ndarray:
        return (self.moment_Nm(state) / self.moment_limit_Nm)[:, None]

    def toppra_w(self, state):
        return self.face_moment_Nm(state) / self.moment_limit_Nm
