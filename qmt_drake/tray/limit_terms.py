"""Tray limits as terms (seed 002): an unfixed bottle on a tray must not slide, tip or lift off.

The physics is qmt_drake/tray/conditions.py (one implementation): from the batched HandState of
the planning arm, whose hand frame is the tray frame T (z_T the surface normal), the bottle's
centre of mass G = (x0, y0, h_G) in T moves with the tray (`kinematics_from_hand_state`), and
Newton-Euler gives the wrench w = (M_O, F) the tray applies at the centre O of its base, in T,
with gravity and the tray's own rotation (`contact_wrench`). Three terms read it:

    tray_slide   |F_t| / (mu F_n)           <= 1   (friction cone)
    tray_tip     |p_zmp| / r_c              <= 1   (zero-moment point inside the base ring)
    tray_lift    1 - F_n / (m g)            <= 1   (F_n >= 0: the tray never pulls)

All three are "ratio" columns with scaling "none" (gravity: playing a motion slower does not
divide them by lam^2). The wrench of a sample is computed once and shared by the three terms
(kept on the HandState object).

TOPP-RA: w is affine in qdd and quadratic in qd on a fixed path, so each term gives toppra_w and
rows F w <= g (conditions.slide_rows / tip_rows, inscribed K-gons with K = `tray_polygon_sides`,
default 4; a vertex on the tray's x axis when `vertex_on_chord`). On a planar arm the tangential
force and the centre of pressure lie on the tray's x axis, where the polygons have a vertex: then
the rows are exact for any K (tests/test_tray_limits.py), and K = 4 keeps toppra's row count and
time lowest (1000-point line: ~35 ms CPU vs ~42 ms with K = 16). `polygon_sides` (the payload
moment's polygon in the shared TOPP-RA planner) does not apply to these rows. w is scaled
to unit size (forces by m g, moments by m g r_c): toppra's tolerances are absolute.

`margin` (0, 1] scales mu and r_c for planning (the servos lag the plan: it keeps room); the
re-check of a plan uses the same terms, so a plan made with margin 0.8 is feasible against 0.8 mu.

JointSpeedTerm: |qd_i| / (fraction v_i) <= 1 with v_i the servos' no-load speeds when given (the
datasheet: a servo cannot turn faster unloaded), else the URDF's joint velocity limits; for TOPP-RA
(qd_i / (fraction v_i))^2 <= 1, quadratic in qd.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2
from qmt_drake.limits.base import LimitTerm, RowOptions
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.tray.conditions import (
    contact_wrench,
    kinematics_from_hand_state,
    slide_ratio,
    slide_rows,
    tip_ratio,
    tip_rows,
)


class TrayContact:
    """The bottle seated on the tray (at (x0, y0) [m] in T) and its contact wrench per HandState."""

    def __init__(self, bottle: BottleSpec, margin: float = 1.0, seat_xy_m=(0.0, 0.0),
                 gravity_m_s2=(0.0, 0.0, -STANDARD_GRAVITY_M_S2)) -> None:
        if not 0 < margin <= 1:
            raise ValueError(f"tray planning margin {margin} must lie in (0, 1]")
        self.bottle = bottle
        self.margin = float(margin)
        self.friction = bottle.friction * margin
        self.contact_radius_m = bottle.contact_radius_m * margin
        self.p_TG = np.array([seat_xy_m[0], seat_xy_m[1], bottle.com_height_m], float)
        self.gravity_W = np.asarray(gravity_m_s2, float)  # the scenario's world gravity [m/s^2]
        self.weight_N = bottle.mass_kg * float(np.linalg.norm(self.gravity_W))
        self._key = f"_tray_wrench_{id(self)}"

    def planning_bottle(self) -> BottleSpec:
        return replace(self.bottle, friction=self.friction, contact_radius_m=self.contact_radius_m)

    def wrench(self, state) -> np.ndarray:
        """(S, 6) (M_O, F) in T [N m, N], computed once per HandState."""
        w = state.__dict__.get(self._key)
        if w is None:
            # moments about O = G - h_G z_T, the base centre under G (contact_wrench)
            w = contact_wrench(kinematics_from_hand_state(state, self.p_TG), self.bottle, self.gravity_W)
            state.__dict__[self._key] = w
        return w


class _TrayTerm(LimitTerm):
    kind = "ratio"
    scaling = "none"

    def __init__(self, contact: TrayContact) -> None:
        self.contact = contact


class TraySlideTerm(_TrayTerm):
    name = "tray_slide"
    column_names = ("tray_slide",)

    def columns(self, state) -> np.ndarray:
        return slide_ratio(self.contact.wrench(state), self.contact.friction)[:, None]

    def toppra_w(self, state):
        return self.contact.wrench(state)[:, 3:6] / self.contact.weight_N

    def toppra_rows(self, options: RowOptions):
        R = slide_rows(self.contact.friction, options.tray_polygon_sides, options.inscribed, options.vertex_on_chord)
        return R, np.zeros(len(R))


class TrayTipTerm(_TrayTerm):
    name = "tray_tip"
    column_names = ("tray_tip",)

    def columns(self, state) -> np.ndarray:
        return tip_ratio(self.contact.wrench(state), self.contact.contact_radius_m)[:, None]

    def toppra_w(self, state):
        w = self.contact.wrench(state)
        scale = self.contact.weight_N * self.contact.contact_radius_m
        return np.stack([w[:, 0] / scale, w[:, 1] / scale, w[:, 5] / self.contact.weight_N], axis=1)

    def toppra_rows(self, options: RowOptions):
        R = tip_rows(1.0, options.tray_polygon_sides, options.inscribed, options.vertex_on_chord)  # moments over r_c
        return R, np.zeros(len(R))


class TrayLiftTerm(_TrayTerm):
    name = "tray_lift"
    column_names = ("tray_lift",)

    def columns(self, state) -> np.ndarray:
        return 1.0 - self.contact.wrench(state)[:, 5:6] / self.contact.weight_N  # conditions.lift_ratio

    def toppra_w(self, state):
        return self.contact.wrench(state)[:, 5:6] / self.contact.weight_N

    def toppra_rows(self, options: RowOptions):
        return np.array([[-1.0]]), np.zeros(1)  # F_n >= 0


def tray_terms(bottle: BottleSpec, margin: float = 1.0, seat_xy_m=(0.0, 0.0),
               gravity_m_s2=(0.0, 0.0, -STANDARD_GRAVITY_M_S2)) -> list:
    """[slide, tip, lift] sharing one TrayContact (gravity_m_s2: the world's, as the arm's plant)."""
    c = TrayContact(bottle, margin, seat_xy_m, gravity_m_s2)
    return [TraySlideTerm(c), TrayTipTerm(c), TrayLiftTerm(c)]
