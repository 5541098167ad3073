"""The scenario's sections as plain typed data (frozen dataclasses), and the Scenario that holds them.

Loaded and validated by config/scenario.py. Plain data only: what a scenario turns into (the arm model,
the limit set, the tray's bottle) is built above config/ (qmt_drake/transfer_scenario.TransferScenario,
with the builders of qmt_drake/builders.py), so this module imports nothing above config/ (catalogue
data aside) and calls nothing registered.
"""

from __future__ import annotations

import hashlib
import json
import numbers
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from qmt_drake.catalog import SERVO_CATALOG, CoilSpec, ServoGains
from qmt_drake.config.registry import DEFAULT_OBJECTIVE_KIND
from qmt_drake.config.simulation import NO_SIMULATION, Simulation

STANDARD_GRAVITY_M_S2 = 9.81  # the value every model here was calibrated with (and Drake's default)


@dataclass(frozen=True)
class World:
    """`world`: what every model of the scenario shares. gravity_m_s2: the gravity vector in the world
    frame [m/s^2] (z up); the planning plant, the co-simulation plant and every limit term take it
    from here."""

    gravity_m_s2: tuple[float, float, float] = (0.0, 0.0, -STANDARD_GRAVITY_M_S2)

    @property
    def g_m_s2(self) -> float:
        """|gravity| [m/s^2]."""
        return float(np.linalg.norm(self.gravity_m_s2))


@dataclass(frozen=True)
class UrdfArm:
    """arm.kind 'urdf' (the default): a serial arm read from a URDF file."""

    urdf_path: Path
    hand_frame: str = "hand"
    kind: str = "urdf"


@dataclass(frozen=True)
class PayloadBody:
    """The rigid body the co-simulation carries (sets rotational inertia and the visual; mass and
    r_G always come from the payload). A cylinder about the face normal."""

    name: str
    length_m: float  # along the face normal
    radius_m: float
    face_radius_m: float  # radius of the part's attraction face (>= the core radius)
    shell_mass_kg: float = 0.0  # kind bottle: the empty bottle (thin-walled); the rest is water


@dataclass(frozen=True)
class Payload:
    """The carried part. `com_offset_m` is r_G, attraction face to centre of mass."""

    name: str
    mass_kg: float
    com_offset_m: float
    length_m: float | None = None  # kept for old callers: body.length_m
    body: PayloadBody | None = None


class HandSection(Protocol):
    """What every hand section has: the kind its plug-in registered under (config/registry.HANDS)."""

    kind: str


@dataclass(frozen=True)
class MagnetHand:
    """hand.kind 'magnet': an iron-cored coil pulling an iron part onto its face (electromagnet.py).

    The coil current is either given (`coil_current_A`) or calibrated (`slip_boundary_Nm`: the
    thesis's last-success and first-failure peak moments; the current whose quasi-static hold
    limit is their geometric mean, sim/magnet_hand.py). Contact data: friction coefficient, the
    ring of contact points (the core end's radius), point stiffness and Hunt-Crossley dissipation."""

    coil: CoilSpec  # catalog.CoilSpec (a THESIS_COILS entry or explicit numbers)
    coil_name: str  # THESIS_COILS key, or "explicit"
    slip_boundary_Nm: tuple[float, float] | None = None
    coil_current_A: float | None = None
    effective_gap_m: float = 0.5e-3  # g0: an assumption, shared by both thesis hands
    friction: float = 0.3
    contact_radius_m: float = 3.9e-3
    n_contact_points: int = 8
    sphere_radius_m: float = 0.5e-3
    point_stiffness_N_per_m: float = 1.0e6
    hunt_crossley_dissipation_s_per_m: float = 5.0
    kind: str = "magnet"


@dataclass(frozen=True)
class DcMotorGear:
    """actuator.kind 'dc_motor_gear': one catalogue DC motor per joint (systems/dc_motor.py
    MOTOR_CATALOG keys) behind the URDF's gear ratio; `efficiency` is the gearbox's."""

    motors: tuple[str, ...]
    efficiency: float = 0.7
    kind: str = "dc_motor_gear"


