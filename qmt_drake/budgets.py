"""Budgets: every size a user controls is priced in memory and time before the work starts.

Each `*_estimate` function returns an `Estimate` (bytes of memory, seconds of wall time on one core
of the machine the constants were measured on); `check_budget` refuses an estimate over the stated
budget (MEMORY_BUDGET_BYTES, TIME_BUDGET_S) in one line that gives the estimate and the fix, unless
the user passed `--allow-large`. Memory beyond the machine's physical RAM is refused even then
(the run could only end in MemoryError). Runs estimated above ANNOUNCE_S print their estimate.

Calibration (2026-11-25, this project's 2-core build machine, shared with other jobs, so the
constants are rounded up; the scripts are in the docstrings' "measured" notes, each a few seconds):

- limit re-check (`plan.recheck`, thesis-ch4, 2 joints, T = 1.735 s) at 1e4 / 1e5 / 1e6 Hz:
  0.046 / 0.24 / 2.13 s, peak Python memory 5.3 / 51 / 514 MB -> 1.3 us and 150 B per sample
  and joint (memory), CHECK_S_PER_SAMPLE and CHECK_BYTES_PER_SAMPLE_JOINT;
- GA (thesis-ch4, population 50, 40 generations, plan rate 1 kHz): 1789 evaluations in 0.90 s ->
  0.5 ms per evaluation of ~1700 samples: GA_S_PER_EVAL + GA_S_PER_SAMPLE * samples;
- magnet-arm co-simulation (thesis-ch4, 2 ms step) at time scale 1 / 10 / 40: 0.12 / 0.96 / 5.1 s,
  max RSS 142 / 176 / 301 MB -> 1.5e-4 s and 4.8 kB per plant step (Drake's loggers keep every
  step), SIM_S_PER_STEP and SIM_BYTES_PER_STEP; tray (crane-tray): 0.5 s per simulated second;
- energy-time objective (ohsaka-fig3) value and gradient: 1.1 ms at 40 divisions, 76 ms and 48 MB
  at 20000 divisions (3.7 us and 2.4 kB per division); SNOPT over 8 starts: m = 5 / 10 / 20 took
  0.17 / 0.57 / 5.7 s per start (287 / 601 / 3367 evaluations; ~ m^3.3), its dense quasi-Newton
  matrices 8 * n^2 bytes with n = 6 m + 1 variables;
- design (seed 003) fitness: 1.1e-4 s per design and unit task (2000 designs of peg_in_hole and
  task1: 0.66 s, 1.83 s), 6 kB per design-unit in a batch; GA population 200;
- sweep case: one co-simulated replay (above) plus 0.5 s of per-case set-up (tiny-ch4's 4 cases).
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass

import numpy as np

from qmt_drake.config.registry import hand_entry
from qmt_drake.errors import QmtInputError

GIB = 1024 ** 3
MEMORY_BUDGET_BYTES = 4 * GIB  # the stated budget: a run may use at most this much memory
TIME_BUDGET_S = 4 * 3600.0  # ... and at most this long (wall, on the cores it uses)
ANNOUNCE_S = 10.0  # runs estimated longer than this print their estimate first

CHECK_S_PER_SAMPLE = 1.3e-6
CHECK_BYTES_PER_SAMPLE_JOINT = 150.0
GA_S_PER_EVAL = 1.0e-4
GA_S_PER_SAMPLE = 2.5e-7
SIM_S_PER_STEP = 1.5e-4
SIM_BYTES_PER_STEP = 4.8e3
SIM_BASE_BYTES = 150e6
TRAY_S_PER_SIM_S = 0.5
TRAY_BYTES_PER_SIM_S = 1e6
TRAY_TIME_STEP_S = 1e-3  # tray/cosim.py TIME_STEP_S
ENERGY_S_PER_START_M5 = 0.17
ENERGY_M_EXPONENT = 3.3
ENERGY_S_PER_EVAL = 1.1e-3
ENERGY_S_PER_DIVISION = 3.7e-6
ENERGY_BYTES_PER_DIVISION = 2.4e3
DESIGN_S_PER_DESIGN_UNIT = 1.1e-4
DESIGN_BYTES_PER_DESIGN_UNIT = 6e3
DESIGN_POPULATION = 200
DESIGN_GRID = 126976  # design.search.reduced_grid(): designs of one type in the exhaustive search
SWEEP_CASE_OVERHEAD_S = 0.5


@dataclass(frozen=True)
class Estimate:
    """Memory [bytes] and wall time [s] of one run; `what` names the sizes, `fix` how to shrink them."""
    bytes: float
    seconds: float
    what: str
    fix: str

    def describe(self) -> str:
        return f"~{fmt_bytes(self.bytes)} and ~{fmt_seconds(self.seconds)}"


@dataclass(frozen=True)
class ReplayCost:
    """What a hand's co-simulation costs per plant step: s_per_step [s of wall time] and
    bytes_per_step [B] on top of SIM_BASE_BYTES; default_step_s [s]: its plant step when none is
    asked. Each hand plug-in carries one (hands.HandPlugin.replay_cost)."""
    default_step_s: float
    s_per_step: float
    bytes_per_step: float


MAGNET_REPLAY = ReplayCost(2e-3, SIM_S_PER_STEP, SIM_BYTES_PER_STEP)
# measured per simulated second at the servos' 1 ms step: per step at that step
# spatial arms (sim/spatial_cosim.py, 1 ms SAP plant, any hand and actuator): `qmt-drake simulate ur5-suction-bins
# (or panda-tray-cup) --method toppra --time-scale 3 [--actuator dc_motor]` prints real-time factors 1.49-1.95,
# 0.51-0.67 s of wall time per simulated second with the diagram's build; 0.8 ms a step keeps a margin for a busy
# machine. The per-step logs (arm state, plan, motor currents: 5 n doubles) stay under 1 kB a step
SPATIAL_REPLAY = ReplayCost(1e-3, 0.8e-3, 1e3)
TRAY_REPLAY = ReplayCost(TRAY_TIME_STEP_S, TRAY_S_PER_SIM_S * TRAY_TIME_STEP_S, TRAY_BYTES_PER_SIM_S * TRAY_TIME_STEP_S)


def fmt_bytes(b: float) -> str:
    for unit, size in (("TiB", 1024 ** 4), ("GiB", GIB), ("MiB", 1024 ** 2)):
        if b >= size:
            return f"{b / size:.3g} {unit}"
    return f"{b / 1024:.3g} KiB"


def fmt_seconds(s: float) -> str:
    if s >= 86400 * 365:
        return f"{s / (86400 * 365):.3g} years"
    for unit, size in (("days", 86400), ("h", 3600), ("min", 60)):
        if s >= size:
            return f"{s / size:.3g} {unit}"
    return f"{s:.2g} s"


def physical_memory_bytes() -> float:
    """This machine's RAM (inf if unknown)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def check_budget(est: Estimate, *, allow_large: bool = False, memory_bytes: float = MEMORY_BUDGET_BYTES,
                 time_s: float = TIME_BUDGET_S) -> Estimate:
    """Refuse `est` over the budget (one-line QmtInputError with the estimate and the fix) unless
    allow_large; refuse memory beyond this machine's RAM always. Call `announce(est)` once every
    other input is checked (a refused command prints one line only)."""
    ram = physical_memory_bytes()
    if not (est.bytes <= ram):
        raise QmtInputError(f"{est.what} needs {est.describe()}: more memory than this machine has "
                            f"({fmt_bytes(ram)}), even with --allow-large; {est.fix}")
    if not allow_large and not (est.bytes <= memory_bytes and est.seconds <= time_s):
        raise QmtInputError(f"{est.what} needs {est.describe()}, over the budget of "
                            f"{fmt_bytes(memory_bytes)} and {fmt_seconds(time_s)}; {est.fix}, or add "
                            "--allow-large to run it anyway")
    return est


