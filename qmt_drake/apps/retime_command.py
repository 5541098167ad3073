"""`qmt-drake retime SCENARIO --path FILE`: the fastest timing of a joint path made elsewhere (qmt_drake/retime.py).

    qmt-drake retime ur5-suction-bins --path moveit_path.yaml [--method toppra|ga] [--json plan.json]
        [--trajectory-csv t.csv] [--simulate] [--n-grid 1000] [--seed N --generations G] [--quiet]

Prints one line: the motion time, the re-check's largest ratio and its term, the time scale the
re-check applied, the hand's pose error at the path's ends against the scenario's first/last task
pose (information: the path is the task), its clearance from the obstacles (a colliding path is refused,
exit 2, unless --collisions report: then timed, reported COLLIDES, exit 3), and with --simulate the
co-simulation's verdict. --json writes the plan file (spatial_plan_io form; `qmt-drake export` reads
it). Exit 0 when the plan holds every limit and clears the obstacles, 3 when it does not. A planar
scenario (thesis arms, CRANE-X7 tray) takes --method toppra (qmt_drake/retime_planar.py: its LimitSet's toppra rows, the planar re-check, slowed to hold).
An energy-time scenario with joint torque limits (ohsaka-fig3) is retimed as its joint-space transfer
(energy/as_transfer.py), under those limits; `simulate SCENARIO --plan FILE` runs the file in seed 001's execution.
"""

from __future__ import annotations

import inspect
from dataclasses import replace

from qmt_drake.api_checks import OPTION_RANGES, number
from qmt_drake.apps.arg_checks import check_int, check_outputs, emit_json, progress
from qmt_drake.apps.spatial_cli import is_spatial_scenario
from qmt_drake.budgets import check_budget, spatial_ga_estimate
from qmt_drake.energy.as_transfer import transfer_scenario_of
from qmt_drake.energy.scenario import get_experiment, is_energy_scenario
from qmt_drake.errors import QmtInputError
from qmt_drake.hands import run_simulate
from qmt_drake.outcome import verdict_line
from qmt_drake.outputs import jsonable
from qmt_drake.planners.spatial_search import plan_ga_spatial
from qmt_drake.retime import METHODS, retime_path
from qmt_drake.retime_planar import retime_planar_path
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.transfer_scenario import load_scenario

EXIT_INFEASIBLE = 3


def add_parser(subparsers):
    s = subparsers.add_parser("retime", help="fastest timing of your own joint path (CSV or a ROS 2 JointTrajectory)",
                              description=__doc__.splitlines()[0])
    s.add_argument("scenario", help="a planar or spatial scenario (built-in name or YAML path)")
    s.add_argument("--path", required=True, metavar="FILE",
                   help=".csv (header of joint names, one waypoint a row, rad) or .yaml/.json JointTrajectory")
    s.add_argument("--method", choices=METHODS, default="toppra",
                   help="toppra: the time-optimal timing of the path itself; ga: the via cubic through its waypoints")
    s.add_argument("--n-grid", type=int, default=1000, help="toppra: grid points along the path")
    s.add_argument("--seed", type=int, default=None, help="ga: the generator's seed (default 0)")
    s.add_argument("--generations", type=int, default=None, help="ga: maximum generations")
    s.add_argument("--collisions", choices=("refuse", "report"), default="refuse",
                   help="spatial scenarios with world.obstacles: refuse a path that collides (default, exit 2) or "
                        "time it anyway and report it (the plan infeasible, exit 3)")
    s.add_argument("--json", metavar="PATH|-", help="write the plan file")
    s.add_argument("--trajectory-csv", metavar="PATH", help="t, q, qd, qdd at 1 kHz")
    s.add_argument("--simulate", action="store_true", help="then co-simulate it (carried or not)")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    s.add_argument("--quiet", action="store_true")
    s.set_defaults(func=cmd_retime)
    return s


def cmd_retime(args) -> int:
    check_outputs(args, "--json", "--trajectory-csv")
    lo, hi, fix = OPTION_RANGES["n_grid"]  # 10^9 points filled 23 GB before anything was said
    number(args.n_grid, "--n-grid", minimum=lo, maximum=hi, integer=True, fix=fix)
    energy = is_energy_scenario(args.scenario)
    if energy and args.simulate:
        raise QmtInputError(f"--simulate: retime {args.scenario} --json FILE, then `qmt-drake simulate {args.scenario} "
                            "--plan FILE` runs it in seed 001's execution (energy/execute.py)")
    if not energy and not is_spatial_scenario(args.scenario):
        return _retime_planar(args)
    ga = {k: getattr(args, k) for k in ("seed", "generations") if getattr(args, k) is not None}
    if args.method == "toppra" and ga:
        raise QmtInputError(f"--{sorted(ga)[0]}: an option of --method ga; drop it")
    check_int(ga.get("seed"), "--seed", 0, "seeds are non-negative integers")
    check_int(ga.get("generations"), "--generations", 1, "run at least one generation")
    if args.method == "ga":  # priced as `plan --method ga` is (its population: plan_ga_spatial's default)
        population = inspect.signature(plan_ga_spatial).parameters["population"].default
        est = spatial_ga_estimate(population, ga.get("generations", 150))
        check_budget(replace(est, what=f"--generations {ga.get('generations', 150)}: {est.what}",
                             fix="use fewer --generations"), allow_large=args.allow_large)
        ga["progress"] = None if args.quiet else progress
    # seed 001's arm: its joint-space transfer (energy/as_transfer.py: its joint torque limits; none: one line)
    sc = transfer_scenario_of(get_experiment(args.scenario)) if energy else load_spatial_scenario(args.scenario)
    p = retime_path(sc, args.path, args.method, n_grid=args.n_grid, collisions=args.collisions,
                    allow_large=args.allow_large, **ga)
    sim = simulate_spatial(sc, p.trajectory) if args.simulate else None
    if _write_outputs(args, p, sim):
        print(summary_line(sc, p, sim))
    # feasible: the re-check holds and the timed plan clears the obstacles (spatial_plan_io's clearance re-check)
    return 0 if p.recheck["max"] <= 1.0 and p.feasible else EXIT_INFEASIBLE


