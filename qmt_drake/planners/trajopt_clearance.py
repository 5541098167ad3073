"""trajopt in a cell: the spatial trajopt's program with the clearance as a constraint (docs/obstacles.md,
"trajopt that keeps the clearance").

The spatial trajopt (planners/spatial_methods.plan_trajopt_spatial) passes its path points at fixed path
fractions and is free in between; on a collision-free path (planners/collision_free.py, `plan --avoid`) of a
few vertices it wandered 63 mm into a tote's wall between them. `keep_clear` runs after the program as it
was (`first`, a trajopt_core.TrajoptResult):

1. `bound_m` = min(clearance_m, the path points' own clearance): a path point closer than the margin (the
   part 1 cm above a tote's floor at a pick pose is not) lowers the bound to it; a path point that
   collides leaves nothing to keep (the task itself collides: the plain result, re-checked infeasible).
2. The plain result is kept, unchanged, when it is a trajectory of its program (trajopt_core.TrajoptResult.usable:
   solved, or SNOPT stopped unsolved on a point meeting every constraint, e.g. its exit 41 on the deep totes'
   ends-only path) and its clearance certified between samples (limits/clearance.certified_clearance at the
   check rate) is at least bound_m / 2 (the collision-free path's own acceptance, planners/collision_free.smooth):
   no program changes where none is needed.
3. Else the program again with Drake's MinimumDistanceLowerBoundConstraint (the arm's and the carried
   part's shapes against the obstacles, the clearance model's plant, limits/clearance.CollisionModel) >=
   bound_m at SAMPLES uniform path fractions, seeded by the scenario's own geometric path (the C2 cubic in
   chord length through q_path_rad that TOPP-RA times, spatial_toppra.joint_path: with --avoid the
   certified collision-free path), its control points fitted to that path by least squares; the face
   normal kept within max_tilt_rad of THAT path's normal (Drake's forward kinematics at each tilt
   sample; the plain program's slerp between the path points is not a normal the clear path has: the
   collision-free path's straight joint edges tilt the hand up to 0.13 rad from it, and the two
   constraints together left SNOPT no feasible point). SNOPT stops at MAJOR_ITERATIONS and MINOR_ITERATIONS
   (a deterministic bound on the time); a point that meets every constraint (trajopt_core.INFEASIBLE_TOL) is accepted
   then, reported as not proven minimal. A point that does not is described by `breaks` (the refusal's reason).
4. Certified again; where the lower bound is below bound_m / 2, constraint samples are added around the
   smallest (REFINE_POINTS at spacing 1 / (4 SAMPLES)) and the program solved again from the last point,
   up to REFINE_ROUNDS times. The result is what the plan's re-check (limits, clearance) then judges.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.inverse_kinematics import (
    AngleBetweenVectorsConstraint,
    MinimumDistanceLowerBoundConstraint,
)
from pydrake.trajectories import BsplineTrajectory

from qmt_drake.limits.clearance import certified_clearance, collision_model
from qmt_drake.limits.spatial_columns import joint_range_by_name
from qmt_drake.planners import trajopt_core
from qmt_drake.planners.spatial_toppra import joint_path
from qmt_drake.planners.spatial_trajectory import PolyTrajectory

SAMPLES = 80  # MinimumDistanceLowerBoundConstraint's uniform path fractions
REFINE_ROUNDS = 2
REFINE_POINTS = 5  # fractions added around a certified minimum below bound / 2, 1 / (4 SAMPLES) apart
MAJOR_ITERATIONS = 150  # SNOPT's major iterations, and its minor (QP) iterations in all: a deterministic bound
MINOR_ITERATIONS = 20000  # on the time (a stalled solve took 530 s without the second)
FEASIBILITY_TOL = 1e-8  # SNOPT's major feasibility tolerance (the plain program's 1e-10 stalls on distances)
INFLUENCE_M = 0.01  # pairs within bound + this enter the constraint (Drake's default)
FIT_POINTS = 400  # the seed's least-squares fit of the control points to the path


def _chord_at(fractions, Q) -> tuple:
    """(x -> chord length (rad) of the joint path through Q at trajopt fraction x, the path): the path
    points' fractions map to their chord lengths, linearly in between."""
    c = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))]
    return (lambda x: np.interp(x, fractions, c)), c[-1]


def _basis_matrix(basis, xs) -> np.ndarray:
    m = basis.num_basis_functions()
    b = BsplineTrajectory(basis, [np.eye(m)[:, [i]] for i in range(m)])
    return np.stack([b.value(float(x))[:, 0] for x in xs])


def clear_problem(sc, p: trajopt_core.TrajoptProblem, bound_m: float, max_tilt_rad: float | None, tilt_samples: int,
                  samples, start=None) -> trajopt_core.TrajoptProblem:
    """The program p with the clearance at `samples` (module docstring, step 3); start: (control points
    (ncp, n), duration s) of a previous solve to start from, else the fit to the geometric path."""
    pp = joint_path(p.path_rad, *joint_range_by_name(sc.plant, sc.joint_names))
    chord, _ = _chord_at(p.fractions, p.path_rad)

    def q_at(x):
        return pp.value(float(chord(x)))[:, 0]

    tilt = []
    if max_tilt_rad is not None:
        ctx = sc.plant.CreateDefaultContext()
        tilt = [(AngleBetweenVectorsConstraint(sc.plant, sc.plant.world_frame(), sc.ik.pose(q_at(x))[1] @ sc.ik.face_axis,
                                               sc.ik.hand, sc.ik.face_axis, 0.0, max_tilt_rad, ctx), x)
                for x in np.linspace(0.0, 1.0, tilt_samples)]
    cm = collision_model(sc)
    clear = MinimumDistanceLowerBoundConstraint(cm.plant, bound_m, cm.plant_context, None, INFLUENCE_M)
    if start is None:
        def guess(basis):
            xs = np.linspace(0.0, 1.0, FIT_POINTS)
            return np.linalg.lstsq(_basis_matrix(basis, xs), np.stack([q_at(x) for x in xs]), rcond=None)[0]
        duration = p.initial_duration_s
    else:
        guess, duration = start
    opts = {**p.snopt_options, "Major feasibility tolerance": FEASIBILITY_TOL, "Major iterations limit": MAJOR_ITERATIONS,
            "Iterations limit": MINOR_ITERATIONS}
    return trajopt_core.TrajoptProblem(
        p.path_rad, p.fractions, p.lower_rad, p.upper_rad, p.control_points, p.duration_bounds_s, guess,
        initial_duration_s=duration, rest_derivatives=p.rest_derivatives, velocity_limit=p.velocity_limit,
        acceleration_limit=p.acceleration_limit, jerk_limit=p.jerk_limit,
        path_constraints=tilt + [(clear, float(x)) for x in samples], snopt_options=opts)


