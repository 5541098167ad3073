"""A tray hand in 3-D: an unfixed cup standing on a flat tray fixed to the hand must not lift off,
slide or tip.

Geometry (SI): the tray surface is the face plane through the hand frame H's origin, its normal u the
hand's face axis (H's axes); the cup, a cylinder of radius r, height h_c and mass m, stands with its
base centre O on H's origin, its centre of mass G on u at height h_G (default h_c / 2). T is the
tray frame: H's origin, axes t1, t2, u (limits/contact_wrench.face_basis).

While the cup moves with the tray, limits/contact_wrench.contact_wrench gives the wrench [n; f] the
tray applies to it at O (Newton-Euler with gravity, H's axes); turned into T it is the seed-002
tray wrench w = (M_O, F) of tray/conditions.py (there for a bottle on the planar CRANE-X7's tray;
tests/test_spatial_tray.py checks the two equal on random planar motions). The limits, in T:

    lift:   F_n > 0                           lift_ratio   1 - F_n / (m |g|)      (<= 1)
    slide:  |F_t| <= mu F_n                   slide_ratio  |F_t| / (mu F_n)
    tip:    |(-M_Oy, M_Ox)| <= r F_n          tip_ratio    |p_cop| / r            (centre of pressure
                                                           inside the base circle)

`margin` in (0, 1] scales mu and r (room for tracking error), as tray/limit_terms.TrayContact does.
The ratio formulas and the K-gon rows (`slide_rows`, `tip_rows`, moved here from tray/conditions.py,
which imports them: one implementation) are pure numpy.

TrayContactTerm: one LimitTerm, columns (tray_slide, tray_tip, tray_lift) from the circles; for
TOPP-RA the friction cone and the base circle are inscribed K-gons (K = `pyramid_edges`: never
allows more than the circle), rows F w_s <= 0 on the wrench scaled to unit size (forces over the
weight m |g|, moments over m |g| r): toppra's tolerances are absolute.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from qmt_drake.config.scenario import STANDARD_GRAVITY_M_S2
from qmt_drake.limits.base import LimitTerm, RowOptions
from qmt_drake.limits.contact_wrench import CarriedBody, contact_wrench, face_basis


def slide_ratio(wrench: np.ndarray, friction: float) -> np.ndarray:
    """|F_t| / (mu F_n) (S,) of tray wrenches (M_O, F) in T: <= 1 while the object can stick; inf
    without normal force."""
    w = np.atleast_2d(wrench)
    fn, ft = w[:, 5], np.hypot(w[:, 3], w[:, 4])
    with np.errstate(divide="ignore", invalid="ignore"):
        r = ft / (friction * fn) if friction > 0 else np.where(ft > 0, np.inf, 0.0)
    return np.where(fn > 0, r, np.inf)


def tip_ratio(wrench: np.ndarray, contact_radius_m: float) -> np.ndarray:
    """|p_zmp| / r_c (S,): <= 1 while the centre of pressure is inside the base ring."""
    w = np.atleast_2d(wrench)
    fn = w[:, 5]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.hypot(w[:, 0], w[:, 1]) / (fn * contact_radius_m)
    return np.where(fn > 0, r, np.inf)


def lift_ratio(wrench: np.ndarray, mass_kg: float, g_m_s2: float = STANDARD_GRAVITY_M_S2) -> np.ndarray:
    """1 - F_n / (m g) (S,): <= 1 while the tray pushes (> 1 when it would have to pull)."""
    return 1.0 - np.atleast_2d(wrench)[:, 5] / (mass_kg * g_m_s2)


def polygon(sides: int, inscribed: bool, vertex_on_x: bool):
    """Unit normals (cos, sin) of a regular K-gon about the unit circle and its apothem factor:
    inscribed (apothem cos(pi/K): never allows more than the circle) or circumscribed (1). With
    vertex_on_x a vertex lies on +x (and, K even, on -x): exact for forces in the arm's plane."""
    if sides < 3:
        raise ValueError(f"polygon needs at least 3 sides, got {sides}")
    a = 2.0 * math.pi * np.arange(sides) / sides + (math.pi / sides if vertex_on_x else 0.0)
    return np.cos(a), np.sin(a), (math.cos(math.pi / sides) if inscribed else 1.0)


def slide_rows(friction: float, sides: int = 16, inscribed: bool = True, vertex_on_x: bool = False) -> np.ndarray:
    """(K, 3) rows R with R (F_x, F_y, F_n) <= 0: the friction cone as a K-sided pyramid."""
    c, s, k = polygon(sides, inscribed, vertex_on_x)
    return np.stack([c, s, np.full(sides, -friction * k)], axis=1)


