"""A suction-cup (or magnet) grip as a linear contact-stability constraint on the contact wrench.

Model (after Pham & Pham, "Critically fast pick-and-place with suction cups", ICRA 2019, arXiv
1809.03151: the cup as contacts on its rim plus the vacuum force, the stable wrenches a polyhedral
set, a linear constraint TOPP-RA takes). In the grip frame C (origin at the cup's centre = H's
origin, z = u the face normal pointing from the hand into the part):

- the rim touches the part at `rim_points` points p_i = r (cos t_i, sin t_i, 0); each can push the
  part (along +u) with Coulomb friction mu, the cone replaced by the inscribed pyramid of
  `pyramid_edges` edges d_ij = u + mu (cos s_j, sin s_j, 0), s_j = pyramid_angle_rad + 2 pi j /
  pyramid_edges (conservative: never allows more);
- the vacuum (or the magnet's pull) pulls the part onto the cup with a constant force F along -u.

The wrench the hand may apply to the part at C's origin is then w = sum_ij l_ij [p_i x d_ij; d_ij]
+ [0; -F u] with l_ij >= 0: w - w_F lies in the polyhedral cone of the generators. Its faces
(`GripModel.rows`, from the convex hull of the origin and the unit generators: scipy's Qhull) give
F_k w <= g_k, every row linear in the wrench: the normal force (no separation: the pull is not
overcome), the friction pyramid, the tipping moments (the centre of pressure stays within the rim)
and the twist, coupled as the rim contacts couple them. g_k = F_k w_F > 0 for every face.

SuctionTerm: the ratio column max_k (F_k w) / g_k (<= 1: held), w the contact wrench of the
carried body (limits/contact_wrench.py) in H's axes; for TOPP-RA toppra_w = w and rows F_k / g_k
<= 1 (unit scale). Linear in w, hence affine in qdd and quadratic in qd on a fixed path.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.spatial import ConvexHull

from qmt_drake.limits.base import LimitTerm, RowOptions
from qmt_drake.limits.contact_wrench import CarriedBody, contact_wrench, face_basis


class GripModel:
    """The contact-stability polyhedron of a flat grip of radius `radius_m` with pull `pull_force_N`,
    friction `friction`, face normal `face_normal` (H's axes)."""

    def __init__(self, radius_m: float, pull_force_N: float, friction: float, *, face_normal=(0.0, 0.0, 1.0),
                 rim_points: int = 8, pyramid_edges: int = 4, pyramid_angle_rad: float = 0.0) -> None:
        if radius_m <= 0 or pull_force_N <= 0 or friction <= 0 or rim_points < 3 or pyramid_edges < 3:
            raise ValueError("a grip needs radius, pull force and friction > 0, >= 3 rim points and pyramid edges")
        self.radius_m, self.pull_force_N, self.friction = float(radius_m), float(pull_force_N), float(friction)
        self.basis = face_basis(face_normal)  # rows t1, t2, u in H's axes
        self.rim_points, self.pyramid_edges = int(rim_points), int(pyramid_edges)
        self.pyramid_angle_rad = float(pyramid_angle_rad)
        self.F, self.g = self._rows()

    def generators(self) -> np.ndarray:
        """(rim_points * pyramid_edges, 6) unit-force contact wrenches [p x d; d] in C's axes."""
        t = 2 * np.pi * np.arange(self.rim_points) / self.rim_points
        s = self.pyramid_angle_rad + 2 * np.pi * np.arange(self.pyramid_edges) / self.pyramid_edges
        p = self.radius_m * np.stack([np.cos(t), np.sin(t), np.zeros_like(t)], axis=1)
        d = np.stack([self.friction * np.cos(s), self.friction * np.sin(s), np.ones_like(s)], axis=1)
        P = np.repeat(p, len(d), axis=0)
        D = np.tile(d, (len(p), 1))
        return np.concatenate([np.cross(P, D), D], axis=1)

    def _rows(self):
        G = self.generators()
        scale = np.r_[np.full(3, 1.0 / self.radius_m), np.ones(3)]  # moments in units of r: a round hull
        pts = G * scale
        pts /= np.linalg.norm(pts, axis=1, keepdims=True)
        hull = ConvexHull(np.vstack([np.zeros(6), pts]))
        eq = hull.equations[np.abs(hull.equations[:, -1]) < 1e-9][:, :6]  # faces through the origin
        eq = eq / np.linalg.norm(eq, axis=1, keepdims=True)
        # Qhull splits a face with more than 6 vertices into simplices sharing its normal: keep one
        _, first = np.unique(np.round(eq, 8), axis=0, return_index=True)
        H_C = eq[np.sort(first)] * scale  # h . (w scaled) <= 0  <=>  (h * scale) . w <= 0
        R_CH = self.basis  # rows: C's axes in H's axes, so w_C = blockdiag(R_CH) w_H
        F = np.concatenate([H_C[:, :3] @ R_CH, H_C[:, 3:] @ R_CH], axis=1)
        w_pull = np.r_[np.zeros(3), -self.pull_force_N * self.basis[2]]
        g = F @ w_pull
        if np.any(g <= 0):
            raise ValueError("grip model: a face of the contact cone does not involve the normal force")
        return F, g

    def holds(self, wrench_H) -> np.ndarray:
        """(S,) ratio max_k F_k w / g_k of wrenches [n; f] at C's origin in H's axes (<= 1: held)."""
        return np.max(np.atleast_2d(wrench_H) @ (self.F / self.g[:, None]).T, axis=1)


@lru_cache(maxsize=64)
def _cached_grip(radius_m, pull_force_N, friction, face_normal, rim_points, pyramid_edges, pyramid_angle_rad):
    return GripModel(radius_m, pull_force_N, friction, face_normal=face_normal, rim_points=rim_points,
                     pyramid_edges=pyramid_edges, pyramid_angle_rad=pyramid_angle_rad)


def cached_grip(radius_m: float, pull_force_N: float, friction: float, *, face_normal=(0.0, 0.0, 1.0),
                rim_points: int = 8, pyramid_edges: int = 4, pyramid_angle_rad: float = 0.0) -> GripModel:
    """GripModel(...) built once per distinct set of arguments (its hull takes about 0.1-1 s at 24x8): the
    shared instance must not be modified."""
    return _cached_grip(float(radius_m), float(pull_force_N), float(friction),
                        tuple(float(v) for v in np.asarray(face_normal, float).reshape(3)), int(rim_points),
                        int(pyramid_edges), float(pyramid_angle_rad))


class SuctionTerm(LimitTerm):
    """The carried body held by a GripModel (suction cup, or a magnet's face with its pull)."""

    kind = "ratio"
    scaling = "none"

    def __init__(self, grip: GripModel, body: CarriedBody, gravity_m_s2, name: str = "suction") -> None:
        self.grip, self.body = grip, body
        self.gravity_m_s2 = np.asarray(gravity_m_s2, float).reshape(3)
        self.name = name
        self.column_names = (name,)

    def wrench(self, state) -> np.ndarray:
        return contact_wrench(state, self.gravity_m_s2, self.body)

    def columns(self, state) -> np.ndarray:
        return self.grip.holds(self.wrench(state))[:, None]

    def toppra_w(self, state):
        return self.wrench(state)

    def toppra_rows(self, options: RowOptions):
        return self.grip.F / self.grip.g[:, None], np.ones(len(self.grip.g))
