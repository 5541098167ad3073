"""Sweep cases of a spatial scenario (`kind: spatial_transfer`): the same Case, PlanRef, store and
runner as the planar cases (cases.py, runner.py), with the spatial co-simulation as the worker.

Physics of the uncertainty: the plan and the controller (Drake's inverse-dynamics controller, or the
DC motors' PD law with its back-EMF and inverse-dynamics feedforward) are made from the NOMINAL
scenario; a case simulates a drawn copy of it (`perturbed_scenario`): the part's mass and centre of
mass, the hand's hold (suction: vacuum pull, cup friction; magnet: pull, hence its moment limit;
tray: the cup's friction), the motors' torque constant, resistance and gear efficiency (the
amplifier's current limit stays the nominal one), the executed law's gains and loop period (kp_scale, kd_scale,
loop_period_s: drawn_drive), and the executed timing (time_scale_jitter). The spec's sim.integral_rate_per_s
gives the nominal law an integral (default: the scenario's, 0).

A perturbed copy is cheap: dataclasses.replace of the scenario with a new CarriedBody / GripModel /
TrayCup / SpatialMotors and, when the body changes, a new SpatialChain on the same plant (no URDF
parse, no IK).
"""

from __future__ import annotations

import dataclasses
import json
import os
import socket
import tempfile
import time

import numpy as np

from qmt_drake.errors import QmtInputError, QmtSimulationError
from qmt_drake.limits.contact_wrench import CarriedBody, face_basis
from qmt_drake.limits.suction import GripModel
from qmt_drake.model.spatial_chain import SpatialChain
from qmt_drake.outputs import jsonable
from qmt_drake.planners import registry
from qmt_drake.planners.spatial_plan_io import load_spatial_plan, make_spatial_plan, plan_file_dict
from qmt_drake.planners.spatial_trajectory import TimeScaled
from qmt_drake.sim.spatial_actuation import SpatialMotorDrive, motor_params_for_spatial
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_motor import check_control_period, check_integral_rate
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.sweep.cases import Case, PlanRef, plan_file_hash, stable_hash
from qmt_drake.sweep.parameters import MOTOR_PARAMETERS, PARAMETERS, SPATIAL_HAND_PARAMETERS
from qmt_drake.sweep.spec import SweepSpec
from qmt_drake.systems.joint_tracking import PidGains

# The drawn gears' efficiency (< 1) switched at zero joint speed (dc_motor.gear_gain: eta motoring, 1 back-driven)
# makes a joint held against gravity chatter at the 1 ms loop's Nyquist rate: the arm stands still to 1e-7 rad
# while its speed flips sign every step (4e-4 rad/s on the UR5), and the carried part's logged acceleration
# (0.1-0.3 m/s^2) adds 0.03-0.05 to the hold ratio of a part at rest and lost UR5 magnet draws at 0.04 s that the
# limit model holds (studies/hold_floor.py, docs/robustness.md). Cases that draw the gear efficiency simulate the
# regularised switch (dc_motor's efficiency_blend_speed_rad_s, as Coulomb friction is regularised at zero speed):
# 25x the chatter's speed, below 1 % of the joints' speed limits; above 3x it the switched model is unchanged.
EFFICIENCY_BLEND_RAD_S = 0.01
GAIN_PARAMETERS = ("kp_scale", "kd_scale")  # the executed PD law's gains over the designed ones (dc_motor)
LAW_PARAMETERS = GAIN_PARAMETERS + ("loop_period_s",)  # the executed law's (drawn_drive), not the motors'