def _write_outputs(args, p, sim) -> bool:
    """The plan (and its co-simulation) to --json and --trajectory-csv; True when the summary line is
    still to print (--json - takes stdout)."""
    if args.json == "-":
        emit_json(jsonable({**p.to_json_dict(), "simulation": sim}), "-")
    elif args.json:
        p.write_json(args.json)
    if args.trajectory_csv:
        p.write_csv(args.trajectory_csv)
    return args.json != "-"


def _retime_planar(args) -> int:
    """retime on a planar scenario (retime_planar.py): TOPP-RA under its LimitSet, the planar re-check."""
    if args.collisions != "refuse":
        raise QmtInputError(f"--collisions {args.collisions}: a planar scenario has no obstacles to report; drop it")
    if args.method != "toppra" or args.seed is not None or args.generations is not None:
        raise QmtInputError(f"retime {args.scenario}: a planar scenario's path is retimed with --method toppra "
                            "(the GA retime searches the spatial via-cubic family); drop --method ga, --seed, "
                            "--generations")
    sc = load_scenario(args.scenario)
    p = retime_planar_path(sc, args.path, n_grid=args.n_grid)
    sim = run_simulate(sc, p) if args.simulate and p.feasible else None
    if _write_outputs(args, p, sim):
        c = p.check
        line = (f"{sc.name} retime toppra of {p.extra['path_waypoints']} waypoints: T = {p.motion_time_s:.4f} s "
                f"(slowed by {p.extra.get('slowdown_factor', 1.0):.4f} to hold), re-check max ratio "
                f"{c.worst_ratio:.5f} ({max(c.peak_ratios, key=c.peak_ratios.get) if c.peak_ratios else 'none'}) "
                f"at {c.rate_hz:g} Hz, {'feasible' if p.feasible else 'INFEASIBLE'}")
        if not p.feasible and p.extra.get("infeasible"):
            line += f" ({p.extra['infeasible']})"
        if sim is not None:
            line += f"; co-simulation: {verdict_line(sim['outcome'], sim.get('detached_at_s', sim.get('lost_at_s')))}"
        print(line)
    return 0 if p.feasible else EXIT_INFEASIBLE


def binding(recheck: dict) -> str:
    """The binding column a re-check dict names, else the name of its largest ratio (the spatial re-check's
    dict also holds strings and counts: only numbers below ratio names compete)."""
    if isinstance(recheck.get("binding"), str):
        return recheck["binding"]
    skip = ("max", "max_timed", "n_samples", "check_rate_hz", "binding_time_s", "refined_local_maxima")
    ratios = {k: v for k, v in recheck.items() if k not in skip and isinstance(v, (int, float))}
    return max(ratios, key=ratios.get)


def summary_line(sc, p, sim) -> str:
    e = p.info["end_pose_error"]
    line = (f"{sc.name} retime {p.method.removeprefix('retime_')} of {p.info['path_waypoints']} waypoints: "
            f"T = {p.duration_s:.4f} s (time scale applied {p.hold_scale:.4f}), re-check max ratio "
            f"{p.recheck['max']:.5f} ({binding(p.recheck)}) at {sc.recheck_rate_hz:g} Hz; hand at the path's "
            f"start/end {e[0, 0] * 1e3:.3g}/{e[1, 0] * 1e3:.3g} mm and {e[0, 1]:.2g}/{e[1, 1]:.2g} rad from the "
            f"first/last task pose (information); {p.planning_s:.2f} s")
    c = p.info.get("path_clearance")
    if c:  # the scenario has obstacles: the path's smallest clearance (--collisions refuse: a colliding path stopped)
        line += (f"; clearance >= {c['clearance_m']:.4f} m (no obstacle nearer)" if c["clearance_pair"] is None else
                 f"; clearance {c['clearance_m']:.4f} m ({' vs '.join(c['clearance_pair'])} {'' if c['at'].startswith('between') else 'at '}{c['at']}"
                 f"{'; COLLIDES' if c['clearance_m'] < 0 else ''})")
    t = p.clearance
    if t and t.get("clearance_pair") and t["clearance_m"] < 0 <= (c or {}).get("clearance_m", 0.0):
        line += f"; the timed plan COLLIDES ({t['clearance_m']:+.4f} m at {t['clearance_time_s']:.4f} s)"
    if sim is not None:
        line += f"; co-simulation: {verdict_line(sim['outcome'], sim['lost_at_s'])}"
    return line