def announce(*estimates: Estimate, stream=None) -> None:
    """Print the estimates of a long run (above ANNOUNCE_S) on stderr before it starts."""
    for est in estimates:
        if est.seconds > ANNOUNCE_S:
            print(f"qmt-drake: estimate: {est.what} needs {est.describe()}", file=stream or sys.stderr,
                  flush=True)


def _f(x) -> float:
    """A size as a float (huge integers stay finite as inf rather than overflowing)."""
    try:
        return float(x)
    except OverflowError:
        return math.inf


# ------------------------------------------------------------------------------ per quantity
def check_rate_estimate(rate_hz: float, motion_time_s: float, n_dof: int, what: str = "check rate") -> Estimate:
    """The limit re-check of one trajectory sampled at `rate_hz` over `motion_time_s` (plan.recheck,
    calibrated above: 1.3 us and 150 B per sample and joint)."""
    n = _f(rate_hz) * _f(motion_time_s)
    return Estimate(n * CHECK_BYTES_PER_SAMPLE_JOINT * max(1, n_dof), n * CHECK_S_PER_SAMPLE,
                    f"{what} {_f(rate_hz):g} Hz over {_f(motion_time_s):g} s ({n:.3g} samples)",
                    "lower the rate (the thesis checks at 1e4 Hz)")