@dataclass(frozen=True)
class IdealTorque:
    """actuator.kind 'ideal': the joint torque is whatever the controller asks (no motor model). The
    co-simulation then reads control.kp [N*m/rad] and control.kd [N*m*s/rad] as JOINT-side PD
    torque gains (not the thesis's motor-side volt gains; sim/actuation.add_ideal_torque_actuation)."""

    kind: str = "ideal"


@dataclass(frozen=True)
class TrayHand:
    """hand.kind 'tray' (seed 002): the payload rests unfixed on a tray held by the hand frame
    (z up when level). friction: bottle-tray Coulomb coefficient; contact_radius_m: radius of the
    ring the bottle stands on (its feet); plan_margin (0, 1]: friction and ring radius are scaled
    by it for planning (the servos lag the plan); rest_tilt_rad: the tray's tilt at rest that the
    bottle must survive (default: the seed's printed start joints sum to -0.0168 rad);
    tray_mass_kg: tray plus attachment (seed: 208 g; the URDF's tray link carries it)."""

    friction: float = 0.3
    contact_radius_m: float = 0.029
    plan_margin: float = 0.8
    rest_tilt_rad: float = 0.0168
    tray_mass_kg: float = 0.208
    n_contact_points: int = 16
    kind: str = "tray"


@dataclass(frozen=True)
class DynamixelServos:
    """actuator.kind 'dynamixel': one Dynamixel position servo per joint (systems/dynamixel_servo.py
    datasheets), firmware PID gains in control-table units, sampled every control_period_s."""

    servos: tuple[str, ...]
    p: tuple[float, ...]
    i: tuple[float, ...]
    d: tuple[float, ...]
    ff1: tuple[float, ...] = ()  # Feedforward 1st Gain (velocity), control-table units; () = 0
    ff2: tuple[float, ...] = ()  # Feedforward 2nd Gain (acceleration)
    control_period_s: float = 1e-3
    # goal stream: "plain" streams the plan; "shaped" streams the goals that make the firmware's
    # loop execute the plan (systems/servo_reference.py)
    reference: str = "plain"
    kind: str = "dynamixel"

    def gains(self) -> ServoGains:
        return ServoGains(tuple(self.p), tuple(self.i), tuple(self.d), tuple(self.ff1) or None,
                          tuple(self.ff2) or None)

    def datasheets(self) -> tuple:
        return tuple(SERVO_CATALOG[s] for s in self.servos)


@dataclass(frozen=True)
class Limits:
    """Planning limits. Moment |tau_M| = m_o * r_G * |a_tip| (eq. 2-24, 3-10, 4-33); motor torque
    is motor side (joint torque / N, eq. 2-34)."""

    moment_limit_Nm: float
    motor_torque_limit_Nm: np.ndarray
    joint_speed_fraction: float | None = None  # tray scenarios: |qd| <= fraction * URDF velocity limit


@dataclass(frozen=True)
class Task:
    points_m: np.ndarray  # (k, 2): start, vias..., goal
    tool_angle_rad: float | None
    ik_branch: str


@dataclass(frozen=True)
class Family:
    kind: str
    gene_names: tuple[str, ...]
    gene_bounds: np.ndarray  # (G, 2)


@dataclass(frozen=True)
class GaSettings:
    population: int = 50
    bits_per_gene: int = 12
    crossover_rate: float = 0.5
    mutation_rate: float = 0.05  # per bit
    max_generations: int = 10000
    fitness_c_per_s: float = 0.1  # fitness = exp(-c * T0)
    elite_count: int = 1  # 0 reproduces the thesis's plain GA
    stall_generations: int = 0  # stop when the best has not improved this long (0: never)
    # Parent selection. The thesis names "selection" without saying how; "roulette" is
    # fitness-proportional, "tournament" picks the fitter of two random individuals.
    selection: str = "roulette"
    # How 12 bits map to a level: "binary" (plain) or "gray" (reflected Gray code, where
    # neighbouring levels differ in one bit, so a one-bit mutation can always step to them).
    encoding: str = "binary"
    # Seed 003's operator: if > 0, that many individuals get one random bit flipped per
    # generation (instead of flipping each bit with mutation_rate).
    mutants_per_generation: int = 0
    # Not in the thesis: play each chromosome at the time scale that puts it exactly on its limits
    # (the family optimum's tight motion), so the GA searches the shape of the motion and never its
    # feasibility boundary. Off reproduces the thesis's GA.
    tight_timing: bool = False