# ------------------------------------------------------------------------- the drawn scenario
def perturbed_scenario(sc, values: dict):
    """A copy of the spatial scenario `sc` with the named parameters (sweep/parameters.PARAMETERS,
    those of SPATIAL_HAND_PARAMETERS[sc.hand_kind]) set; time_scale and time_scale_jitter are the
    replay's, not the scenario's, and are ignored here."""
    v = {k: float(x) for k, x in values.items() if k not in ("time_scale", "time_scale_jitter")}
    allowed = SPATIAL_HAND_PARAMETERS[sc.hand_kind]
    for k in v:
        if k not in allowed:
            raise QmtInputError(f"parameter '{k}': the spatial {sc.hand_kind} hand's co-simulation does not vary it; "
                                f"vary {', '.join(allowed)}")
    changes = {}
    if sc.hand_kind == "tray":
        cup = sc.cup
        mass = v.get("mass_kg", cup.mass_kg * v.get("mass_scale", 1.0))
        h_g = (v.get("com_offset_m", cup.h_G * v.get("com_offset_scale", 1.0))
               if "com_offset_m" in v or "com_offset_scale" in v else cup.com_height_m)
        new = dataclasses.replace(cup, mass_kg=mass, com_height_m=h_g, friction=v.get("friction", cup.friction))
        if new != cup:
            changes["cup"] = new
        if new.mass_kg != cup.mass_kg or new.h_G != cup.h_G:  # friction leaves the carried body as it is
            changes["body"] = new.body(sc.face_axis)
    else:
        b = sc.body
        mass = v.get("mass_kg", b.mass_kg * v.get("mass_scale", 1.0))
        a = np.asarray(sc.face_axis, float) / np.linalg.norm(sc.face_axis)
        along = float(np.dot(b.com_m, a))
        com = np.asarray(b.com_m, float) + (v.get("com_offset_m", along * v.get("com_offset_scale", 1.0)) - along) * a
        com = com + v.get("com_lateral_m", 0.0) * face_basis(a)[0]
        if mass != b.mass_kg or not np.array_equal(com, b.com_m):
            # the same shape: its inertia scales with its mass
            changes["body"] = CarriedBody(mass, com, np.asarray(b.inertia_kgm2, float) * (mass / b.mass_kg))
        if sc.hand_kind == "suction" and ("friction" in v or "vacuum_force_scale" in v):
            g = sc.grip
            changes["grip"] = GripModel(g.radius_m, g.pull_force_N * v.get("vacuum_force_scale", 1.0),
                                        v.get("friction", g.friction), face_normal=g.basis[2],
                                        rim_points=g.rim_points, pyramid_edges=g.pyramid_edges,
                                        pyramid_angle_rad=g.pyramid_angle_rad)
        if sc.hand_kind == "magnet" and "magnet_pull_scale" in v:
            changes["moment_limit_Nm"] = sc.moment_limit_Nm * v["magnet_pull_scale"]
    if "body" in changes:  # the planners' chain carries the part (joint torques, limit check)
        changes["chain"] = SpatialChain(sc.plant, sc.chain.hand_frame, carried=changes["body"].as_dict(),
                                        reflected_inertia_kgm2=sc.drive["reflected_inertia_kgm2"])
    if any(k in v for k in MOTOR_PARAMETERS if k not in LAW_PARAMETERS):  # the law's: drawn_drive
        m = sc.motor
        n = len(sc.joint_names)
        changes["motor"] = dataclasses.replace(
            m, torque_constant_Nm_per_A=m.torque_constant_Nm_per_A * v.get("motor_torque_constant_scale", 1.0),
            resistance_ohm=m.resistance_ohm * v.get("motor_resistance_scale", 1.0),
            gear_efficiency=np.full(n, v["gear_efficiency"]) if "gear_efficiency" in v else m.gear_efficiency)
    return dataclasses.replace(sc, **changes) if changes else sc


def default_actuator(sc) -> str:
    """The scenario's real drive: its DC motors when it has actuators.motor, else the ideal controller."""
    return "ideal" if sc.motor is None else "dc_motor"