def ga_estimate(population: int, generations: int, *, plan_rate_hz: float, motion_time_s: float,
                n_dof: int, n_genes: int = 3, bits_per_gene: int = 12) -> Estimate:
    """A GA of population x generations fitness evaluations (an upper bound: repeated chromosomes
    are cached), each sampling the motion at the plan rate (0.1 ms + 0.25 us per sample)."""
    p, g = _f(population), _f(generations)
    samples = _f(plan_rate_hz) * _f(motion_time_s)
    seconds = p * g * (GA_S_PER_EVAL + GA_S_PER_SAMPLE * samples)
    mem = p * (n_genes * bits_per_gene * 8 + 200) * 4 + samples * CHECK_BYTES_PER_SAMPLE_JOINT * max(1, n_dof)
    return Estimate(mem, seconds, f"a GA of population {p:g} x {g:g} generations",
                    "use fewer generations (--generations, or a stall limit) or a smaller population")


# the spatial GA (planners/spatial_methods.plan_ga_spatial, tight timing), measured on the UR5 suction task:
# 3.2-4.2 ms per candidate at population 40 (150 generations in 19-25 s, studies/spatial_ga_seeds), 2.4 ms at
# 1000 and 4000; peak RSS 0.39 / 0.42 / 0.42 GiB at population 40 / 1000 / 4000 (`/usr/bin/time -f %M qmt-drake
# plan ur5-suction-bins --method ga --option population=N --generations 2`; candidates are evaluated in
# batches of 50), the GA's own arrays a few kB a candidate
SPATIAL_GA_S_PER_EVAL = 4e-3
SPATIAL_GA_BASE_BYTES = 450e6
SPATIAL_GA_BYTES_PER_CANDIDATE = 1e4


def spatial_ga_estimate(population: int, generations: int) -> Estimate:
    """A spatial GA of population x generations candidates (an upper bound: repeats are cached and the
    stall rule may stop it early), its memory the batch of one generation."""
    p, g = _f(population), _f(generations)
    return Estimate(SPATIAL_GA_BASE_BYTES + p * SPATIAL_GA_BYTES_PER_CANDIDATE, p * g * SPATIAL_GA_S_PER_EVAL,
                    f"a spatial GA of population {p:g} x {g:g} generations",
                    "use fewer generations (--generations, or --stall) or a smaller population (--option population=N)")


def replay_estimate(time_scale: float, motion_time_s: float, time_step_s: float | None = None, *,
                    cost: ReplayCost = MAGNET_REPLAY) -> Estimate:
    """One co-simulated replay of a motion of `motion_time_s` stretched by `time_scale`, priced by
    the hand's `cost` (the magnet arm: 0.15 ms and 4.8 kB per plant step, default 2 ms; the tray:
    0.5 s and 1 MB per simulated second at its 1 ms step, proportionally more at a smaller step)."""
    sim_s = _f(time_scale) * _f(motion_time_s)
    if time_step_s is None:
        time_step_s = cost.default_step_s
    steps = sim_s / _f(time_step_s)
    seconds, mem = steps * cost.s_per_step, SIM_BASE_BYTES + steps * cost.bytes_per_step
    return Estimate(mem, seconds, f"a replay at time scale {_f(time_scale):g} ({sim_s:.3g} s simulated, "
                    f"step {_f(time_step_s) * 1e3:g} ms)",
                    "use a time scale near 1 (0.5-5 covers the thesis's studies) or a larger step")


def fourier_estimate(m: int, divisions: int, *, starts: int = 8, n_joints: int = 3) -> Estimate:
    """The energy-time planner (seed 001): `starts` SNOPT solves over 2 m n_joints + 1 variables; per
    start 0.17 s at m = 5, growing as m^3.3, times the objective's cost per evaluation at
    `divisions` (1.1 ms + 3.7 us per division); memory 2.4 kB per division plus the solver's
    dense 8 n^2-byte matrices (x 4)."""
    m, d = max(_f(m), 0.0), max(_f(divisions), 0.0)
    n = 2 * m * n_joints + 1
    per_eval = (ENERGY_S_PER_EVAL + ENERGY_S_PER_DIVISION * d) / (ENERGY_S_PER_EVAL + ENERGY_S_PER_DIVISION * 40)
    seconds = starts * ENERGY_S_PER_START_M5 * (m / 5) ** ENERGY_M_EXPONENT * per_eval
    mem = d * ENERGY_BYTES_PER_DIVISION + 4 * 8 * n * n
    return Estimate(mem, seconds, f"the energy-time plan with m = {m:g} Fourier terms and {d:g} time "
                    f"divisions ({starts} starts)",
                    "use --m up to ~20 and --divisions up to a few thousand (the paper: m = 5, 40)")


