"""The held part's moment about the hand's attraction face (seed 000, eq. 2-24, 3-10, 4-33).

The part's centre of mass sits r_G from the face. A hand accelerating at a (gravity g) loads it
with m_o (a - g); the component along the face pulls it sideways with moment

    tau_M = m_o * r_G * |P_face (a - g)|,   P_face = I - n n^T, n the face normal (hand z axis),

held while tau_M <= the moment limit. On the thesis's horizontal arms the face is the arm's plane
and g is normal to it, so tau_M = m_o r_G |a_tip| exactly: the column is then computed from the
in-plane acceleration (the planning hot path), and it is purely inertial (scaling lam^-2).
"""

from __future__ import annotations

import numpy as np

from qmt_drake.limits.base import LimitTerm, RowOptions


class PayloadMomentTerm(LimitTerm):
    name = "payload_moment"
    kind = "ratio"
    column_names = ("payload_moment",)

    def __init__(self, arm, moment_per_accel_kgm: float, moment_limit_Nm: float) -> None:
        self.moment_per_accel_kgm = float(moment_per_accel_kgm)
        self.moment_limit_Nm = float(moment_limit_Nm)
        self.accel_limit_m_s2 = self.moment_limit_Nm / self.moment_per_accel_kgm  # A
        p = arm.planar
        face_normal = p.hand_rotation_at_zero[:, 2] if p is not None else None
        # The face stays in the arm's plane when its normal is the plane normal.
        self.in_plane = p is not None and abs(abs(face_normal @ p.normal) - 1.0) < 1e-12
        self.gravity_in_plane = p.gravity_in_plane_m_s2 if self.in_plane else None
        self.gravity_m_s2 = np.asarray(arm.plant.gravity_field().gravity_vector(), float)
        inertial = self.in_plane and not np.any(self.gravity_in_plane)
        self.scaling = "inverse_square" if inertial else "none"
        self._g_plane = (float(self.gravity_in_plane[0]), float(self.gravity_in_plane[1])) if self.in_plane else None

    def face_acceleration(self, state) -> np.ndarray:
        """P_face (a - g): (S, 2) in plane coordinates when in_plane, else (S, 3) in world."""
        if self.in_plane:
            return state.planar_acceleration_m_s2 - self.gravity_in_plane
        s = state.linear_acceleration_m_s2 - self.gravity_m_s2
        n = state.rotation[:, :, 2]
        return s - np.einsum("si,si->s", s, n)[:, None] * n

    def moment_Nm(self, state) -> np.ndarray:
        if self.in_plane:  # the hot path of planning: two columns, no (S, 2) temporaries
            a = state.planar_acceleration_m_s2
            return self.moment_per_accel_kgm * np.hypot(a[:, 0] - self._g_plane[0], a[:, 1] - self._g_plane[1])
        a = self.face_acceleration(state)
        return self.moment_per_accel_kgm * np.sqrt(np.sum(a * a, axis=-1))

    def columns(self, state) -> np.ndarray:
        return (self.moment_Nm(state) / self.moment_limit_Nm)[:, None]

    def toppra_w(self, state):
        if not self.in_plane:
            return None
        return self.face_acceleration(state) / self.accel_limit_m_s2

    def toppra_rows(self, options: RowOptions):
        """|w| <= 1 as a polygon of options.polygon_sides normals, turned so a vertex (or, with
        vertex_on_chord=False, an edge normal) points along angle0_rad; inscribed in the circle (never
        allows more than the limit) or circumscribed (never less)."""
        polygon_sides, angle0_rad = options.polygon_sides, options.angle0_rad
        inscribed, vertex_on_chord = options.inscribed, options.vertex_on_chord
        offset = np.pi / polygon_sides if vertex_on_chord else 0.0
        theta = angle0_rad + offset + 2 * np.pi * np.arange(polygon_sides) / polygon_sides
        F = np.stack([np.cos(theta), np.sin(theta)], axis=1)
        g = np.full(polygon_sides, np.cos(np.pi / polygon_sides) if inscribed else 1.0)
        return F, g
