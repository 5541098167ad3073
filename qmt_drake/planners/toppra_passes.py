"""TOPP-RA's two passes over toppra's Seidel LP, without toppra's per-stage Python around them.

toppra.algorithm.TOPPRA.compute_parameterization (reachability_algorithm.py) computes the
controllable sets K_i backwards (two stage LPs per grid point: the largest and smallest sdot^2 from
which K_{i+1} is reachable) and then the greedy forward pass (one stage LP per grid point: the largest
sddot that keeps x_{i+1} in K_{i+1}). Of its 23 ms on a 1000-point path about 12 ms are the 3000
LPs of its Cython seidelWrapper; the rest is Python around each call (fresh arrays, NaN checks,
logging guards), and the TOPPRA constructor asks which solver packages are importable (2 ms).
`seidel_parameterization` makes the same LP calls with the same arguments in the same order and the
same safeguards (toppra's constants TINY, SMALL, MAX_TRIES; its retry that lowers x_i when a forward
LP is marginally infeasible), so its (sdd, sd) and return code equal toppra's bit for bit
(tests/test_spatial_toppra.py, and tests/test_one_toppra.py on every caller's problem). Called only by the
one TOPP-RA, planners/toppra_core.parameterise.
"""

from __future__ import annotations

import math

import numpy as np


def seidel_parameterization(constraints, path, gridpoints, sd_start: float = 0.0, sd_end: float = 0.0):
    """(sdd (N,), sd (N+1,), code) of the time-optimal parameterisation of `path` on `gridpoints` under
    toppra `constraints` (canonical linear only), or (None, None, code) when the path is not controllable,
    the start velocity sd_start is outside the controllable set or the forward pass fails; code is
    str() of toppra's ParameterizationReturnCode, as TOPPRA sets it. Called by planners/toppra_core.py."""
    # lazy: toppra loads matplotlib.pyplot, too slow for every CLI start
    from toppra.algorithm.algorithm import ParameterizationReturnCode as Code
    from toppra.constants import MAX_TRIES, SMALL, TINY
    from toppra.solverwrapper.cy_seidel_solverwrapper import seidelWrapper

    grid = np.array(gridpoints, dtype=float)
    if grid[0] != path.path_interval[0] or grid[-1] != path.path_interval[1] or np.any(np.diff(grid) <= 0):
        raise ValueError("gridpoints must increase from the path's start to its end")
    solver = seidelWrapper(list(constraints), path, grid, solve_lp1d=True)
    solve = solver.solve_stagewise_optim
    N = len(grid) - 1
    deltas = np.diff(grid).tolist()
    nan = math.nan
    # backward: K_i = [smallest, largest] sdot^2 at s_i from which K_{i+1} can be reached
    g_up, g_down = np.array([1e-9, -1.0]), np.array([-1e-9, 1.0])  # toppra's objectives (warm-start choice)
    K = np.zeros((N + 1, 2))
    K[N] = sd_end ** 2
    lo = hi = sd_end ** 2
    for i in range(N - 1, -1, -1):
        hi_i = solve(i, None, g_up, nan, nan, lo, hi)[1]
        lo_i = solve(i, None, g_down, nan, nan, lo, hi)[1]
        if math.isnan(lo_i) or math.isnan(hi_i):
            return None, None, str(Code.FailUncontrollable)
        lo, hi = max(lo_i, 0.0), hi_i
        K[i] = lo, hi
    x = sd_start ** 2
    if x + SMALL < K[0, 0] or K[0, 1] + SMALL < x:
        return None, None, str(Code.FailUncontrollable)
    # forward: the largest sddot at each stage that keeps sdot^2 controllable
    xs = np.empty(N + 1)
    us = np.empty(N)
    xs[0] = x
    Kl = K.tolist()
    g = np.array([0.0, -1.0])
    i = tries = 0
    while i < N:
        g[0] = -2.0 * deltas[i]
        lo, hi = Kl[i + 1]
        u = solve(i, None, g, x, x, lo, hi)[0]
        if math.isnan(u):  # marginally infeasible: lower x_i a little and try again (as toppra)
            if tries >= MAX_TRIES:
                return None, None, str(Code.ErrUnknown)
            x = max(x - TINY, 0.999 * x)
            xs[i] = x
            tries += 1
            continue
        tries = 0
        us[i] = u
        x_next = x + 2.0 * deltas[i] * u
        x_next = max(x_next - TINY, 0.9999 * x_next)
        x = min(hi, max(lo, x_next))
        xs[i + 1] = x
        i += 1
    sd = np.sqrt(xs)
    if np.isnan(sd).any():  # as toppra: a NaN speed is an unknown error
        return None, None, str(Code.ErrUnknown)
    return us, sd, str(Code.Ok)