def design_estimate(*, method: str, types: int, units: int, generations: int = 400,
                    workers: int = 1, population: int = DESIGN_POPULATION) -> Estimate:
    """The structural design search (seed 003): every type's GA of population x generations designs
    (an upper bound: seen designs are cached), or the exhaustive grid of 126976 designs per type;
    1.1e-4 s per design and unit task, `workers` types at a time."""
    designs = DESIGN_GRID if method == "exhaustive" else _f(population) * _f(generations)
    seconds = _f(types) * designs * _f(units) * DESIGN_S_PER_DESIGN_UNIT / max(1, min(workers, types))
    batch = 2000 if method == "exhaustive" else _f(population)
    mem = batch * _f(units) * DESIGN_BYTES_PER_DESIGN_UNIT * max(1, min(workers, types))
    what = (f"the exhaustive design search ({types} types x {DESIGN_GRID} designs x {units} unit tasks)"
            if method == "exhaustive" else
            f"the design GA ({types} type(s) x at most {_f(generations):g} generations x {units} unit tasks)")
    return Estimate(mem, seconds, what, "use fewer generations (--generations MAX,STALL), fewer "
                    "types (--types) or fewer unit tasks")


def sweep_estimate(cases: int, per_case: Estimate, *, workers: int = 1, plans: Estimate | None = None) -> Estimate:
    """A sweep: `cases` replays of `per_case` (plus 0.5 s set-up each) on `workers` processes, after
    the plans (`plans`, one after another)."""
    w = max(1, int(workers))
    seconds = _f(cases) * (per_case.seconds + SWEEP_CASE_OVERHEAD_S) / min(w, max(1.0, _f(cases)))
    mem = per_case.bytes * min(w, max(1.0, _f(cases)))
    if plans is not None:
        seconds += plans.seconds
        mem = max(mem, plans.bytes)
    what = f"a sweep of {_f(cases):g} cases on {w} worker(s) (each {per_case.what})"
    fix = "narrow the grid or lower monte_carlo.cases"
    if per_case.bytes > MEMORY_BUDGET_BYTES or per_case.seconds > TIME_BUDGET_S:
        fix = per_case.fix
    if plans is not None:
        what += f" after its plans ({plans.what})"
        if plans.bytes > MEMORY_BUDGET_BYTES or plans.seconds > TIME_BUDGET_S:
            fix = plans.fix.replace("--generations, or a stall limit", "the plan's options.max_generations")
    return Estimate(mem, seconds, what, fix)


def motion_time_bound_s(scenario) -> float:
    """An upper bound of a scenario's motion time before planning: the sum of the upper bounds of
    its time genes (names starting with T)."""
    fam = scenario.family
    total = sum(float(hi) for name, (lo, hi) in zip(fam.gene_names, fam.gene_bounds) if str(name).startswith("T"))
    return total if total > 0 else 10.0


def scenario_estimates(scenario, *, generations: int | None = None, method: str = "ga") -> list[Estimate]:
    """What planning on `scenario` will cost: the GA (with its population, generations and plan
    rate; only for method ga) and the independent re-check at the check rate."""
    T = motion_time_bound_s(scenario)
    n_dof = int(len(scenario.limits.motor_torque_limit_Nm))  # one motor per joint
    out = [check_rate_estimate(scenario.sampling.check_rate_hz, T, n_dof, "sampling.check_rate_hz"),
           check_rate_estimate(scenario.sampling.plan_rate_hz, T, n_dof, "sampling.plan_rate_hz")]
    if method == "ga":
        out.append(ga_estimate(scenario.ga.population,
                               generations if generations is not None else scenario.ga.max_generations,
                               plan_rate_hz=scenario.sampling.plan_rate_hz, motion_time_s=T, n_dof=n_dof,
                               n_genes=len(scenario.family.gene_names), bits_per_gene=scenario.ga.bits_per_gene))
    return out


# --------------------------------------------------------------------- for the commands' checks
def check_plan_budget(scenario, method: str, generations: int | None = None, *,
                      allow_large: bool = False) -> list[Estimate]:
    """`qmt-drake plan`: the scenario's rates and (method ga) its GA, before planning."""
    return [check_budget(e, allow_large=allow_large)
            for e in scenario_estimates(scenario, generations=generations, method=method)]