# ------------------------------------------------------------------------------- client side
def check_spatial_spec(spec: SweepSpec, base) -> tuple[str, str]:
    """One-line QmtInputError when the spec varies what the spatial scenario's co-simulation does not
    model; returns its (actuator, feedforward): sim.actuator (default: default_actuator) and
    sim.feedforward (default full)."""
    for name in (*spec.fixed, *spec.grid, *spec.distributions):
        if name != "time_scale" and name not in SPATIAL_HAND_PARAMETERS[base.hand_kind]:
            raise QmtInputError(f"sweep parameter '{name}': the spatial {base.hand_kind} hand's co-simulation does "
                                f"not vary it (scenario {base.name}); vary "
                                f"{', '.join(SPATIAL_HAND_PARAMETERS[base.hand_kind])}")
        if name in MOTOR_PARAMETERS and base.motor is None:
            raise QmtInputError(f"sweep parameter '{name}': scenario {base.name} has no actuators.motor (the DC motors "
                                "it scales); add actuators.motor to the scenario or drop the parameter")
    extra = sorted(set(spec.sim) - {"actuator", "feedforward", "integral_rate_per_s"})
    if extra:
        raise QmtInputError(f"sweep sim.{extra[0]}: the spatial co-simulation steps at 1 ms; give only sim.actuator, "
                            "sim.feedforward and sim.integral_rate_per_s")
    actuator = spec.sim.get("actuator", default_actuator(base))
    if actuator == "dc_motor" and base.motor is None:
        raise QmtInputError(f"sweep sim.actuator dc_motor: scenario {base.name} has no actuators.motor; use ideal")
    feedforward = (spec.raw.get("sim") or {}).get("feedforward", "full")
    if actuator == "ideal" and feedforward not in ("full", "shaped"):
        raise QmtInputError(f"sweep sim.feedforward {feedforward}: applies to sim.actuator dc_motor; the ideal actuator "
                            "always has the full feedforward (or 'shaped': on the shaped reference)")
    if any(n in MOTOR_PARAMETERS for n in spec.parameter_names) and actuator != "dc_motor":
        raise QmtInputError("sweep: motor parameters act through sim.actuator dc_motor; set it or drop them")
    if "integral_rate_per_s" in spec.sim:
        if actuator != "dc_motor":
            raise QmtInputError("sweep sim.integral_rate_per_s: the DC-motor drive's PID integral; set sim.actuator "
                                "dc_motor or drop it (the ideal controller has none)")
        check_integral_rate(spec.sim["integral_rate_per_s"], "sweep sim", base.n_dof, base.joint_names)
    return actuator, feedforward


def drive_options(spec: SweepSpec) -> dict:
    """The spec's drive options beyond actuator and feedforward that go into each case's sim (only when given:
    a spec without them keeps its case keys): integral_rate_per_s [1/s] (a number or one per joint)."""
    rate = spec.sim.get("integral_rate_per_s")
    if rate is None:
        return {}
    return {"integral_rate_per_s": [float(x) for x in rate] if isinstance(rate, list) else float(rate)}


def build_spatial_cases(spec: SweepSpec) -> tuple[list[Case], dict[str, PlanRef]]:
    """All cases of a spec on a spatial scenario (plans x grid points x samples) and their plans."""
    base = _scenario(spec.scenario)  # validates the scenario before any long work
    actuator, feedforward = check_spatial_spec(spec, base)
    options = drive_options(spec)
    samples = spec.samples()
    cases, plans = [], {}
    for pdef in spec.plans:
        if "file" in pdef:  # loaded (rebuilt, fitted to the scenario) now: in a worker a bad file was every case's
            load_spatial_plan(pdef["file"], base)  # failure (exit 4), named by the worker's temporary copy
            ref = PlanRef(spec.scenario, {}, file=pdef["file"], file_sha256=plan_file_hash(pdef["file"]))
        else:
            ref = PlanRef(spec.scenario, {}, method=registry.find(registry.SPATIAL, pdef["method"]).name,
                          options=dict(pdef.get("options") or {}), seed=pdef.get("seed", 0))
        plans.setdefault(ref.key, ref)
        for point in spec.grid_points():
            for i, draw in enumerate(samples):
                values = {**spec.fixed, **point, **draw}
                drive = {k for k in values if k in MOTOR_PARAMETERS}  # motors drawn, the PD law's gains drawn
                drawn = {k: float(x) for k, x in values.items() if PARAMETERS[k].target != "sim" and k not in drive}
                motor = {k: float(x) for k, x in values.items() if k in drive}
                sim = {"time_scale": float(values.get("time_scale", 1.0)) * float(values.get("time_scale_jitter", 1.0)),
                       "actuator": actuator, "feedforward": feedforward, **options}
                if "gear_efficiency" in values:  # in the key: such cases simulate the regularised gear switch
                    sim["efficiency_blend_speed_rad_s"] = EFFICIENCY_BLEND_RAD_S
                cases.append(Case(index=len(cases), label=pdef["label"], scenario=spec.scenario, scenario_overrides={},
                                  plan_key=ref.key, payload=drawn, magnet={}, motor_scales=motor, sim=sim,
                                  parameters=dict(values), sample=i if spec.distributions else None))
    return cases, plans