@dataclass(frozen=True)
class Sampling:
    plan_rate_hz: float = 1000.0  # limit checks inside planners
    check_rate_hz: float = 10000.0  # the independent re-check of every plan written out


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    source_path: Path
    urdf_path: Path
    hand_frame: str
    payload: Payload
    task: Task
    limits: Limits
    family: Family
    ga: GaSettings
    sampling: Sampling
    control: dict = field(default_factory=dict)  # kp, ki, kd lists (one per joint), validated
    reported: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    arm_spec: UrdfArm | None = None
    # a registered hand kind's typed section (config/registry.HANDS: magnet, tray, or a plug-in's own)
    hand: MagnetHand | TrayHand | HandSection | None = None
    actuator: DcMotorGear | IdealTorque | DynamixelServos | None = None
    world: World = field(default_factory=World)
    # `uncertainty`: what a part, a hand or a servo may differ by, in the sweep spec's parameter form
    # ({friction: {dist: normal, mean: 0.3, std: 0.03}, ...}, monte_carlo: {cases, seed}); used by
    # `plan --success P` (validated there by sweep/parameters.py)
    uncertainty: dict = field(default_factory=dict)
    # `objective: {kind: ...}`: what the planners minimise, a kind registered in config/registry.OBJECTIVES
    # for transfer scenarios (problem.py: min_time, the motion time under the limits)
    objective: str = DEFAULT_OBJECTIVE_KIND
    # `simulation`: Drake's plant and simulator settings of its co-simulations (config/simulation.py); how a
    # plan is simulated, not what is planned, so no part of the fingerprint or of a plan's identity
    simulation: Simulation = NO_SIMULATION

    @property
    def moment_per_accel_kgm(self) -> float:
        """m_o * r_G: payload moment per unit tip acceleration (tray: the bottle's tipping moment
        about its base per unit horizontal tray acceleration, m h_G)."""
        return self.payload.mass_kg * self.payload.com_offset_m

    def fingerprint(self) -> str:
        """sha256 (hex) of a canonical JSON of the validated data plus the URDF file's bytes.

        Left out: where the files are (source_path, urdf_path: the URDF counts by content),
        the prose (description, notes, reported) and how a plan is co-simulated (simulation). Any edit that can change a plan or a
        simulation changes the fingerprint."""
        data = {f.name: _canonical(getattr(self, f.name)) for f in fields(self)
                if f.name not in ("source_path", "urdf_path", "description", "notes", "reported", "uncertainty",
                                  "simulation")}
        if data.get("objective") == DEFAULT_OBJECTIVE_KIND:  # the default leaves plans and checkpoints of older files valid
            del data["objective"]
        if isinstance(data.get("arm_spec"), dict):
            data["arm_spec"].pop("urdf_path", None)
        h = hashlib.sha256(json.dumps(data, sort_keys=True, separators=(",", ":")).encode())
        h.update(b"\0urdf\0")
        h.update(Path(self.urdf_path).read_bytes())
        return h.hexdigest()


def _canonical(x: Any) -> Any:
    """JSON-ready data of validated dataclasses/arrays; floats as repr strings (exact, stable)."""
    if is_dataclass(x):
        return {f.name: _canonical(getattr(x, f.name)) for f in fields(x)}
    if isinstance(x, dict):
        return {str(k): _canonical(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_canonical(v) for v in x]
    if isinstance(x, np.ndarray):
        return _canonical(x.tolist())
    if isinstance(x, Path):
        return str(x)
    if isinstance(x, bool) or x is None or isinstance(x, str):
        return x
    if isinstance(x, numbers.Integral):
        return int(x)
    if isinstance(x, numbers.Real):
        return repr(float(x))
    return repr(x)
