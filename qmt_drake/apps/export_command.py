"""`qmt-drake export PLAN.json --scenario SCENARIO`: a plan as a controller's stream, re-checked as interpolated.

    qmt-drake export plan.json --scenario ur5-suction-bins --format ros2|csv --rate 125 --out plan.yaml
        [--interp linear|cubic] [--hold] [--simulate] [--json report.json] [--allow-large]

Writes the stream (qmt_drake/export.py: samples at --rate, CSV of time_s and the joint names, or a
ROS 2 JointTrajectory YAML), re-checks it as the controller interpolates it (--interp, at 10x the
rate or the scenario's re-check rate if finer: joint speed, acceleration, torque, the hand's ratio)
and prints one line: the largest ratio and its term, whether the stream keeps the limits, the plan's
own largest ratio at the same rate, and the peak jerks. --simulate co-simulates the interpolated
stream as the reference; --hold first slows the plan until its stream keeps the limits. The plan file may be any spatial plan of the scenario (`plan --json`) or a
retimed path's (`retime --json`). Exit 0 when the stream keeps every limit, 3 when it does not (the
stream is written either way). Planar scenarios (the thesis arms, the CRANE-X7 tray) take it too: their own
limit set re-checks the stream, its local maxima refined between the samples.
"""

from __future__ import annotations

from qmt_drake.apps.arg_checks import check_outputs, emit_json
from qmt_drake.apps.retime_command import binding
from qmt_drake.apps.spatial_cli import is_spatial_scenario
from qmt_drake.energy.scenario import get_experiment, is_energy_scenario
from qmt_drake.energy.stream import EnergyStreamTarget
from qmt_drake.errors import QmtInputError
from qmt_drake.export import FORMATS, INTERPOLATIONS, check_stream_options, export_plan
from qmt_drake.hands import run_simulate
from qmt_drake.outcome import verdict_line
from qmt_drake.outputs import jsonable
from qmt_drake.plan import make_plan
from qmt_drake.plan_files import load_plan
from qmt_drake.retime import load_plan_file
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.transfer_scenario import load_scenario

EXIT_STREAM_BREAKS = 3


def add_parser(subparsers):
    s = subparsers.add_parser("export", help="write a plan as a controller's stream (ROS 2 or CSV) and re-check it",
                              description=__doc__.splitlines()[0])
    s.add_argument("plan", metavar="PLAN.json", help="a plan file (`plan --json` or `retime --json`)")
    s.add_argument("--scenario", required=True, help="the plan's scenario, planar or spatial (built-in name or YAML path)")
    s.add_argument("--format", required=True, help=f"{'|'.join(FORMATS)}")
    s.add_argument("--rate", required=True, type=float, metavar="HZ", help="the controller's rate (125, 500, 1000)")
    s.add_argument("--out", required=True, metavar="FILE", help="the stream file")
    s.add_argument("--interp", default="cubic", help=f"{'|'.join(INTERPOLATIONS)}: the controller's interpolation "
                   "between samples (cubic: Hermite through positions and velocities, as ROS 2's controller)")
    s.add_argument("--hold", action="store_true", help="first slow the plan until its interpolated stream keeps "
                   "every limit (bisection up to 3x; the scale is printed)")
    s.add_argument("--simulate", action="store_true", help="co-simulate the interpolated stream (carried or not)")
    s.add_argument("--json", metavar="PATH|-", help="write the report")
    s.add_argument("--allow-large", action="store_true", help="run even over the memory/time budget (budgets.py)")
    s.set_defaults(func=cmd_export)
    return s


def cmd_export(args) -> int:
    check_outputs(args, "--out", "--json")
    check_stream_options(args.format, args.rate, args.interp)
    spatial, energy = is_spatial_scenario(args.scenario), is_energy_scenario(args.scenario)
    if energy and args.simulate:
        raise QmtInputError("--simulate: the energy-time execution runs its plan's Fourier trajectory (its "
                            "inverse-dynamics controller needs the plan's qdd); drop --simulate, or run "
                            f"`qmt-drake simulate {args.scenario} --plan {args.plan}`")
    if spatial:
        sc = load_spatial_scenario(args.scenario)
        plan = load_plan_file(args.plan, sc)
    else:
        E = get_experiment(args.scenario) if energy else None
        sc = EnergyStreamTarget(E) if energy else load_scenario(args.scenario)
        plan = load_plan(args.plan, E) if energy else load_plan(args.plan, scenario=sc)
    rep = export_plan(sc, plan, args.format, args.rate, args.out, args.interp, hold=args.hold,
                      allow_large=args.allow_large)
    stream = rep.pop("stream")
    if args.simulate:  # the interpolated stream as the co-simulation's reference
        rep["simulation"] = (simulate_spatial(sc, stream) if spatial else
                             run_simulate(sc, make_plan(sc, f"{plan.method}_stream", stream)))
    emit_json(jsonable(rep), args.json)
    if args.json != "-":
        print(summary_line(rep))
    return 0 if rep["stream_holds"] else EXIT_STREAM_BREAKS


def summary_line(rep: dict) -> str:
    rc, own = rep["stream_recheck"], rep["plan_recheck_same_rate"]
    sj, pj = rep["stream_peak_jerk"], rep["plan_peak_jerk"]
    jerk = ((f"peak jerk {sj['peak_jerk_ratio']:.3g} x the limit at {sj['jerk_rate_hz']:g} Hz (the plan's "
             f"{pj['peak_jerk_ratio']:.3g} x at {pj['jerk_rate_hz']:g} Hz)") if sj["peak_jerk_ratio"] is not None else
            f"peak jerk {max(sj['peak_jerk_rad_s3']):.4g} rad/s^3 at {sj['jerk_rate_hz']:g} Hz (no jerk limit stated; "
            f"the plan's {max(pj['peak_jerk_rad_s3']):.4g} at {pj['jerk_rate_hz']:g} Hz)")
    line = (f"{rep['scenario']} {rep['method']} -> {rep['out']}: {rep['n_samples']} samples at {rep['rate_hz']:g} Hz "
            f"({rep['format']}); {rep['interp']} interpolation re-checked at {rc['check_rate_hz']:g} Hz: max ratio "
            f"{rc['max']:.4f} ({binding(rc)}), the stream {'keeps' if rc['max'] <= 1.0 else 'BREAKS'} the limits "
            f"(the plan itself {own['max']:.5f} at that rate); {jerk}")
    if "clearance_m" in rc:  # a scenario with obstacles: the interpolated stream's clearance from them
        a, b = rc["clearance_pair"]
        line += (f"; clearance {rc['clearance_m']:+.4f} m ({a} vs {b} at {rc['clearance_time_s']:.4f} s)"
                 + ("" if rc["clearance_m"] >= 0.0 else ": the stream COLLIDES"))
    if rep["hold_scale"] != 1.0:
        line += f"; played {rep['hold_scale']:.4f} x slower (--hold): T = {rep['plan_duration_s'] * rep['hold_scale']:.4f} s"
    sim = rep.get("simulation")
    if sim is not None:
        lost_at = sim.get("lost_at_s", sim.get("detached_at_s"))  # the planar magnet's summary names it so
        line += f"; co-simulation of the stream: {verdict_line(sim['outcome'], lost_at)}"
    return line
