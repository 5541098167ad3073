"""Seed 002 study (studies/crane_tray.py): the seed's two runs (P-only + linear spacing, PID + eased
spacing) of the CRANE-X7 tray transfer through the co-simulation, and what is read from a run
(event windows, the friction each phase needs, carried or not)."""

from __future__ import annotations

from qmt_drake.systems.dynamixel_servo import SEED_GAINS_AFTER, SEED_GAINS_BEFORE
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.tray.cosim import required_friction, simulate_tray
from qmt_drake.tray.waypoints import seed_motion

CASES = {"before": (1.0, SEED_GAINS_BEFORE, "P-only (800), linear spacing (eq. 14)"),
         "after": (1.5, SEED_GAINS_AFTER, "PID (1000/1040/1000, I 150, D 200/250/200), eased p=1.5 (eq. 15)")}


SETTLE_S = 1.0


# the seed's measured tool angle at the start (section 7): the tray at rest is this far off level
SEED_REST_TILT_RAD = 0.0168


def run(case: str, *, mu: float = 0.3, period_s: float = 1e-3, exponent=None, gains=None, com_height=None,
        recording=None):
    e, g, _ = CASES[case]
    bottle = BottleSpec.pet_500ml(friction=mu)
    if com_height is not None:
        bottle = bottle.with_com_height(com_height)
    sched = seed_motion(e if exponent is None else exponent, settle_s=SETTLE_S)
    return simulate_tray(sched, g if gains is None else gains, bottle, servo_period_s=period_s,
                         recording_path=recording)


def event_windows(phases: dict) -> dict:
    """Named time windows [s] around the run's events (starts and stops of the goal stream)."""
    m0, m1 = phases["move"]
    r0, r1 = phases["return"]
    return {"line start": (m0, m0 + 0.5), "line": (m0 + 0.5, m1), "arrival": (m1, m1 + 1.0), "hold": (m1 + 1.0, r0),
            "return start": (r0, r0 + 0.5), "return": (r0 + 0.5, r1), "return end": (r1, r1 + 1.0)}


def phase_mu(r) -> dict:
    return {ev: required_friction(r.series, a, b) for ev, (a, b) in event_windows(r.phases).items()}


def carried_ok(r) -> bool:
    return r.outcome == "on_tray" and not r.slipped


def fill_bottle(water_kg: float, mu: float) -> BottleSpec:
    """The assumed PET bottle (20 g shell) with `water_kg` of water: fill sets mass and COM height."""
    return BottleSpec.pet_500ml(mass_kg=0.020 + water_kg, friction=mu)
