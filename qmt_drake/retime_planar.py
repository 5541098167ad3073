"""Retime a joint path made elsewhere under a planar scenario's limits (the thesis arms, the CRANE-X7 tray).

    plan = retime_planar_path(load_scenario("thesis-ch4"), "path.csv")   # or .yaml / .json / (K, n)

The path is read as for a spatial scenario (joint_path_files.read_joint_path: joints BY NAME, CSV or a ROS 2
JointTrajectory) and joined by the same C2 cubic in the joint-space chord length (zero slopes at the
ends: the arm starts and stops at rest; spatial_toppra.joint_path). Its fastest timing is the planar
TOPP-RA (planners/baselines/toppra_plan.toppra_segment): the scenario's LimitSet as toppra rows
(limits/toppra_form.py: the payload moment's inscribed polygon, the motor torques, the tray's
wrench rows), then the planar re-check (baselines/finish.finish_plan: every local maximum refined
between the 10 kHz samples) and, where it breaks a limit between TOPP-RA's grid points, the exact
slow-down that makes it hold. A path leaving a joint range or the arm's reach is not refused here:
the re-check's joint-range term reports it and the plan is infeasible (exit 3).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from qmt_drake.api_checks import OPTION_RANGES, number
from qmt_drake.errors import QmtInputError
from qmt_drake.joint_path_files import read_joint_path
from qmt_drake.planners.baselines.finish import finish_plan, infeasible_plan
from qmt_drake.planners.baselines.paths import GeometricPath
from qmt_drake.planners.baselines.toppra_plan import toppra_segment
from qmt_drake.planners.spatial_toppra import joint_path, path_grid

METHOD = "retime_toppra"
# a user path may be longer than anything the scenario's family makes: the motion-time budget of the
# re-check (10 kHz samples), not a limit of the arm
MAX_MOTION_TIME_S = 600.0


class SplinePath(GeometricPath):
    """A Drake PiecewisePolynomial q(s) as a GeometricPath (s: joint-space chord length, rad)."""

    unit = "rad (joint-space chord length through the waypoints)"

    def __init__(self, pp) -> None:
        self.pp, self.d1, self.d2 = pp, pp.derivative(1), pp.derivative(2)
        self.length = float(pp.end_time() - pp.start_time())
        self.n_dof = pp.rows()

    def derivatives(self, s):
        s = np.clip(np.asarray(s, float), 0.0, self.length)
        return tuple(p.vector_values(s).T for p in (self.pp, self.d1, self.d2))


def retime_planar_path(scenario, joint_path_or_file, *, n_grid: int = 1000):
    """The fastest timing of a given joint path on a planar scenario (module docstring): a Plan
    re-checked at the scenario's check rate (feasible False, the reason in extra['infeasible'], when
    TOPP-RA finds no timing or the path leaves a joint range)."""
    lo, hi, fix = OPTION_RANGES["n_grid"]  # the API's range: 10^9 points would fill the memory before any word
    n_grid = number(n_grid, "n_grid", minimum=lo, maximum=hi, integer=True, fix=fix)
    src = joint_path_or_file if isinstance(joint_path_or_file, (str, Path)) else None
    Q = read_joint_path(joint_path_or_file, scenario.arm.joint_names)
    if not np.all(np.isfinite(Q)):
        raise QmtInputError("joint path: a waypoint holds a value that is not a finite number (rad)")
    if len(Q) < 2:
        raise QmtInputError("joint path: give at least 2 waypoints (the start and the goal)")
    t0 = time.perf_counter()
    seg = SplinePath(joint_path(Q))
    extra = {"path": "user joint path", "path_source": None if src is None else str(src),
             "path_waypoints": len(Q), "path_q_rad": Q.tolist(), "path_length_rad": seg.length,
             "n_grid": n_grid, "path_unit": seg.unit}
    grid = path_grid(seg.pp, n_grid)  # a dense path's knots and short pieces on the grid, as spatial retime
    extra["grid_points"] = len(grid)
    traj, code, wall = toppra_segment(scenario, seg, grid_points=grid)
    extra["toppra_solve_wall_s"] = wall
    if traj is None:
        return infeasible_plan(scenario, METHOD, f"toppra found no parameterization of the path ({code}): a limit "
                               "breaks at rest somewhere on it", planner_wall_s=time.perf_counter() - t0, extra=extra)
    return finish_plan(scenario, METHOD, traj, planner_wall_s=time.perf_counter() - t0, extra=extra,
                       max_motion_time_s=MAX_MOTION_TIME_S)
