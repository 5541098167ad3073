"""The spatial co-simulation's cost over a floor of Drake primitives (issue 27 "Cost"), for
studies/bench_cosim_floor.py, in the same process and run:

    ours   sim/spatial_cosim.simulate_spatial(sc, plan) as the CLI calls it, whole: drive choice, grip
           model, plant and controller plant from the URDF, diagram, run, the hold check, the summary;
    floor  the same physics built with pydrake primitives only: the same checked URDF plant
           (model/urdf_check.load_arm_plant, 1 ms discrete SAP), the same part as a free body on the
           same weld constraint (the tray hand: the same tray box and cup on its 6-DOF joint, point
           contact, SceneGraph), Drake's InverseDynamicsController with the same gains and the same
           controller plant (part welded), the same Saturation at the torque limits, TrajectorySources
           of the same 1 kHz reference (sim/spatial_cosim._reference), the same initial state and final
           time; no monitor, no logger, no summary.

Both are built afresh every repeat (as a sweep case or a carried-plan search builds them); the two
alternate (A B, then B A, ...) so that a drift of the shared machine's speed hits both alike. Each
side's wall and CPU times are kept; the ratios are median(ours) / median(floor) and min / min.
"""

from __future__ import annotations

import gc
import time

import numpy as np


def _plans(names):
    """{name: (scenario, TOPP-RA plan's trajectory)} (planned once, outside any timing); a name
    SCENARIO@K plays the plan time-scaled by K (K > 1: slower)."""
    from qmt_drake.planners.spatial_methods import PLANNERS
    from qmt_drake.planners.spatial_trajectory import TimeScaled
    from qmt_drake.spatial_task import load_spatial_scenario
    out, planned = {}, {}
    for name in names:
        base, _, k = name.partition("@")
        if base not in planned:
            sc = load_spatial_scenario(base)
            planned[base] = (sc, PLANNERS["toppra"](sc).trajectory)
        sc, traj = planned[base]
        out[name] = (sc, TimeScaled(traj, float(k)) if k else traj)
    return out


def build_floor(sc, traj):
    """The floor diagram of sc playing traj (module docstring); returns (simulator, final time s)."""
    from pydrake.geometry import SceneGraph
    from pydrake.math import RigidTransform
    from pydrake.multibody.plant import DiscreteContactApproximation
    from pydrake.multibody.tree import RotationalInertia, SpatialInertia
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.controllers import InverseDynamicsController
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import Saturation, TrajectorySource

    from qmt_drake.model.urdf_check import load_arm_plant
    from qmt_drake.sim import spatial_cosim as S
    from qmt_drake.systems.payload import allow_contact

    tray = sc.hand_kind == "tray"
    b = DiagramBuilder()
    plant, H, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, time_step_s=S.TIME_STEP_S,
                                 effort_limit_Nm=sc.torque_limit_Nm, velocity_limit_rad_s=sc.velocity_limit_rad_s,
                                 finalize=False)
    plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    b.AddSystem(plant)
    if tray:
        scene_graph = b.AddSystem(SceneGraph())
        tray_body, cup, _ = S.add_tray_and_cup(plant, scene_graph, H, sc)
    else:
        m = sc.body
        M = SpatialInertia.MakeFromCentralInertia(m.mass_kg, np.asarray(m.com_m, float),
                                                  RotationalInertia(*np.diag(m.inertia_kgm2)))
        part = plant.AddRigidBody("part", plant.AddModelInstance("part"), M)
        plant.AddWeldConstraint(H.body(), H.GetFixedPoseInBodyFrame(), part, RigidTransform())
    plant.Finalize()
    if tray:
        b.Connect(plant.get_geometry_pose_output_port(), scene_graph.get_source_pose_port(plant.get_source_id()))
        b.Connect(scene_graph.get_query_output_port(), plant.get_geometry_query_input_port())
        allow_contact(plant, scene_graph, tray_body, cup)
    arm, n = H.model_instance(), sc.n_dof
    pp, acc, t_end, _ = S._reference(S._Delayed(traj, S.SETTLE_S) if tray else traj)
    src = b.AddSystem(TrajectorySource(pp, output_derivative_order=1))
    src_a = b.AddSystem(TrajectorySource(acc))
    ctrl_plant, _, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints, carried=sc.body.as_dict(),
                                      effort_limit_Nm=sc.torque_limit_Nm, velocity_limit_rad_s=sc.velocity_limit_rad_s)
    ctrl = b.AddSystem(InverseDynamicsController(ctrl_plant, np.full(n, S.KP_1_S2), np.full(n, S.KI_1_S3),
                                                 np.full(n, S.KD_1_S), True))
    sat = b.AddSystem(Saturation(-sc.torque_limit_Nm, sc.torque_limit_Nm))
    b.Connect(plant.get_state_output_port(arm), ctrl.get_input_port_estimated_state())
    b.Connect(src.get_output_port(), ctrl.get_input_port_desired_state())
    b.Connect(src_a.get_output_port(), ctrl.get_input_port_desired_acceleration())
    b.Connect(ctrl.get_output_port_control(), sat.get_input_port())
    b.Connect(sat.get_output_port(), plant.get_actuation_input_port(arm))
    sim = Simulator(b.Build())
    pctx = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
    plant.SetPositions(pctx, arm, traj.sample([0.0])[0][0])
    if not tray:
        plant.SetFreeBodyPose(pctx, part, H.CalcPoseInWorld(pctx))
    return sim, t_end


