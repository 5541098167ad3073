"""What our co-simulation costs over the least any Drake diagram of the same physics can cost,
and what a sweep gains from a second worker (issue 13 item 5; the spatial part: issue 27 "Cost").

0. The spatial co-simulation (sim/spatial_cosim.simulate_spatial of each --spatial scenario's TOPP-RA
   plan, ideal actuators) against its floor of Drake primitives: studies/bench_spatial_floor.py,
   `--spatial-repeats` alternating repeats (0: skip).

1. Cost ratio, in one process and one run: the chapter-4 thesis move (1.716 s + 0.2 s lead +
   0.5 s settle) through
     ours  = sim.build_transfer_diagram as simulate_transfer builds it (the payload on its joint to
             the hand; the PD law, the motors and the damping add-back as one compiled law; the
             electromagnet, the applied signals and slip / tilt / gap as Drake primitives; implicit
             loop damping; one per-step C++ logger, the monitor's summary computed from it after the
             run, its cost included; no 5 ms series), run by sim.run_diagram (its seated check,
             per-chunk checks and summary included);
     ours, simulation only = the same diagram advanced by the floor's loop (no checks, no summary);
     ours, per-step monitor = the Python TransferMonitor and the Python PID called every step
             (after all the others, repeats // 3 times: see cost_ratio);
     floor = Drake primitives only, around the SAME plant (sim.add_transfer_plant: arm URDF +
             payload on its joint, eight contact spheres, kLagged contact, the same joint damping D
             stepped implicitly, the same 2 ms step): TrajectorySource -> two MatrixGains + Adder
             (the PD with its damping in the plant: no continuous state) -> actuation, and a
             ConstantVectorSource holding the magnet's pull at zero gap on the joint (the part stays
             seated, so the pull is that constant: what is dropped is its fade with gap and slide,
             the motors' nonlinearity, the logging and the summary);
     floor, previous plant = the same with the payload floating in the world frame (the plant of
             session 5; its pull as spatial forces), for the record;
     floor + our magnet = the floor with our electromagnet in place of the constant pull.
   Every diagram is built afresh for each repeat (as a sweep case is) and all are simulated
   `--repeats` times alternately, their order rotating from repeat to repeat; each run's wall and CPU time is kept; ratio = median(ours) /
   median(floor). Target <= 1.3. os.getloadavg() is recorded before and after (the machine is
   shared: only ratios measured side by side mean anything).
2. Sweep throughput: the same 2 x `--sweep-cases` real ch.4 cases (thesis and GA-free family
   optimum plans are not needed: the thesis genes, friction drawn) on a LocalCluster of 1 and of 2
   workers, each into a fresh store; cases per minute of the case phase (cluster start and
   planning excluded). Target: 2 workers / 1 worker >= 1.8 on this 2-core machine, which is
   shared: os.getloadavg() before each run is recorded.

Writes OUT/bench_cosim_floor.json atomically (OUT ending in .json: that file). Run:
  .venv/bin/python -m studies.bench_cosim_floor [--repeats 10] [--sweep-cases 120] [--spatial-repeats 5]
The study imports qmt_drake from sys.path, so the same study measures another checkout's package:
  cd DIR_WITH_ONLY_A_studies_LINK && PYTHONPATH=/other/checkout python -m studies.bench_cosim_floor ...
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import gc  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

from qmt_drake.outputs import jsonable, write_text_atomic  # noqa: E402
from studies.bench_spatial_floor import print_rows, spatial_cost  # noqa: E402

# the magnet's TOPP-RA plan detaches at 0.014 s (a free part is cheaper than the floor's weld): x1.3633,
# the slow-down that carries it (docs/spatial.md), is the like-for-like row
SPATIAL_SCENARIOS = ("ur5-suction-bins", "ur5-magnet-part@1.3633", "ur5-magnet-part", "panda-tray-cup")

THESIS_GENES_CH4 = (0.622, 0.532, 0.562)  # seed 000 Table 4.3 (the scenario's reported genes)


def build_floor(sc, plan, time_step_s: float, *, our_magnet: bool = False, our_monitor: bool = False,
                free_payload: bool = False):
    """The floor diagram (module docstring); returns (diagram, plant, handles) ready to simulate.
    our_magnet / our_monitor put back our electromagnet_force (fed the calibrated current) / our
    TransferMonitor (motor inputs zero) to attribute the cost ratio. free_payload: the previous
    plant, the payload floating in the world frame (its constant pull as spatial forces)."""
    from pydrake.common.value import AbstractValue
    from pydrake.multibody.math import SpatialForce
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import AddMultibodyPlant, ExternallyAppliedSpatialForce
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import (
        Adder,
        ConstantValueSource,
        ConstantVectorSource,
        MatrixGain,
        TrajectorySource,
    )

    from qmt_drake.sim import (
        add_magnet_hand,
        add_transfer_plant,
        coil_current_for,
        finalize_transfer_plant,
        magnet_params_for,
        motor_params_for,
        move_loop_damping_into_plant,
        pid_gains_for,
        plan_start,
        reference_trajectories,
        set_initial_state,
        transfer_plant_config,
    )
    from qmt_drake.systems.joint_tracking import effective_joint_gains
    from qmt_drake.systems.payload import PayloadSpec, add_payload, payload_joint

    b = DiagramBuilder()
    K, D = effective_joint_gains(pid_gains_for(sc), motor_params_for(sc))
    q0 = plan_start(plan)
    if free_payload:
        plant, _ = AddMultibodyPlant(transfer_plant_config(time_step_s), b)
        arm = Parser(plant).AddModels(str(sc.urdf_path))[0]
        hand = plant.GetBodyByName(sc.hand_frame, arm)
        spec = PayloadSpec.for_scenario(sc)
        payload = add_payload(plant, spec, hand, attach_to_hand=False)
        move_loop_damping_into_plant(plant, arm, D)
        plant.Finalize()
    else:  # the transfer plant itself, as build_transfer_diagram makes it
        tp = add_transfer_plant(b, sc, time_step_s)
        plant, arm, hand, payload, spec = tp.plant, tp.arm_instance, tp.hand_body, tp.payload_body, tp.payload_spec
        move_loop_damping_into_plant(plant, arm, D)
        finalize_transfer_plant(tp, q0)
    n = len(K)
    pp_q, _, t_end = reference_trajectories(plan)
    # The joint PD with its damping in the plant (stepped implicitly), as stateless gains: actuation
    # = K (q_des - q) + D qd_des; the plant's joint damping supplies -D qd.
    ref = b.AddSystem(TrajectorySource(pp_q, output_derivative_order=1))
    from_desired = b.AddSystem(MatrixGain(np.hstack([np.diag(K), np.diag(D)])))
    from_state = b.AddSystem(MatrixGain(np.hstack([-np.diag(K), np.zeros((n, n))])))
    act = b.AddSystem(Adder(2, n))
    state = plant.get_state_output_port(arm)
    b.Connect(ref.get_output_port(), from_desired.get_input_port())
    b.Connect(state, from_state.get_input_port())
    b.Connect(from_desired.get_output_port(), act.get_input_port(0))
    b.Connect(from_state.get_output_port(), act.get_input_port(1))
    b.Connect(act.get_output_port(), plant.get_actuation_input_port(arm))

    # The magnet's pull at zero gap and full overlap along the hand's face normal: on the relative
    # plant one generalized-force entry of the payload's joint (the hand's reaction is the joint's);
    # on the free plant a spatial force on the payload and its reaction on the hand, whose face
    # normal a planar arm turning about vertical joints never tilts.
    current = coil_current_for(sc, spec)
    f0 = magnet_params_for(sc, spec).force_N(current)
    if our_magnet:
        add_magnet_hand(b, plant, hand, payload, sc, spec, current)
    elif free_payload:
        ctx = plant.CreateDefaultContext()
        plant.SetPositions(ctx, arm, q0)
        z = plant.EvalBodyPoseInWorld(ctx, hand).rotation().col(2)
        if abs(abs(z[2]) - 1.0) > 1e-9:
            raise RuntimeError("floor: the hand's face normal is not vertical; a constant pull would be wrong")
        on_p, on_h = ExternallyAppliedSpatialForce(), ExternallyAppliedSpatialForce()
        on_p.body_index, on_p.p_BoBq_B, on_p.F_Bq_W = payload.index(), np.zeros(3), SpatialForce(np.zeros(3), f0 * z)
        on_h.body_index, on_h.p_BoBq_B, on_h.F_Bq_W = hand.index(), np.zeros(3), SpatialForce(np.zeros(3), -f0 * z)
        pull = b.AddSystem(ConstantValueSource(AbstractValue.Make([on_p, on_h])))
        b.Connect(pull.get_output_port(), plant.get_applied_spatial_force_input_port())
    else:
        tau = np.zeros(plant.num_velocities())
        tau[payload_joint(plant, payload).velocity_start() + 5] = f0
        pull = b.AddSystem(ConstantVectorSource(tau))
        b.Connect(pull.get_output_port(), plant.get_applied_generalized_force_input_port())
    if our_monitor:
        from qmt_drake.systems.transfer_monitor import TransferMonitor
        mon = b.AddSystem(TransferMonitor(n, hand.index(), payload.index(), period_s=time_step_s))
        zeros = b.AddSystem(ConstantVectorSource(np.zeros(n)))
        b.Connect(plant.get_body_poses_output_port(), mon.GetInputPort("body_poses"))
        b.Connect(state, mon.GetInputPort("arm_state"))
        b.Connect(ref.get_output_port(), mon.GetInputPort("desired_state"))
        b.Connect(zeros.get_output_port(), mon.GetInputPort("motor_torque"))
        b.Connect(zeros.get_output_port(), mon.GetInputPort("electrical_power"))
    diagram = b.Build()

    def init(root_ctx):
        pc = plant.GetMyMutableContextFromRoot(root_ctx)
        if free_payload:
            plant.SetPositions(pc, arm, q0)
            plant.SetFreeBodyPose(pc, payload, plant.EvalBodyPoseInWorld(pc, hand))
        else:
            set_initial_state(plant, pc, arm, hand, payload, q0)
    return diagram, plant, dict(init=init, t_final=t_end + 0.5, arm=arm, hand=hand, payload=payload,
                                pull_N=f0, coil_current_A=current)


def run_floor(diagram, plant, h, chunk_s: float = 0.25):
    """Simulate the floor to its end in the same 250 ms chunks as sim.run_diagram; returns
    (wall s, cpu s, final payload offset from the face centre [m])."""
    from pydrake.systems.analysis import Simulator
    gc.collect(1)  # as run_diagram does before a run: earlier diagrams' reference cycles freed
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    h["init"](ctx)
    sim.Initialize()
    gc_on = gc.isenabled()
    gc.disable()
    w0, c0 = time.perf_counter(), time.process_time()
    try:
        t = 0.0
        while t < h["t_final"] - 1e-12:
            t = min(t + chunk_s, h["t_final"])
            sim.AdvanceTo(t)
    finally:
        if gc_on:
            gc.enable()
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    pc = plant.GetMyContextFromRoot(ctx)
    X_HP = plant.EvalBodyPoseInWorld(pc, h["hand"]).InvertAndCompose(plant.EvalBodyPoseInWorld(pc, h["payload"]))
    return wall, cpu, float(np.linalg.norm(X_HP.translation()))


def cost_ratio(repeats: int, time_step_s: float) -> dict:
    from qmt_drake.sim import GenesPlan, build_transfer_diagram, make_result, run_diagram
    from qmt_drake.transfer_scenario import load_scenario
    sc = load_scenario("thesis-ch4")
    plan = GenesPlan(sc, THESIS_GENES_CH4, method="thesis")
    keys = ("ours", "ours_simulation_only", "ours_per_step_monitor", "floor", "floor_previous_plant",
            "floor_our_magnet")
    runs = {k: {"wall": [], "cpu": []} for k in keys}
    held, offsets, posthoc_s, summaries = [], [], [], {}
    load_before = os.getloadavg()

    def record(key, wall, cpu):
        runs[key]["wall"].append(wall)
        runs[key]["cpu"].append(cpu)

    def ours(step_logs: bool, key: str):
        td = build_transfer_diagram(sc, plan, time_step_s=time_step_s, log_period_s=0, step_logs=step_logs,
                                    primitive_controller=step_logs)
        c0 = time.process_time()
        summary, wall = run_diagram(td)
        record(key, wall, time.process_time() - c0)
        summaries[key] = summary
        return td, summary, wall

    def floor(key: str, **kw):
        d, p, hh = build_floor(sc, plan, time_step_s, **kw)
        w, c, off = run_floor(d, p, hh)
        record(key, w, c)
        return hh, off

    def run_ours():
        td, summary, wall = ours(True, "ours")
        held.append(make_result(sc, plan, td, summary, wall, 1.0, {}).held)
        t0 = time.perf_counter()
        td.summary(td.simulator.get_context())  # what computing the summary from the logs costs
        posthoc_s.append(time.perf_counter() - t0)

    def run_floor_row():
        offsets.append(floor("floor")[1])

    def run_ours_simulation_only():
        td = build_transfer_diagram(sc, plan, time_step_s=time_step_s, log_period_s=0, step_logs=True)
        w, c, _ = run_floor(td.diagram, td.plant, dict(init=lambda ctx: None, t_final=td.t_final_s,
                                                       hand=td.hand_body, payload=td.payload_body))
        record("ours_simulation_only", w, c)

    # The order rotates from repeat to repeat: a run's cost depends a little on what ran before it
    # in the process, so every configuration takes every position equally often when repeats is a
    # multiple of their number. (Before run_diagram collected the young garbage generations before
    # each run, every configuration slowed by 30-50% over this loop: uncollected diagrams.) The
    # per-step Python monitor runs after them all: its diagrams hold Python systems, which pydrake
    # never frees (README), and the memory they pin slowed every later run of the process by up to
    # 50% when it ran among them.
    rows = [run_ours, run_floor_row, run_ours_simulation_only, lambda: floor("floor_previous_plant", free_payload=True),
            lambda: floor("floor_our_magnet", our_magnet=True)]
    for r in range(repeats):
        for row in rows[r % len(rows):] + rows[:r % len(rows)]:
            row()
    for _ in range(max(1, repeats // 3)):
        ours(False, "ours_per_step_monitor")
    h = build_floor(sc, plan, time_step_s)[2]
    steps = h["t_final"] / time_step_s
    med = lambda x: float(np.median(x))  # noqa: E731
    fw, fc = med(runs["floor"]["wall"]), med(runs["floor"]["cpu"])
    a, b = summaries["ours"], summaries["ours_per_step_monitor"]
    return dict(scenario="thesis-ch4", plan="thesis genes 0.622/0.532/0.562 s", time_step_s=time_step_s,
                sim_time_s=h["t_final"], repeats=repeats, loadavg_before=load_before, loadavg_after=os.getloadavg(),
                runs=runs,
                ratio_wall_median=med(runs["ours"]["wall"]) / fw,
                ratio_wall_best=min(runs["ours"]["wall"]) / min(runs["floor"]["wall"]),
                ratio_cpu_median=med(runs["ours"]["cpu"]) / fc,
                **{f"ratio_{k}_wall_median": med(runs[k]["wall"]) / fw for k in keys[1:] if k != "floor"},
                **{f"{k}_us_per_step_median": med(runs[k]["wall"]) / steps * 1e6 for k in keys},
                posthoc_summary_s_median=med(posthoc_s),
                ours_real_time_factor_median=h["t_final"] / med(runs["ours"]["wall"]),
                floor_real_time_factor_median=h["t_final"] / fw,
                ours_held=all(held),
                logs_summary_vs_per_step_monitor_max_rel_diff=float(np.nanmax(np.abs(a - b) / np.abs(b))),
                floor_final_offset_m=max(offsets), floor_pull_N=h["pull_N"], target_ratio=1.3)


def throughput(cases: int, workers_list=(1, 2)) -> dict:
    from qmt_drake.sweep.runner import run_sweep
    spec = {"name": "throughput", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
            "monte_carlo": {"cases": cases, "seed": 7},
            "parameters": {"friction": {"dist": "uniform", "low": 0.25, "high": 0.35}}}
    rows = []
    for w in workers_list:
        with tempfile.TemporaryDirectory(prefix="qmt_tp_") as d:
            load = os.getloadavg()
            o = run_sweep(spec, d, workers=w, progress=False, figures=False)
        rows.append(dict(workers=w, cases=o["computed"], failed=o["failed"], case_phase_wall_s=o["case_phase_wall_s"],
                         cases_per_min=o["cases_per_min"], loadavg_before=load))
        print(f"throughput: {w} worker(s): {o['cases_per_min']:.1f} cases/min "
              f"({o['computed']} cases in {o['case_phase_wall_s']:.1f} s; load {load[0]:.2f})", flush=True)
    base = rows[0]["cases_per_min"]
    return dict(rows=rows, speedup_2_over_1=rows[-1]["cases_per_min"] / base if base else None, target_speedup=1.8)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10, help="best a multiple of 5 (the configurations rotate)")
    ap.add_argument("--sweep-cases", type=int, default=120,
                    help="0: skip the throughput part. A case takes ~0.15 s: with fewer than ~100 the ratio "
                         "measures the sweep's start and tail more than its throughput")
    ap.add_argument("--time-step-ms", type=float, default=2.0)
    ap.add_argument("--spatial-repeats", type=int, default=5, help="0: skip the spatial part")
    ap.add_argument("--spatial", nargs="+", default=list(SPATIAL_SCENARIOS), metavar="SCENARIO[@K]",
                    help="spatial scenarios (TOPP-RA plan; @K: time-scaled by K)")
    ap.add_argument("--out", default=str(ROOT / "out"), help="a folder, or a file name ending in .json")
    a = ap.parse_args(argv)
    import qmt_drake
    from qmt_drake.errors import QmtInputError
    from qmt_drake.outputs import check_output_dir
    out_file = Path(a.out) if a.out.endswith(".json") else Path(a.out) / "bench_cosim_floor.json"
    try:  # before any simulation: a folder that cannot be written stops here, in one line
        check_output_dir(str(out_file.parent), "--out")
    except QmtInputError as exc:
        print(f"{ap.prog}: error: {exc}", file=sys.stderr)
        return 2
    data = dict(machine=platform.platform(), cpus=os.cpu_count(), python=platform.python_version(),
                when=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()), loadavg_start=os.getloadavg(),
                qmt_drake=str(Path(qmt_drake.__file__).parent.parent),
                note="shared machine: wall times vary run to run; medians of alternating runs")
    print(f"qmt_drake from {data['qmt_drake']}", flush=True)
    if a.spatial_repeats > 0:
        data["spatial"] = sp = spatial_cost(a.spatial, a.spatial_repeats)
        print_rows(sp)
        write_text_atomic(out_file, json.dumps(jsonable(data), indent=1))
    if a.repeats <= 0:
        write_text_atomic(out_file, json.dumps(jsonable(data), indent=1))
        print(f"wrote {out_file}")
        return 0
    data["cost"] = c = cost_ratio(a.repeats, a.time_step_ms * 1e-3)
    print(f"cost: ours {c['ours_us_per_step_median']:.0f} us/step, floor {c['floor_us_per_step_median']:.0f} us/step, "
          f"ratio {c['ratio_wall_median']:.2f} (wall, median), {c['ratio_cpu_median']:.2f} (CPU); target <= 1.3; "
          f"ours simulation only {c['ratio_ours_simulation_only_wall_median']:.2f}; with the per-step Python monitor "
          f"{c['ratio_ours_per_step_monitor_wall_median']:.2f}; floor + our magnet "
          f"{c['ratio_floor_our_magnet_wall_median']:.2f}; previous plant's floor "
          f"{c['ratio_floor_previous_plant_wall_median']:.2f}; summary from the log {c['posthoc_summary_s_median'] * 1e3:.1f} ms "
          f"(vs the per-step monitor: max rel. diff {c['logs_summary_vs_per_step_monitor_max_rel_diff']:.1e}); "
          f"ours held {c['ours_held']}, floor part offset {c['floor_final_offset_m'] * 1e3:.3f} mm; "
          f"load {c['loadavg_before'][0]:.2f} -> {c['loadavg_after'][0]:.2f}", flush=True)
    write_text_atomic(out_file, json.dumps(jsonable(data), indent=1))
    if a.sweep_cases > 0:
        data["throughput"] = t = throughput(a.sweep_cases)
        print(f"throughput speed-up 2/1 workers: {t['speedup_2_over_1']:.2f} (target >= 1.8)", flush=True)
    write_text_atomic(out_file, json.dumps(jsonable(data), indent=1))
    print(f"wrote {out_file}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
