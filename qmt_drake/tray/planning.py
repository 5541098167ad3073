"""The crane-tray scenario for a given bottle: what the tray planners and studies plan with.

`tray_scenario(bottle, margin, speed_fraction)` loads the built-in `crane-tray` scenario
(models/scenarios/crane-tray.yaml) with the bottle's mass, size, centre-of-mass height, friction
and ring radius, and the planning margin, so that every planner (TOPP-RA, Ruckig, the GA) and the
re-check use the same limit terms (tray/limit_terms.py) as `qmt-drake plan crane-tray`.
"""

from __future__ import annotations

from qmt_drake.config.fields import merge_overrides
from qmt_drake.systems.tray_object import BottleSpec
from qmt_drake.transfer_scenario import load_scenario


def bottle_overrides(bottle: BottleSpec, margin: float | None = None, speed_fraction: float | None = None) -> dict:
    """Scenario overrides (load_scenario's `overrides`) that describe `bottle`."""
    o = {"payload": {"mass_kg": bottle.mass_kg, "com_offset_m": bottle.com_height_m,
                     "body": {"kind": "bottle", "radius_m": bottle.radius_m, "height_m": bottle.height_m,
                              "shell_mass_kg": bottle.shell_mass_kg}},
         "hand": {"friction": bottle.friction, "contact_radius_m": bottle.contact_radius_m,
                  "n_contact_points": bottle.n_contact_points}}
    if margin is not None:
        o["hand"]["plan_margin"] = margin
    if speed_fraction is not None:
        o["limits"] = {"joint_speed_fraction": speed_fraction}
    return o


def tray_scenario(bottle: BottleSpec, margin: float | None = None, speed_fraction: float | None = None,
                  extra: dict | None = None):
    """The crane-tray Scenario carrying `bottle` (see module docstring); `extra` more overrides."""
    o = bottle_overrides(bottle, margin, speed_fraction)
    return load_scenario("crane-tray", overrides=merge_overrides(o, extra) if extra else o)