# ------------------------------------------------------------------------------- worker side
_SCENARIOS: dict = {}
_PLANS: dict = {}
_DRIVES: dict = {}


def _scenario(name: str):
    if name not in _SCENARIOS:
        _SCENARIOS[name] = load_spatial_scenario(name)
    return _SCENARIOS[name]


def make_spatial_plan_doc(ref: PlanRef) -> dict:
    """Plan once (in a worker), or read the plan file: the plan file's JSON document plus its key."""
    t0 = time.perf_counter()
    if ref.file is not None:
        with open(ref.file) as fh:
            doc = json.load(fh)
    else:
        sc = _scenario(ref.scenario)  # the one planner registry (its refusals: one line naming the methods)
        doc = jsonable(plan_file_dict(sc, registry.plan(sc, ref.method, seed=ref.seed, **ref.options)))
    doc["plan_key"] = ref.key
    doc["plan_wall_s"] = time.perf_counter() - t0
    return doc


def _plan(doc: dict, sc):
    k = doc.get("plan_key") or stable_hash(doc)
    if k not in _PLANS:  # load_spatial_plan reads files only (and re-checks the plan on sc)
        fd, tmp = tempfile.mkstemp(suffix=".json", prefix="qmt_spatial_plan_")
        try:
            with os.fdopen(fd, "w") as fh:
                json.dump(doc, fh)
            _PLANS[k] = load_spatial_plan(tmp, sc)
        finally:
            os.unlink(tmp)
    return _PLANS[k]


def _drive(sc, physical, plan, plan_key: str, case_sim: dict, values: dict):
    """The nominal DC-motor law (gains, feedforward model, the case's integral rate) driving the drawn motors
    (drawn_drive)."""
    feedforward, rate = case_sim["feedforward"], case_sim.get("integral_rate_per_s")
    k = (sc.name, plan_key, feedforward, json.dumps(rate))
    if k not in _DRIVES:
        _DRIVES[k] = SpatialMotorDrive.for_scenario(sc, plan.trajectory.sample([0.0])[0][0], feedforward,
                                                    integral_rate_per_s=rate)
    return drawn_drive(_DRIVES[k], sc, physical, values, case_sim.get("efficiency_blend_speed_rad_s"))


