"""Sweep parameters: the table of every quantity a sweep may vary (`PARAMETERS`: where it goes,
its unit and its physical range), the distributions a Monte Carlo draws it from, and the checks of a
value, a list of values or a distribution against that table.

Every parameter maps to exactly one place: a field of the co-simulation's PayloadSpec (the physical
part: its mass and r_G vary, the plan does not), the magnet (coil current, absolute or as a multiple
of the calibrated current; the equivalent gap g0), the motor model (multiples of torque constant and
resistance), a scenario override (gains as multiples of the scenario's, the planning moment limit),
a `simulate_transfer` keyword (time scale, step) or the planner (seed, Ruckig jerk limit). "scale"
parameters multiply the nominal value. sweep/spec.py parses a spec against this table; a scenario's
`uncertainty` section is checked here too (validate_uncertainty, called by transfer_scenario.load_scenario).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import norm, truncnorm

from qmt_drake.config.fields import check_keys, is_number, show
from qmt_drake.errors import QmtInputError
from qmt_drake.spatial_motor import MAX_CONTROL_PERIOD_S

MAX_TIME_STEP_S = 0.005  # measured: thesis-ch4 replayed at 2 and 5 ms is carried, at 10 and 20 ms "lost" (a step artifact)

# Where a parameter goes (cases.py applies them):
#   payload  -> dataclasses.replace(PayloadSpec, field=value)   (the simulated part only)
#   magnet   -> coil current [A] / effective gap g0 [m]
#   motor    -> DcMotorParams field multiplied by value
#   scenario -> override in the scenario's YAML mapping (dotted path)
#   sim      -> simulate_transfer keyword
#   plan     -> planner input (seed, or an option of the planner)


@dataclass(frozen=True)
class Parameter:
    name: str
    target: str  # payload | magnet | motor | scenario | sim | plan
    field: str
    scale: bool  # True: value multiplies the nominal value
    unit: str
    doc: str
    lower: float = 0.0  # values must be > lower (or >= when inclusive)
    inclusive: bool = False
    upper: float = math.inf
    integer: bool = False
    kinds: tuple = ("planar",)  # the scenario kinds whose cases vary it: planar, spatial


BOTH, SPATIAL = ("planar", "spatial"), ("spatial",)

PARAMETERS: dict[str, Parameter] = {p.name: p for p in (
    Parameter("friction", "payload", "friction", False, "-", "Coulomb friction, part on face", kinds=BOTH),
    Parameter("mass_kg", "payload", "mass_kg", False, "kg", "simulated part mass", kinds=BOTH),
    Parameter("mass_scale", "payload", "mass_kg", True, "-", "simulated part mass / nominal", kinds=BOTH),
    Parameter("com_offset_m", "payload", "com_offset_m", False, "m", "simulated r_G", kinds=BOTH),
    Parameter("com_offset_scale", "payload", "com_offset_m", True, "-", "simulated r_G / nominal", kinds=BOTH),
    Parameter("contact_stiffness_N_per_m", "payload", "point_stiffness_N_per_m", False, "N/m",
              "contact point stiffness"),
    Parameter("coil_current_A", "magnet", "coil_current_A", False, "A", "coil current",
              inclusive=True),
    Parameter("coil_current_scale", "magnet", "coil_current_A", True, "-",
              "coil current / the calibrated current of the nominal part", inclusive=True),
    Parameter("magnet_gap_m", "magnet", "effective_gap_m", False, "m",
              "equivalent magnet gap g0 (coil current stays as set)"),
    Parameter("motor_torque_constant_scale", "motor", "torque_constant_Nm_per_A", True, "-",
              "motor torque (= back-EMF) constant / catalogue", kinds=BOTH),
    Parameter("motor_resistance_scale", "motor", "resistance_ohm", True, "-",
              "armature resistance / catalogue", kinds=BOTH),
    # planar: control.kp / kd of the scenario; spatial dc_motor: the executed PD law's voltage gains over the
    # ones designed from the nominal model (spatial_actuation.decentralised_gains), the feedforward nominal
    Parameter("kp_scale", "scenario", "control.kp", True, "-", "proportional gains / scenario's (designed)",
              inclusive=True, kinds=BOTH),
    Parameter("kd_scale", "scenario", "control.kd", True, "-", "derivative gains / scenario's (designed)",
              inclusive=True, kinds=BOTH),
    Parameter("moment_limit_Nm", "scenario", "limits.moment_limit_Nm", False, "N*m",
              "planning moment limit (replans)"),
    Parameter("time_scale", "sim", "time_scale", False, "-",
              "replay time stretch (<1 faster; moment ~ 1/s^2)", kinds=BOTH),
    Parameter("time_step_s", "sim", "time_step_s", False, "s", "plant step", upper=MAX_TIME_STEP_S),
    Parameter("servo_delay_s", "sim", "servo_delay_s", False, "s",
              "latency of the goal stream to the servos (tray hand)", inclusive=True, upper=0.1),
    Parameter("seed", "plan", "seed", False, "-", "planner seed", lower=0.0, inclusive=True,
              integer=True),
    Parameter("jerk_limit_m_s3", "plan", "options.jerk_limit", False, "m/s^3",
              "Ruckig tip jerk limit (replans)"),
    # executed timing: the plan replayed time_scale x time_scale_jitter slower (a drive that runs the
    # trajectory at another speed than planned); not searched, drawn
    Parameter("time_scale_jitter", "sim", "time_scale_jitter", False, "-",
              "executed time scale / the planned one", kinds=BOTH),
    # spatial hands (sweep/spatial_cases.perturbed_scenario applies them)
    Parameter("vacuum_force_scale", "hand", "pull_force_N", True, "-", "suction cup's vacuum pull / nominal",
              kinds=SPATIAL),
    Parameter("magnet_pull_scale", "hand", "moment_limit_Nm", True, "-",
              "magnet's pull / nominal (its face-plane moment limit scales with it)", kinds=SPATIAL),
    Parameter("com_lateral_m", "payload", "com_lateral_m", False, "m",
              "part's centre of mass off the face normal (hand frame, first face-plane axis)",
              lower=-math.inf, kinds=SPATIAL),
    Parameter("gear_efficiency", "motor", "gear_efficiency", False, "-", "every joint's gear efficiency",
              upper=1.0, kinds=SPATIAL),
    # the DC drive law's sample-and-hold period (a firmware loop; sim/spatial_actuation), from the spatial sweeps'
    # 1 ms plant step (sim/spatial_cosim.TIME_STEP_S) to spatial_motor.MAX_CONTROL_PERIOD_S
    Parameter("loop_period_s", "motor", "control_period_s", False, "s", "DC drive law's control period (held)",
              lower=1e-3, inclusive=True, upper=MAX_CONTROL_PERIOD_S, kinds=SPATIAL),
)}

# What each spatial hand's co-simulation varies (sweep/spatial_cases.perturbed_scenario); the motor
# parameters (the motors drawn, and the executed PD law's gains) also need actuators.motor (the dc_motor drive).
MOTOR_PARAMETERS = ("motor_torque_constant_scale", "motor_resistance_scale", "gear_efficiency", "kp_scale", "kd_scale",
                    "loop_period_s")
_COMMON = ("mass_kg", "mass_scale", "com_offset_m", "com_offset_scale", "time_scale_jitter") + MOTOR_PARAMETERS
SPATIAL_HAND_PARAMETERS = {
    "suction": _COMMON + ("friction", "vacuum_force_scale", "com_lateral_m"),
    "magnet": _COMMON + ("magnet_pull_scale", "com_lateral_m"),  # the spatial magnet has no friction model
    "tray": _COMMON + ("friction",),  # the cup stands on its axis (no lateral centre of mass)
}

DISTRIBUTIONS = {"uniform": ("low", "high"), "normal": ("mean", "std"),
                 "truncnormal": ("mean", "std", "low", "high")}


@dataclass(frozen=True)
class Distribution:
    kind: str
    args: dict

    def sample(self, rng: np.random.Generator, n: int, p: Parameter) -> np.ndarray:
        a = self.args
        if self.kind == "uniform":
            x = rng.uniform(a["low"], a["high"], n)
        else:
            # normal: truncated at the parameter's physical bound; truncnormal: at [low, high].
            lo = a.get("low", p.lower)
            hi = a.get("high", p.upper)
            x = _truncated_normal(rng, a["mean"], a["std"], lo, hi, n)
        return np.round(x).astype(int) if p.integer else x


def _truncated_normal(rng, mean, std, lo, hi, n) -> np.ndarray:
    if std == 0:
        return np.full(n, float(mean))
    a, b = (lo - mean) / std, (hi - mean) / std
    return truncnorm.ppf(rng.uniform(size=n), a, b, loc=mean, scale=std)



def check_distribution(v: dict, p: Parameter, at: str) -> Distribution:
    kind = v["dist"]
    if kind not in DISTRIBUTIONS:
        raise QmtInputError(f"{at}: unknown distribution '{kind}'; use one of {', '.join(DISTRIBUTIONS)}")
    need = DISTRIBUTIONS[kind]
    allowed = set(need) | {"dist"} | ({"low", "high"} if kind == "normal" else set())
    check_keys(v, allowed, at)
    missing = [k for k in need if k not in v]
    if missing:
        raise QmtInputError(f"{at}: a {kind} distribution needs {', '.join(need)}; missing "
                            f"{', '.join(missing)}")
    args = {k: number(v[k], f"{at}.{k}") for k in v if k != "dist"}
    if "std" in args and args["std"] < 0:
        raise QmtInputError(f"{at}: std {args['std']:g} is negative; a spread must be >= 0")
    if "low" in args and "high" in args and not args["low"] <= args["high"]:
        raise QmtInputError(f"{at}: low {args['low']:g} > high {args['high']:g}; a spread must be "
                            ">= 0 (swap them)")
    lo = args.get("low", args.get("mean"))
    hi = args.get("high", args.get("mean"))
    for x in (lo, hi):
        check_range(x, p, at)
    if kind == "normal" and p.integer:
        raise QmtInputError(f"{at}: '{p.name}' is an integer; give a list of values instead")
    if kind == "normal" and args["std"] > 0 and "low" not in args and "high" not in args:
        _check_normal_within_bounds(args["mean"], args["std"], p, at)
    return Distribution(kind, args)


# A normal's draws are cut at the parameter's physical bounds (Distribution.sample); beyond this share of its
# mass cut off (2.3 std), the cases are no longer the distribution the file names (friction N(0.3, 1): mean 0.92,
# not 0.3), unless the file says where to cut (low / high).
MAX_CUT_MASS = 0.01


def _check_normal_within_bounds(mean: float, std: float, p: Parameter, at: str) -> None:
    a, b = (p.lower - mean) / std, (p.upper - mean) / std
    cut = float(norm.cdf(a) + norm.sf(b))
    if cut > MAX_CUT_MASS:
        drawn = float(truncnorm.mean(a, b, loc=mean, scale=std))
        raise QmtInputError(f"{at}: normal(mean {mean:g}, std {std:g}) has {cut:.1%} of its mass outside "
                            f"{p.name}'s range ({p.lower:g}, {p.upper:g}); the draws would be cut there (their mean "
                            f"{drawn:.3g}, not {mean:g}): give a smaller std, or say where to cut it (low, high)")


def check_values(values, p: Parameter, at: str) -> list:
    if not isinstance(values, list) or not values:
        raise QmtInputError(f"{at}: give a non-empty list of values")
    out = []
    for x in values:
        x = integer(x, at, minimum=0) if p.integer else number(x, at)
        check_range(x, p, at)
        out.append(x)
    return out


def check_range(x: float, p: Parameter, at: str) -> None:
    ok_lo = x >= p.lower if p.inclusive else x > p.lower
    if not ok_lo or x > p.upper:
        rel = ">=" if p.inclusive else ">"
        upper = f" and <= {p.upper:g}" if math.isfinite(p.upper) else ""
        raise QmtInputError(f"{at}: {x:g} is out of range; {p.name} ({p.doc}, {p.unit}) must be "
                            f"{rel} {p.lower:g}{upper}")


def number(v, at: str, positive: bool = False) -> float:
    """A finite number (config/fields.py's rule: not a bool, not a string)."""
    if not is_number(v):
        raise QmtInputError(f"{at}: must be a number, got {show(v)}")
    x = float(v)
    if not math.isfinite(x) or (positive and x <= 0):
        raise QmtInputError(f"{at}: must be a {'positive' if positive else 'finite'} number, got {show(v)}")
    return x


def integer(v, at: str, minimum: int = 0, maximum: int = 2 ** 63 - 1) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not minimum <= v <= maximum:
        raise QmtInputError(f"{at}: must be an integer in [{minimum}, {maximum}], got {show(v)}")
    return int(v)




def validate_uncertainty(u: dict, where: str) -> None:
    """A scenario's `uncertainty` section: every parameter a known sweep parameter drawn from a
    distribution (its keys and ranges checked as in a spec), monte_carlo {cases >= 1, seed}."""
    for pname, v in u["parameters"].items():
        at = f"{where}.parameters.{pname}"
        if pname not in PARAMETERS:
            raise QmtInputError(f"{at}: unknown parameter '{pname}'; known parameters are {', '.join(PARAMETERS)}")
        if not (isinstance(v, dict) and "dist" in v):
            raise QmtInputError(f"{at}: give a distribution, e.g. {{dist: normal, mean: 0.3, std: 0.03}}")
        check_distribution(v, PARAMETERS[pname], at)
    mc = u.get("monte_carlo") or {}
    if not isinstance(mc, dict):
        raise QmtInputError(f"{where}.monte_carlo must be a mapping {{cases: 200, seed: 1}}, got {mc!r}")
    check_keys(mc, {"cases", "seed"}, f"{where}.monte_carlo")
    if "cases" in mc:
        integer(mc["cases"], f"{where}.monte_carlo.cases", minimum=1)
    if "seed" in mc:
        integer(mc["seed"], f"{where}.monte_carlo.seed")



def check_spatial_uncertainty(u, hand_kind: str, where: str) -> dict:
    """A spatial scenario's `uncertainty` section (the planar one's shape, validate_uncertainty's
    checks), each parameter one its hand's co-simulation varies (SPATIAL_HAND_PARAMETERS); {} when absent.
    One-line QmtInputError otherwise. A motor parameter needs actuators.motor: checked when the section is
    used (sweep/spatial_cases.check_spatial_spec), so a copy of a file without its motors still loads."""
    if u is None:
        return {}
    if not isinstance(u, dict) or not isinstance(u.get("parameters"), dict) or not u["parameters"]:
        raise QmtInputError(f"{where} must be a mapping {{parameters: {{mass_scale: {{dist: normal, mean: 1, "
                            f"std: 0.05}}}}, monte_carlo: {{cases: 40, seed: 1}}}}, got {show(u)}")
    check_keys(u, {"parameters", "monte_carlo", "sim"}, where)
    check_success_drive(u.get("sim"), f"{where}.sim")
    allowed = SPATIAL_HAND_PARAMETERS[hand_kind]
    for pname in u["parameters"]:
        if pname in PARAMETERS and pname not in allowed:
            raise QmtInputError(f"{where}.parameters.{pname}: the spatial {hand_kind} hand's co-simulation does "
                                f"not vary it; vary {', '.join(allowed)}")
    validate_uncertainty(u, where)
    return dict(u)


SUCCESS_DRIVES = {"ideal": ("full", "shaped"), "dc_motor": ("full", "shaped")}  # --success / sweep drives


def check_success_drive(sim, where: str) -> dict:
    """A spatial `uncertainty.sim` (the drive `--success` runs the drawn cells through): {actuator: ideal |
    dc_motor, feedforward: full | shaped}, both optional ({} or None: the scenario's real drive, full
    feedforward). One-line QmtInputError otherwise."""
    if sim is None:
        return {}
    if not isinstance(sim, dict):
        raise QmtInputError(f"{where} must be a mapping {{actuator: dc_motor, feedforward: shaped}}, got {show(sim)}")
    check_keys(sim, {"actuator", "feedforward", "integral_rate_per_s"}, where)  # the rate: spatial_cases checks it
    if "actuator" in sim and sim["actuator"] not in SUCCESS_DRIVES:
        raise QmtInputError(f"{where}.actuator: {show(sim['actuator'])}; choose one of {', '.join(SUCCESS_DRIVES)}")
    if "feedforward" in sim and sim["feedforward"] not in SUCCESS_DRIVES["dc_motor"]:
        raise QmtInputError(f"{where}.feedforward: {show(sim['feedforward'])}; choose full (the plan as planned) or "
                            "shaped (the closed-loop-aware reference, sim/spatial_reference)")
    return dict(sim)
