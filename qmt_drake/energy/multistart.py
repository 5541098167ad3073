"""Multi-start over the 8 rotation-direction patterns of the three joints (seed 001, Fig. 3: "eight
end postures give eight local optima"; the paper labels them by the signs of joint travel, e.g.
(+,-,-)).

For a redundant 3-link arm, X(T) is reached by a one-parameter family of postures, and each
posture can be reached turning each joint either way (theta_T,i and theta_T,i -+ 2 pi). For the
sign pattern s the start is the posture on that family (1/4-degree samples, both elbow branches,
kinematics.self_motion_samples) whose joint travel with signs s has the smallest sum of |travel|,
each travel taken in (0, 2 pi) for + and (-2 pi, 0) for -; the initial trajectory is the
simplest member of eq. (5) for it (a_i1 only) with T = 1 s, as the paper starts Fig. 3/4.
Every start is solved; the result reports the pattern it started from AND the pattern of the
local optimum it ended in (a solver may cross over), and distinct optima are listed once.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from qmt_drake.energy.kinematics import self_motion_samples
from qmt_drake.energy.nlp import solve_nlp
from qmt_drake.energy.problem import EnergyProblem
from qmt_drake.energy.steepest import steepest_descent

PATTERNS = tuple(itertools.product((1, -1), repeat=3))


def pattern_str(p) -> str:
    return "(" + ",".join("+" if v > 0 else ("-" if v < 0 else "0") for v in p) + ")"


def travel_pattern(theta0, thetaT, tol: float = 1e-6) -> tuple[int, ...]:
    d = np.asarray(thetaT) - np.asarray(theta0)
    return tuple(int(np.sign(v)) if abs(v) > tol else 0 for v in d)


def signed_travel(theta0, postures, pattern) -> np.ndarray:
    """Travel (K, n) from theta0 to each posture, turning joint i in direction pattern[i]."""
    d = np.mod(np.asarray(postures) - np.asarray(theta0), 2 * np.pi)  # [0, 2pi)
    neg = np.asarray(pattern) < 0
    d = np.where(neg, d - 2 * np.pi, d)
    return d


def initial_end_posture(problem: EnergyProblem, pattern) -> np.ndarray:
    Q = self_motion_samples(problem.arm, problem.XT)
    d = signed_travel(problem.theta0, Q, pattern)
    # a joint that does not turn belongs to no pattern: leave such samples out
    cost = np.where(np.all(np.abs(d) > 1e-3, axis=1), np.sum(np.abs(d), axis=1), np.inf)
    k = int(np.argmin(cost))
    return problem.theta0 + d[k]


def initial_reduced_genes(problem: EnergyProblem, theta_T, T_s: float = 1.0) -> np.ndarray:
    x = problem.family.initial_genes(theta_T, T_s)
    return problem.family.full_to_reduced(x)


@dataclass
class LocalOptimum:
    start_pattern: tuple
    end_pattern: tuple
    y: np.ndarray
    x: np.ndarray
    z: float
    T_s: float
    energy: float          # integral tau'tau dt on the same grid
    success: bool
    wall_s: float
    evaluations: int
    method: str
    iterations: int | None = None
    cpu_s: float | None = None


def run_multistart(problem: EnergyProblem, method: str = "snopt", T0_s: float = 1.0,
                   restrict: bool = False, **kw) -> list[LocalOptimum]:
    """Solve from each of the 8 pattern starts with `method` (snopt | ipopt | steepest).
    restrict=True keeps each solve inside its pattern (bounds on theta_T - theta_0): the best
    trajectory of each rotation-direction pattern, which may lie on the pattern's boundary."""
    base = problem
    out = []
    for p in PATTERNS:
        problem = base.with_travel_signs(p) if restrict else base
        thT = initial_end_posture(problem, p)
        y0 = initial_reduced_genes(problem, thT, T0_s)
        if method == "steepest":
            r = steepest_descent(problem, problem.family.reduced_to_full(y0)[0], **kw)
            y, x, z, ok, wall, ev, it = (problem.family.full_to_reduced(r.x), r.x, r.z, r.converged,
                                         r.wall_s, r.evaluations, r.iterations)
            cpu = None
        else:
            r = solve_nlp(problem, y0, method, **kw)
            y, x, z, ok, wall, ev, it = r.y, r.x, r.z, r.success, r.wall_s, r.evaluations, r.iterations
            cpu = r.cpu_s
        out.append(LocalOptimum(p, travel_pattern(problem.theta0, problem.family.end_posture(x)),
                                y, x, z, float(x[-1]), problem.objective.energy_integral(x), ok,
                                wall, ev, method, it, cpu))
    return out


def distinct_optima(results: list[LocalOptimum], rel_tol: float = 1e-6) -> list[LocalOptimum]:
    """One entry per distinct local optimum (same z within rel_tol and same end posture mod 2pi
    and same travel pattern), sorted by z."""
    keep: list[LocalOptimum] = []
    for r in sorted([r for r in results if r.success], key=lambda r: r.z):
        dup = False
        for k in keep:
            if abs(k.z - r.z) <= rel_tol * k.z and k.end_pattern == r.end_pattern:
                dup = True
                break
        if not dup:
            keep.append(r)
    return keep
