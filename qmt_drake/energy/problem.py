"""The constrained problem of seed 001 for one coordinate vector (X(0), X(T)):

    minimise z(y)  over the reduced genes y (fourier.py)
    subject to  FK(theta_T) = X(T)   (eq. 4 at t = T; 2 equations)
                T_min <= T <= T_max, optional frozen genes (fixed T, joints that do not move).

theta0 comes from the start-posture rule (kinematics.lowest_cog_posture) unless given. Input
errors (out of reach, m < 1, bad c1/c2) raise QmtInputError here, before any solve.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from qmt_drake.energy.dynamics import VerticalArm, ohsaka_arm
from qmt_drake.energy.fourier import FourierVelocityFamily
from qmt_drake.energy.kinematics import check_reachable, lowest_cog_posture, tip_jacobian, tip_position
from qmt_drake.energy.objective import PAPER_DIVISIONS, EnergyObjective, check_weights
from qmt_drake.errors import QmtInputError

T_MIN_S = 0.02
T_MAX_S = 100.0
# No bounds on coefficients and angles: an interior-point solver (IPOPT) puts a log barrier on
# every finite bound, and wide boxes then drag the iterate to their centre (seen with +-1e3).
COEFF_BOUND = np.inf
ANGLE_BOUND = np.inf


@dataclass
class EnergyProblem:
    X0: np.ndarray
    XT: np.ndarray
    c1: float = 1.0
    c2: float = 1e5
    m: int = 5
    divisions: int = PAPER_DIVISIONS
    arm: VerticalArm = field(default_factory=ohsaka_arm)
    theta0: np.ndarray | None = None
    fixed_T_s: float | None = None
    moving_joints: tuple[int, ...] | None = None   # None: all
    # (+1/-1, ...): keep theta_T,i - theta_0,i >= 0 / <= 0 (one rotation-direction pattern)
    travel_signs: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        check_weights(self.c1, self.c2)
        if not isinstance(self.m, (int, np.integer)) or self.m < 1:
            raise QmtInputError(f"number of Fourier terms m = {self.m} must be an integer >= 1")
        self.X0 = np.asarray(self.X0, dtype=float)
        self.XT = np.asarray(self.XT, dtype=float)
        check_reachable(self.arm, self.X0, "start point X(0)")
        check_reachable(self.arm, self.XT, "end point X(T)")
        if self.fixed_T_s is not None and not (T_MIN_S <= self.fixed_T_s <= T_MAX_S):
            raise QmtInputError(f"fixed motion time {self.fixed_T_s} s must lie in [{T_MIN_S}, {T_MAX_S}] s")
        if self.theta0 is None:
            self.theta0 = lowest_cog_posture(self.arm, self.X0)
        self.theta0 = np.asarray(self.theta0, dtype=float)
        if np.linalg.norm(tip_position(self.arm, self.theta0) - self.X0) > 1e-9:
            raise QmtInputError("theta0 does not reach X(0); leave it out to use the start-posture rule")
        self.family = FourierVelocityFamily(self.theta0, self.m)
        self.objective = EnergyObjective(self.family, self.arm, self.c1, self.c2, self.divisions)
        self.lower, self.upper = self._bounds()

    def with_travel_signs(self, signs) -> EnergyProblem:
        """The same problem restricted to one rotation-direction pattern."""
        return replace(self, travel_signs=None if signs is None else tuple(int(v) for v in signs))

    def with_divisions(self, divisions: int) -> EnergyObjective:
        return EnergyObjective(self.family, self.arm, self.c1, self.c2, divisions)

    def _bounds(self):
        F = self.family
        n, k = F.n, F.m - 1
        lo = np.concatenate([self.theta0 - ANGLE_BOUND, np.full(2 * n * k, -COEFF_BOUND), [T_MIN_S]])
        hi = np.concatenate([self.theta0 + ANGLE_BOUND, np.full(2 * n * k, COEFF_BOUND), [np.inf]])
        if self.fixed_T_s is not None:
            lo[-1] = hi[-1] = self.fixed_T_s
        if self.travel_signs is not None:
            for i, sg in enumerate(self.travel_signs):
                if sg > 0:
                    lo[i] = self.theta0[i]
                elif sg < 0:
                    hi[i] = self.theta0[i]
        if self.moving_joints is not None:
            for i in set(range(n)) - set(self.moving_joints):
                idx = [i] + [n + i * k + j for j in range(k)] + [n + n * k + i * k + j for j in range(k)]
                lo[idx] = hi[idx] = np.concatenate([[self.theta0[i]], np.zeros(2 * k)])
        return lo, hi

    # the end-point constraint on reduced genes (theta_T is y[:n])
    def endpoint_residual(self, y) -> np.ndarray:
        return tip_position(self.arm, np.asarray(y)[:self.family.n]) - self.XT

    def endpoint_residual_and_jacobian(self, y) -> tuple[np.ndarray, np.ndarray]:
        """(endpoint_residual, endpoint_jacobian) from one kinematics pass (the NLP's callback)."""
        n = self.family.n
        tip, Jq = self.arm.chain.tip_position_and_jacobian(np.asarray(y, dtype=float)[:n])
        J = np.zeros((2, self.family.n_reduced))
        J[:, :n] = Jq
        return tip - self.XT, J

    def endpoint_jacobian(self, y) -> np.ndarray:
        J = np.zeros((2, self.family.n_reduced))
        J[:, :self.family.n] = tip_jacobian(self.arm, np.asarray(y)[:self.family.n])
        return J

    def clip(self, y) -> np.ndarray:
        return np.clip(y, self.lower, self.upper)