def tip_rows(contact_radius_m: float, sides: int = 16, inscribed: bool = True, vertex_on_x: bool = False) -> np.ndarray:
    """(K, 3) rows R with R (M_x, M_y, F_n) <= 0: the centre of pressure p = (-M_y, M_x) / F_n in a
    K-gon of the ring (d . p F_n <= r_c k F_n)."""
    c, s, k = polygon(sides, inscribed, vertex_on_x)
    return np.stack([s, -c, np.full(sides, -contact_radius_m * k)], axis=1)


def cylinder_inertia_kgm2(mass_kg: float, radius_m: float, height_m: float) -> np.ndarray:
    """(3, 3) central inertia of a solid cylinder about its axes (axis z)."""
    ixx = mass_kg * (3.0 * radius_m ** 2 + height_m ** 2) / 12.0
    return np.diag([ixx, ixx, 0.5 * mass_kg * radius_m ** 2])


@dataclass(frozen=True)
class TrayCup:
    """The cup on the tray (module docstring): a solid cylinder, friction mu against the tray,
    planning margin, the K of the TOPP-RA polygons, and the tray's size (a, b, thickness) [m]."""

    radius_m: float
    height_m: float
    mass_kg: float
    friction: float
    com_height_m: float | None = None  # default height / 2
    margin: float = 1.0
    pyramid_edges: int = 8
    tray_size_m: tuple = (0.24, 0.16, 0.005)  # the seed-002 tray's (systems/tray_object.TRAY_SIZE_M)

    def __post_init__(self) -> None:
        if not (self.radius_m > 0 and self.height_m > 0 and self.mass_kg > 0 and self.friction > 0):
            raise ValueError("a tray cup needs radius, height, mass and friction > 0")
        if not 0 < self.margin <= 1 or self.pyramid_edges < 3:
            raise ValueError("tray margin must lie in (0, 1] and pyramid_edges be >= 3")
        if not 0 < self.h_G < self.height_m:
            raise ValueError("the cup's centre of mass must lie inside it")

    @property
    def h_G(self) -> float:
        return self.height_m / 2 if self.com_height_m is None else float(self.com_height_m)

    def inertia_T(self) -> np.ndarray:
        """Central inertia in the cup's (= T's) axes; a solid cylinder of the cup's size, its centre of
        mass shifted to h_G keeps the cylinder's central moments (the contents' inertia, approximately)."""
        return cylinder_inertia_kgm2(self.mass_kg, self.radius_m, self.height_m)

    def body(self, face_axis=(0.0, 0.0, 1.0)) -> CarriedBody:
        """The cup as a body carried by the hand (H's axes)."""
        B = face_basis(face_axis)  # rows t1, t2, u: R_TH
        return CarriedBody(self.mass_kg, self.h_G * B[2], B.T @ self.inertia_T() @ B)


class TrayContactTerm(LimitTerm):
    """The cup on the tray: lift-off, friction cone and centre of pressure (module docstring)."""

    name = "tray"
    kind = "ratio"
    scaling = "none"
    column_names = ("tray_slide", "tray_tip", "tray_lift")

    def __init__(self, cup: TrayCup, gravity_m_s2, face_axis=(0.0, 0.0, 1.0)) -> None:
        self.cup = cup
        self.body = cup.body(face_axis)
        self.basis = face_basis(face_axis)
        self.gravity_m_s2 = np.asarray(gravity_m_s2, float).reshape(3)
        self.g_m_s2 = float(np.linalg.norm(self.gravity_m_s2))
        self.weight_N = cup.mass_kg * self.g_m_s2
        self.friction = cup.friction * cup.margin
        self.radius_m = cup.radius_m * cup.margin

    def wrench_T(self, state) -> np.ndarray:
        """(S, 6) (M_O, F) [N m, N] the tray applies to the cup at its base centre, T's axes."""
        w = contact_wrench(state, self.gravity_m_s2, self.body)
        return np.concatenate([w[:, :3] @ self.basis.T, w[:, 3:] @ self.basis.T], axis=1)

    def ratios(self, wrench_T) -> np.ndarray:
        return np.stack([slide_ratio(wrench_T, self.friction), tip_ratio(wrench_T, self.radius_m),
                         lift_ratio(wrench_T, self.cup.mass_kg, self.g_m_s2)], axis=1)

    def columns(self, state) -> np.ndarray:
        return self.ratios(self.wrench_T(state))

    def toppra_w(self, state):
        w = self.wrench_T(state)
        return np.concatenate([w[:, :3] / (self.weight_N * self.radius_m), w[:, 3:] / self.weight_N], axis=1)

    def toppra_rows(self, options: RowOptions):
        K = self.cup.pyramid_edges
        F = np.zeros((2 * K + 1, 6))
        F[:K, 3:6] = slide_rows(self.friction, K)
        F[K:2 * K, [0, 1, 5]] = tip_rows(1.0, K)  # moments over r
        F[-1, 5] = -1.0  # F_n >= 0
        return F, np.zeros(2 * K + 1)
