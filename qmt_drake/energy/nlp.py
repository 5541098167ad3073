"""Seed 001's problem through Drake's MathematicalProgram: SNOPT (first) and IPOPT (second solver),
with exact gradients of the cost and the end-point constraint.

Decision variables: the reduced genes y (fourier.py), so (2) and (6) hold by construction; the
end point FK(theta_T) = X(T) is a nonlinear equality. Cost and constraint are Python callbacks
that receive AutoDiffXd vectors and return the value with the exact gradient (objective.py) mapped
onto the incoming derivative directions, so no Drake autodiff runs through the dynamics.

Iteration counts: Drake does not expose SNOPT's iteration counter (its print file stays empty
through Drake), so `evaluations` counts gradient evaluations of the cost (one per SNOPT function
call); IPOPT's own count is read from its output file (`iterations`).
"""

from __future__ import annotations

import os
import re
import tempfile
import time
from dataclasses import dataclass

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.solvers import IpoptSolver, MathematicalProgram, SnoptSolver, SolverOptions

from qmt_drake.energy.problem import EnergyProblem
from qmt_drake.errors import QmtInputError

SOLVERS = ("snopt", "ipopt")
# IPOPT from a cold start (measured in studies/ohsaka_1988.py, README "IPOPT"): a longer L-BFGS
# memory than the default 6 pairs is what helps; variable scaling by the Gauss-Newton curvature at
# the start (full or diagonal) made it diverge towards T -> 0 and was dropped.
IPOPT_COLD_OPTIONS = {"limited_memory_max_history": 50}


@dataclass
class NlpResult:
    y: np.ndarray
    x: np.ndarray
    z: float
    success: bool
    status: str
    evaluations: int
    wall_s: float
    solver: str
    cpu_s: float = 0.0   # process CPU time: the machine is shared, wall time includes waiting
    iterations: int | None = None   # IPOPT's own count (its output file); Drake gives none for SNOPT


def _ad_wrap(fun_val_grad):
    """A Drake callback: float arrays -> value, AutoDiffXd arrays -> value with chained gradient."""
    def f(v):
        if v.dtype != object:
            val, _ = fun_val_grad(np.asarray(v, dtype=float))
            return val
        x = ExtractValue(v).ravel()
        dx = ExtractGradient(v)
        val, g = fun_val_grad(x)
        if np.ndim(val) == 0:
            return AutoDiffXd(float(val), g @ dx)
        return InitializeAutoDiff(np.asarray(val).reshape(-1, 1), g @ dx).ravel()
    return f


def build_program(problem: EnergyProblem, counter: list):
    prog = MathematicalProgram()
    y = prog.NewContinuousVariables(problem.family.n_reduced, "y")
    obj = problem.objective
    # SNOPT/IPOPT work best near unit scale: divide z by c2 (z/c2 = T + (c1/c2) int tau'tau).
    scale = 1.0 / max(problem.c2, 1e-300)

    def cost(v):
        counter[0] += 1
        z, g = obj.reduced_value_and_gradient(v)
        return z * scale, g * scale

    prog.AddCost(_ad_wrap(cost), vars=y)
    prog.AddConstraint(_ad_wrap(problem.endpoint_residual_and_jacobian),
                       lb=np.zeros(2), ub=np.zeros(2), vars=y)
    prog.AddBoundingBoxConstraint(problem.lower, problem.upper, y)
    return prog, y


def solve_nlp(problem: EnergyProblem, y0, solver: str = "snopt", tol: float = 1e-8,
              max_iter: int = 3000, options: dict | None = None) -> NlpResult:
    """One local optimum from reduced genes y0. `options`: extra solver options (name -> value),
    e.g. IPOPT_COLD_OPTIONS."""
    if solver not in SOLVERS:
        raise QmtInputError(f"NLP solver '{solver}' is not one of {SOLVERS}")
    counter = [0]
    t0 = time.perf_counter()
    c0 = time.process_time()
    prog, y = build_program(problem, counter)
    opts = SolverOptions()
    if solver == "snopt":
        s = SnoptSolver()
        sid = s.solver_id()
        opts.SetOption(sid, "Major optimality tolerance", 1e-9)
        opts.SetOption(sid, "Major feasibility tolerance", 1e-12)
        opts.SetOption(sid, "Major iterations limit", int(max_iter))
    else:
        s = IpoptSolver()
        sid = s.solver_id()
        opts.SetOption(sid, "tol", tol)
        opts.SetOption(sid, "print_level", 0)
        # z/c2 is O(0.1): the default initial barrier mu = 0.1 would outweigh it
        opts.SetOption(sid, "mu_init", 1e-6)
        # Drake gives IPOPT no Hessian: L-BFGS. Its default first step (identity scaling) throws
        # the coefficients so far that tau overflows; a stiff initial curvature keeps it sane.
        opts.SetOption(sid, "limited_memory_initialization", "constant")
        opts.SetOption(sid, "limited_memory_init_val", 1e2)
        opts.SetOption(sid, "max_iter", int(max_iter))
        log = tempfile.NamedTemporaryFile(prefix="qmt_ipopt_", suffix=".out", delete=False)
        log.close()
        opts.SetOption(sid, "output_file", log.name)
        opts.SetOption(sid, "file_print_level", 3)
    for k, val in (options or {}).items():
        opts.SetOption(sid, k, val)
    if not s.available():
        raise QmtInputError(f"{solver} is not available in this Drake build; use --method steepest")
    result = s.Solve(prog, problem.clip(np.asarray(y0, dtype=float)), opts)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    yv = result.GetSolution(y)
    iterations = None
    if solver == "ipopt":
        try:
            with open(log.name, encoding="utf-8", errors="replace") as f:
                found = re.findall(r"Number of Iterations\.*:\s*(\d+)", f.read())
            iterations = int(found[-1]) if found else None
        finally:
            os.unlink(log.name)
    x, _ = problem.family.reduced_to_full(yv)
    z = problem.objective.value(x)
    return NlpResult(yv, x, z, bool(result.is_success()), str(result.get_solution_result()),
                     counter[0], wall, solver, cpu, iterations)