def check_replay_budget(scenario, time_scale: float, time_step_s: float | None = None, *,
                        motion_time_s: float | None = None, allow_large: bool = False) -> Estimate:
    """`qmt-drake simulate`: the replay at `time_scale` (motion time: the plan's, or before planning
    the scenario's bound), before planning and simulating."""
    T = motion_time_s if motion_time_s is not None else motion_time_bound_s(scenario)
    return check_budget(replay_estimate(time_scale, T, time_step_s, cost=hand_entry(scenario).replay_cost),
                        allow_large=allow_large)


def check_energy_budget(m: int, divisions: int, *, starts: int = 8, allow_large: bool = False) -> Estimate:
    """`qmt-drake plan ohsaka-*`: the Fourier order and time divisions, before any solve."""
    return check_budget(fourier_estimate(m, divisions, starts=starts), allow_large=allow_large)


def check_ga_runs_budget(scenario, runs: int, generations: int, *, allow_large: bool = False) -> Estimate:
    """`qmt-drake bench` / `benchmark`: `runs` GA runs of `generations` on `scenario`, before the first."""
    (g,) = [e for e in scenario_estimates(scenario, generations=generations) if e.what.startswith("a GA")]
    return check_budget(Estimate(g.bytes, g.seconds * _f(runs), f"{_f(runs):g} runs of {g.what}",
                                 "use fewer seeds (--seeds / --ga-seeds)"), allow_large=allow_large)


# ------------------------------------------------------------ spatial scenario sizes, at load
# Sizes a spatial scenario file sets, refused at load before any IK or planning (spatial_task.py), each cap
# from a measurement on this machine (2026-11-26, shared, `studies/bad_inputs_table.py` prints the refusals):
# - the suction grip polyhedron (limits/suction.GripModel, qhull over rim_points x pyramid_edges contact
#   generators): 8x4 0.04 s, 16x16 2.2 s, 32x8 3.6 s, 8x32 3.6 s, 24x32 34 s, 8x64 28 s to build, and qhull
#   fails outright at 64x4 and 16x64: at most 256 generators, each count at most 32;
# - transfer_points (one IK solve each, then every planner's path): 100 points 1.8 s, 400 points 6.8 s to load;
# - check_rate_hz: a UR5 Ruckig plan of a 3.74 s motion took 5 s at 200 Hz, 24 s at 2 kHz, 260 s at 20 kHz
#   (the re-check samples at 10x): above 2e4 Hz a plan takes over 5 minutes;
# - task poses: each one an IK solve and a segment of every planner (the shipped tasks have 4).
SPATIAL_MAX_GRIP_GENERATORS = 256
SPATIAL_MAX_GRIP_COUNT = 32
SPATIAL_MAX_TRANSFER_POINTS = 1000
SPATIAL_MAX_CHECK_RATE_HZ = 2e4
SPATIAL_MAX_TASK_POSES = 100


def check_spatial_sizes(where: str, *, rim_points: int | None = None, pyramid_edges: int | None = None,
                        transfer_points: int = 0, check_rate_hz: float = 0.0, task_poses: int = 0) -> None:
    """One line for a spatial scenario's size over its cap (above), naming the key and the fix."""
    if rim_points is not None and pyramid_edges is not None and rim_points * pyramid_edges > SPATIAL_MAX_GRIP_GENERATORS:
        raise QmtInputError(f"{where}: hand.rim_points x pyramid_edges = {rim_points} x {pyramid_edges} contact "
                            f"generators, over {SPATIAL_MAX_GRIP_GENERATORS} (the grip polyhedron's hull takes seconds "
                            "to minutes, or fails); use e.g. 8 x 4 (the shipped grip)")
    for key, v, cap, fix in (("transfer_points", transfer_points, SPATIAL_MAX_TRANSFER_POINTS, "5-50 points draw a line"),
                             ("check_rate_hz", check_rate_hz, SPATIAL_MAX_CHECK_RATE_HZ,
                              "200 Hz is the shipped rate (the re-check samples at 10x)"),
                             ("poses_m", task_poses, SPATIAL_MAX_TASK_POSES, "split the task into several scenarios")):
        if v > cap:
            raise QmtInputError(f"{where}: {key} {v:g} is over the cap of {cap:g} (each costs planning time: "
                                f"budgets.py); {fix}")


def path_time_lower_bound_s(q_path_rad, velocity_limit_rad_s) -> float:
    """A lower bound of any motion time along a joint path [s] (before planning): every segment takes at
    least its largest joint step over that joint's speed limit."""
    dq = np.abs(np.diff(np.asarray(q_path_rad, float), axis=0)) / np.asarray(velocity_limit_rad_s, float)
    return float(dq.max(axis=1).sum()) if dq.size else 0.0
