"""The spatial contact hand (sim/spatial_contact_hand.py, `hand.physics: contact`) against closed forms.

The UR5 holds its start pose (hand face down) or swings its base joint bang-bang; the part is a free body
held only by point contacts and the pull. Closed forms: the part stays when the pull exceeds its
weight m g (and then presses the rim in by (F - m g) / k), drops when the pull is below it; on a part
whose centre of mass sits at the face (no tipping) the rim's friction holds it up to the lateral hand
acceleration mu (F - m g) / m and lets it slide beyond.
"""

import dataclasses

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.contact_wrench import CarriedBody
from qmt_drake.limits.suction import GripModel
from qmt_drake.sim.contact_hand_build import (
    MAGNET_COIL,
    RIM_STIFFNESS_N_PER_M,
    magnet_spec,
)
from qmt_drake.sim.magnet_hand import MAGNET_EFFECTIVE_GAP_M
from qmt_drake.sim.spatial_cosim import simulate_spatial
from qmt_drake.spatial_task import load_spatial_scenario
from qmt_drake.systems.electromagnet import THESIS_COILS, MagnetParams
from tests.scenario_files import SCENARIO_DIR
from tests.spatial_fixtures import edited_copy, load_or_skip


class Motion:
    """A spatial_trajectory-kind plan: rest at q0 for duration_s, or (accel) a bang-bang swing of the
    base joint: +accel rad/s^2 for half the time, -accel for the other half (ends at rest)."""

    def __init__(self, q0, duration_s: float, accel: float = 0.0) -> None:
        self.q0, self.duration_s, self.accel = np.asarray(q0, float), duration_s, accel

    def sample(self, t):
        t = np.atleast_1d(np.asarray(t, float))
        h = self.duration_s / 2
        up, down = np.minimum(t, h), np.clip(t - h, 0.0, h)
        a = self.accel
        s = 0.5 * a * up ** 2 + a * h * down - 0.5 * a * down ** 2
        v = a * up - a * down
        acc = np.where(t < h, a, -a)
        q = np.tile(self.q0, (len(t), 1))
        qd, qdd = np.zeros_like(q), np.zeros_like(q)
        q[:, 0] += s
        qd[:, 0], qdd[:, 0] = v, acc
        return q, qd, qdd


@pytest.fixture(scope="module")
def suction():
    return dataclasses.replace(load_or_skip("ur5-suction-bins"), hand_physics="contact")


@pytest.fixture(scope="module")
def magnet():
    return dataclasses.replace(load_or_skip("ur5-magnet-part"), hand_physics="contact")


def _grip(sc, pull_N):
    return GripModel(sc.grip.radius_m, pull_N, sc.grip.friction, face_normal=sc.grip.basis[2], rim_points=24)


def test_suction_holds_above_weight_and_drops_below(suction):
    w = suction.body.mass_kg * 9.81  # face down at the start: the whole weight pulls the part off the cup
    held = simulate_spatial(suction, Motion(suction.q_path_rad[0], 0.2), grip=_grip(suction, 1.05 * w))
    assert held["outcome"] == "carried" and held["max_slide_m"] < 1e-5
    # at rest the rim carries F - m g: pressed in by (F - m g) / k (the gap is negative, a penetration)
    assert held["final_gap_m"] == pytest.approx(-0.05 * w / RIM_STIFFNESS_N_PER_M, rel=0.02)
    dropped = simulate_spatial(suction, Motion(suction.q_path_rad[0], 0.2), grip=_grip(suction, 0.95 * w))
    assert dropped["outcome"] == "detached" and dropped["lost_at_s"] < 0.2


def test_magnet_pull_is_the_calibrated_force_and_holds_only_above_weight(magnet):
    spec = magnet_spec(magnet)
    w = magnet.body.mass_kg * 9.81
    # the calibration's closed form: (F - m g) min(rho, mu r_G) = the scenario's moment limit
    pull = w + magnet.moment_limit_Nm / min(spec.contact_radius_m, spec.friction * 0.028)
    held = simulate_spatial(magnet, Motion(magnet.q_path_rad[0], 0.2))
    assert held["pull_N"] == pytest.approx(pull, rel=1e-3)
    assert held["outcome"] == "carried" and abs(held["final_gap_m"]) < 1e-6 and held["max_slide_m"] < 1e-6
    motors = simulate_spatial(magnet, Motion(magnet.q_path_rad[0], 0.2), actuator="dc_motor")  # no continuous state
    assert motors["outcome"] == "carried" and motors["pull_N"] == held["pull_N"]
    params = MagnetParams(THESIS_COILS[MAGNET_COIL], MAGNET_EFFECTIVE_GAP_M, spec.face_radius_m)
    weak = simulate_spatial(magnet, Motion(magnet.q_path_rad[0], 0.2),
                            contact={"coil_current_A": params.current_for_force_A(0.9 * w)})
    assert weak["pull_N"] == pytest.approx(0.9 * w, rel=1e-9) and weak["outcome"] == "detached"


def test_suction_slides_beyond_the_friction_limit(suction):
    # centre of mass 2 mm from the face: tipping needs (F - m g) r / (m h) = 76 m/s^2, far above sliding
    sc = dataclasses.replace(suction, body=CarriedBody(2.0, np.array([0.0, 0.0, 0.002]), np.diag([6e-3, 6e-3, 4e-3])))
    pull, mu, m = sc.grip.pull_force_N, sc.grip.friction, sc.body.mass_kg
    a_slide = mu * (pull - m * 9.81) / m  # m/s^2, the rim's friction limit on the lateral acceleration
    q0 = sc.q_path_rad[0]
    zero = np.zeros((1, sc.n_dof))
    unit = zero.copy()
    unit[0, 0] = 1.0
    a_per_alpha = np.linalg.norm(sc.chain.evaluate(q0[None], zero, unit)["linear_acceleration_m_s2"][0])
    h, runs = 0.08, {}  # s, each half of the swing
    for f in (0.9, 1.3):  # the hand's tangential acceleration over the friction limit
        runs[f] = simulate_spatial(sc, Motion(q0, 2 * h, f * a_slide / a_per_alpha), grip=_grip(sc, pull))
    assert runs[0.9]["outcome"] == "carried" and runs[0.9]["max_slide_m"] < 1e-4
    # beyond: the part lags at (f - 1) a_slide for h, then closes on the decelerating hand at (f + 1) a_slide:
    # the largest slide a_slide h^2 (f - 1) f / (f + 1) (the centripetal part, 8 % of the tangential, neglected)
    f = 1.3
    assert runs[f]["max_slide_m"] == pytest.approx(a_slide * h ** 2 * (f - 1) * f / (f + 1), rel=0.1)


def test_hand_physics_parse_and_refusal(tmp_path):
    src = SCENARIO_DIR / "ur5-magnet-part.yaml"
    ok = edited_copy(src, tmp_path, lambda raw: raw["hand"].update(physics="contact"))
    try:
        assert load_spatial_scenario(ok).hand_physics == "contact"
    except QmtInputError as exc:
        if "example-robot-data" in str(exc):
            pytest.skip(str(exc))
        raise
    bad = edited_copy(src, tmp_path, lambda raw: raw["hand"].update(physics="glue"))
    with pytest.raises(QmtInputError, match=r"hand\.physics 'glue' is not one of weld, contact"):
        load_spatial_scenario(bad)