def _timed(f, *args):
    gc.collect(1)
    w0, c0 = time.perf_counter(), time.process_time()
    out = f(*args)
    return time.perf_counter() - w0, time.process_time() - c0, out


def spatial_cost(names, repeats: int) -> dict:
    """Per scenario: ours and the floor, `repeats` times each, alternating (module docstring)."""
    from qmt_drake.sim.spatial_cosim import simulate_spatial

    def floor(sc, traj):
        sim, t_end = build_floor(sc, traj)
        sim.AdvanceTo(t_end)
        return t_end

    cases = _plans(names)
    runs = {n: {"ours": {"wall": [], "cpu": []}, "floor": {"wall": [], "cpu": []}} for n in names}
    results = {}
    for r in range(repeats):
        for name, (sc, traj) in cases.items():
            order = (("ours", simulate_spatial), ("floor", floor))
            for side, f in order if (r % 2 == 0) else order[::-1]:
                wall, cpu, out = _timed(f, sc, traj)
                runs[name][side]["wall"].append(wall)
                runs[name][side]["cpu"].append(cpu)
                if side == "ours":
                    results[name] = out
    rows = {}
    for name, rr in runs.items():
        o, f = rr["ours"], rr["floor"]
        res = results[name]
        rows[name] = dict(runs=rr, duration_s=cases[name][1].duration_s,
                          outcome=res["outcome"], lost_at_s=res.get("lost_at_s"),
                          max_grip_ratio_while_held=res["max_grip_ratio_while_held"],
                          ours_wall_min_s=min(o["wall"]), ours_wall_median_s=float(np.median(o["wall"])),
                          floor_wall_min_s=min(f["wall"]), floor_wall_median_s=float(np.median(f["wall"])),
                          ratio_wall_median=float(np.median(o["wall"]) / np.median(f["wall"])),
                          ratio_wall_min=min(o["wall"]) / min(f["wall"]),
                          ratio_cpu_median=float(np.median(o["cpu"]) / np.median(f["cpu"])))
    return dict(repeats=repeats, plan="TOPP-RA (planners/spatial_methods), actuator ideal", rows=rows)


def print_rows(sp: dict) -> None:
    for name, r in sp["rows"].items():
        lost = f" at {r['lost_at_s']:.3f} s" if r["lost_at_s"] is not None else ""
        print(f"spatial {name}: ours {r['ours_wall_median_s']:.3f} s (min {r['ours_wall_min_s']:.3f}), floor "
              f"{r['floor_wall_median_s']:.3f} s (min {r['floor_wall_min_s']:.3f}); ratio {r['ratio_wall_median']:.2f} "
              f"(median wall), {r['ratio_wall_min']:.2f} (min), {r['ratio_cpu_median']:.2f} (CPU); "
              f"{r['outcome']}{lost}, hand ratio {r['max_grip_ratio_while_held']:.4f}", flush=True)
