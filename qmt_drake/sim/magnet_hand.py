"""The magnet hand in the co-simulation: coil current calibration and the magnet's wiring.

Everything comes from the scenario's typed `hand` section (scenario.MagnetHand): the coil
(a THESIS_COILS entry or explicit data), how the current is set (given, or calibrated from the
thesis's slip boundary), the effective gap g0 and the contact data (which `PayloadSpec.for_scenario`
reads).

Calibration (`calibrated_coil_current_A`): seed 000 does not report the coil current or voltage.
One rule is applied to both hands: the coil current is the one whose quasi-static hold limit equals
the geometric mean of the thesis's last-success and first-failure moments (Table 2.3:
3.168e-5 / 3.344e-5 N*m; Table 4.2: 0.633e-3 / 0.727e-3 N*m, the scenarios' hand.slip_boundary_Nm):

    tau_hold = (F(I, 0) - m g) * min(rho, mu * r_G)

(the part tips about the edge of the contact ring of radius rho when m a r_G exceeds the net
normal force times rho, or slides when m a exceeds mu times it). The simulated thresholds are then
an outcome of the dynamics, checked by studies/cosim_calibration.py against every row of both
tables (ch.2 between 3.2245e-5 and 3.2273e-5 N*m, ch.4 between 0.640e-3 and 0.641e-3 N*m at the
default 2 ms step, all 14 rows as in the thesis; ch.4 sits 1% above its lower boundary because the
moving arm tips the part earlier than the static bound). The two calibrated currents cannot come
from one supply voltage: the ch.2 coil would need 0.41 of the ch.4 coil's voltage
(out/cosim_calibration.json, shared_voltage_counterfactual).

g0 = 0.5 mm (hand.effective_gap_m) is assumed, not measured; it sets how fast the pull fades once
the part tips, i.e. how surely a tipped part falls.
"""

from __future__ import annotations

import math

from pydrake.systems.primitives import ConstantVectorSource

from qmt_drake.config.scenario import MagnetHand
from qmt_drake.errors import QmtInputError
from qmt_drake.systems.electromagnet import MagnetParams, electromagnet_force
from qmt_drake.systems.payload import PayloadSpec, payload_joint

MAGNET_EFFECTIVE_GAP_M = 0.5e-3  # g0 of the built-in scenarios' hands (hand.effective_gap_m)


def magnet_hand_of(scenario):
    """The scenario's MagnetHand, or a one-line QmtInputError saying what to add."""
    hand = getattr(scenario, "hand", None)
    if not isinstance(hand, MagnetHand):
        raise QmtInputError(f"scenario '{scenario.name}' has no 'hand' section (kind: magnet, coil, "
                            "slip_boundary_Nm or coil_current_A); add one to its YAML to co-simulate it")
    return hand


def hold_lever_m(payload: PayloadSpec) -> float:
    """min(rho, mu * r_G) [m]: net normal force times this is the quasi-static hold moment."""
    return min(payload.contact_radius_m, payload.friction * payload.com_offset_m)


def magnet_params_for(scenario, payload: PayloadSpec, effective_gap_m: float | None = None) -> MagnetParams:
    hand = magnet_hand_of(scenario)
    g0 = hand.effective_gap_m if effective_gap_m is None else effective_gap_m
    return MagnetParams(hand.coil, g0, payload.face_radius_m)


def calibrated_coil_current_A(scenario, payload: PayloadSpec, *, effective_gap_m: float | None = None,
                              boundary_Nm: tuple[float, float] | None = None) -> float:
    """The calibration rule (module docstring): coil current [A] for this scenario's hand.
    boundary_Nm overrides hand.slip_boundary_Nm (last success, first failure [N*m])."""
    hand = magnet_hand_of(scenario)
    boundary = boundary_Nm or hand.slip_boundary_Nm
    if boundary is None:
        raise QmtInputError(f"scenario '{scenario.name}': hand.slip_boundary_Nm is not set; the coil "
                            "current is hand.coil_current_A")
    lo, hi = boundary
    tau_star = math.sqrt(lo * hi)
    force = payload.mass_kg * scenario.world.g_m_s2 + tau_star / hold_lever_m(payload)
    return magnet_params_for(scenario, payload, effective_gap_m).current_for_force_A(force)


def coil_current_for(scenario, payload: PayloadSpec) -> float:
    """hand.coil_current_A if given, else the calibrated current [A]."""
    hand = magnet_hand_of(scenario)
    if hand.coil_current_A is not None:
        return float(hand.coil_current_A)
    return calibrated_coil_current_A(scenario, payload)


def add_magnet_hand(builder, plant, hand_body, payload_body, scenario, payload: PayloadSpec,
                    coil_current_A: float, effective_gap_m: float | None = None, *,
                    host_has_continuous_state: bool = False):
    """Add the electromagnet_force (the scenario's coil, g0 unless effective_gap_m [m] is given, and the
    payload's face) fed by a constant coil current [A], wired plant.state -> magnet -> plant applied
    generalized force. Needs the FINALISED plant with the payload on its joint to `hand_body`
    (sim.plant.finalize_transfer_plant); host_has_continuous_state as in electromagnet_force.
    Returns the magnet system."""
    params = magnet_params_for(scenario, payload, effective_gap_m)
    magnet = builder.AddNamedSystem("magnet", electromagnet_force(
        params, plant, payload_joint(plant, payload_body), host_has_continuous_state=host_has_continuous_state))
    coil_src = builder.AddNamedSystem("coil_current", ConstantVectorSource([float(coil_current_A)]))
    builder.Connect(plant.get_state_output_port(), magnet.GetInputPort("plant_state"))
    builder.Connect(coil_src.get_output_port(), magnet.GetInputPort("coil_current"))
    builder.Connect(magnet.GetOutputPort("generalized_force"), plant.get_applied_generalized_force_input_port())
    return magnet