def drawn_drive(nominal: SpatialMotorDrive, sc, physical, values: dict,
                efficiency_blend_speed_rad_s: float | None = None) -> SpatialMotorDrive:
    """The nominal DC-motor drive (its feedforward model, its loop damping: the controller's) with the drawn
    motors simulated (`physical`'s, when they differ from `sc`'s) and the executed PD law's voltage gains
    scaled by values' kp_scale / kd_scale (the integral gain goes with kp: Ki = Kp x the integral rate), sampled
    and held at values' loop_period_s [s] when drawn. The loop damping moved into the plant is added back by
    the law (sim/actuation.motor_actuation_law), so it stays the nominal one without changing the physics.
    efficiency_blend_speed_rad_s [rad/s]: the drawn motors' gear switch regularised (EFFICIENCY_BLEND_RAD_S)."""
    d = nominal
    if physical.motor is not sc.motor:
        pm = motor_params_for_spatial(physical)
        if efficiency_blend_speed_rad_s is not None:
            pm = dataclasses.replace(pm, efficiency_blend_speed_rad_s=float(efficiency_blend_speed_rad_s))
        d = dataclasses.replace(d, plant_params=pm)
    kp, kd = float(values.get("kp_scale", 1.0)), float(values.get("kd_scale", 1.0))
    if kp != 1.0 or kd != 1.0:
        g = d.gains
        d = dataclasses.replace(d, gains=PidGains(g.kp_V_per_rad * kp, g.ki_V_per_rad_s * kp, g.kd_V_s_per_rad * kd),
                                gain_scales=(kp, kd))  # (a held current law's own gains scaled alike: law_gains)
    if "loop_period_s" in values:  # the law sampled and held at the drawn period (at least the plant step)
        d = dataclasses.replace(d, control_period_s=check_control_period(float(values["loop_period_s"])))
    return d


def run_spatial_case(case: Case, plan_doc: dict) -> dict:
    """Simulate one spatial case in this process (never raises for a failed simulation: status
    'sim_failed' counts as not carried)."""
    t0 = time.perf_counter()
    sc = _scenario(case.scenario)
    plan = _plan(plan_doc, sc)
    s = float(case.sim.get("time_scale", 1.0))
    out = {"key": case.key, "index": case.index, "label": case.label, "plan_key": case.plan_key,
           "parameters": case.parameters, "sample": case.sample, "method": plan.method,
           "motion_time_s": float(plan.duration_s) * s, "plan_motion_time_s": float(plan.duration_s),
           "plan_feasible": bool(plan.recheck["max"] <= 1.0), "actuator": case.sim["actuator"],
           "host": socket.gethostname(), "pid": os.getpid()}
    try:
        drawn = {**case.payload, **case.motor_scales}
        physical = perturbed_scenario(sc, drawn)
        out["payload_mass_kg"] = float(physical.body.mass_kg)
        drive = (_drive(sc, physical, plan, case.plan_key, case.sim, drawn)
                 if case.sim["actuator"] == "dc_motor" else None)
        traj = plan.trajectory if s == 1.0 else TimeScaled(plan.trajectory, s)
        r = simulate_spatial(physical, traj, controller_sc=sc, drive=drive, feedforward=case.sim["feedforward"])
    except (QmtSimulationError, ValueError, RuntimeError) as exc:  # a drawn part Drake cannot simulate
        out.update(status="sim_failed", held=False, outcome="failed", error=f"{type(exc).__name__}: {exc}")
    else:
        out.update(status="ok", held=bool(r["held"]), outcome=r["outcome"], detached_at_s=r["lost_at_s"],
                   max_slip_m=r.get("final_slide_m"), max_grip_ratio_while_held=r["max_grip_ratio_while_held"],
                   max_tracking_error_rad=r["max_tracking_error_rad"],
                   final_goal_error_rad=r["final_goal_error_rad"])
    out["wall_s"] = time.perf_counter() - t0
    return out


def spatial_time_scaled_plan(sc, plan, time_scale: float, method: str, extra: dict | None = None):
    """`plan` played time_scale times slower as a SpatialPlan (re-checked; task poses checked by FK)."""
    traj = TimeScaled(plan.trajectory, time_scale) if time_scale != 1.0 else plan.trajectory
    return make_spatial_plan(sc, method, traj, plan.pose_times_s * time_scale, planning_s=plan.planning_s,
                             raw_duration_s=plan.raw_duration_s, hold_scale=plan.hold_scale * time_scale,
                             info=dict(plan.info, time_scale=float(time_scale), **(extra or {})))