def breaks(res, p: trajopt_core.TrajoptProblem, max_tilt_rad: float | None) -> str:
    """What the point of an unusable solve breaks, in words (a refusal's reason): the path points it misses
    (equality rows equal to a row of p.path_rad), the face tilt beyond max_tilt_rad (rows [cos max_tilt, 1]),
    the clearance (MinimumDistanceLowerBoundConstraint's rows [-inf, 1]), any other constraint by its name."""
    missed, tilt, near, other = {}, [], 0, {}
    cos_tilt = None if max_tilt_rad is None else float(np.cos(max_tilt_rad))
    for name, lo, hi, v in res.broken_rows or []:
        k = [i for i, q in enumerate(p.path_rad) if lo.shape == q.shape and np.array_equal(lo, q) and np.array_equal(hi, q)]
        if k:
            missed[k[0]] = float(np.abs(v - lo).max())
        elif lo.size == 1 and hi[0] == 1.0 and cos_tilt is not None and np.isclose(lo[0], cos_tilt):
            tilt.append(float(np.arccos(np.clip(v[0], -1.0, 1.0))))
        elif lo.size == 1 and lo[0] == -np.inf and hi[0] == 1.0:
            near += 1
        else:
            key = name.split(" at s=")[0]
            other[key] = other.get(key, 0) + 1
    out = [f"misses path point {k} (fraction {p.fractions[k]:.3f}) by {d:.2g} rad" for k, d in sorted(missed.items())]
    if tilt:
        out.append(f"tilts the face {max(tilt):.4f} rad (bound {max_tilt_rad:g}) at {len(tilt)} samples")
    if near:
        out.append(f"comes within the clearance bound at {near} samples")
    out += [f"breaks {key} ({m} rows)" for key, m in other.items()]
    return ", ".join(out) or "breaks no constraint by more than its tolerance"


def _certify(sc, res) -> dict:
    return certified_clearance(sc, PolyTrajectory(res.trajectory), sc.check_rate_hz)


def keep_clear(sc, p: trajopt_core.TrajoptProblem, first, clearance_m: float, max_tilt_rad: float | None,
               tilt_samples: int) -> tuple:
    """(result, facts): the plain result `first` of program p kept or replaced (module docstring)."""
    cm = collision_model(sc)
    d_points = np.array([cm.distance(q)[0] for q in p.path_rad])
    bound = float(min(clearance_m, d_points.min()))
    facts = {"clearance_m": clearance_m, "bound_m": bound, "path_points_clearance_m": float(d_points.min())}
    if bound <= 0.0:
        return first, {**facts, "used": False, "why": f"path point {int(np.argmin(d_points))} itself collides"}
    if first.usable:
        cert = _certify(sc, first)
        facts["plain_certified_lower_bound_m"] = cert["clearance_lower_bound_m"]
        if cert["clearance_lower_bound_m"] >= 0.5 * bound:
            return first, {**facts, "used": False, "why": "the plain program clears by half the bound"}
    samples = list(np.linspace(0.0, 1.0, SAMPLES))
    res, best, rounds, start = None, None, [], None
    for _ in range(REFINE_ROUNDS + 1):
        res = trajopt_core.solve(clear_problem(sc, p, bound, max_tilt_rad, tilt_samples, samples, start))
        row = {"samples": len(samples), "result": res.solution_result, "info": res.info,
               "duration_s": res.duration_s, "solve_wall_s": res.solve_wall_s}
        rounds.append(row)
        if not res.usable:
            row["infeasible_constraints"] = sorted(set(res.infeasible_constraints or []))
            row["breaks"] = breaks(res, p, max_tilt_rad)
            break
        cert = _certify(sc, res)
        row["certified_lower_bound_m"] = cert["clearance_lower_bound_m"]
        best = (res, cert)
        if cert["clearance_lower_bound_m"] >= 0.5 * bound:
            break
        x = cert["clearance_time_s"] / res.duration_s
        samples = sorted(set(samples) | {float(np.clip(x + k / (4 * SAMPLES), 0.0, 1.0))
                                         for k in range(-(REFINE_POINTS // 2), REFINE_POINTS // 2 + 1)})
        start = (np.hstack(res.trajectory.control_points()).T, res.duration_s)
    facts.update(rounds=rounds, samples=SAMPLES)
    if best is None:  # no clear trajectory: the plain one stands (the re-check says it collides)
        return first, {**facts, "used": False, "why": "SNOPT found no trajectory with the clearance"}
    res, cert = best
    return res, {**facts, "used": True, "proven_optimal": bool(res.success),
                 "certified_clearance_m": cert["clearance_m"],
                 "certified_lower_bound_m": cert["clearance_lower_bound_m"]}
