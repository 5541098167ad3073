"""The bang-bang reference of a transfer: the largest tip acceleration A the payload's limit allows on
a level straight line, and the time 2*sqrt(L/A) no path between two task points can beat (the tip as
a double integrator with |a| <= A, L the start-goal distance). The benchmark's rows and figures are
measured against it."""

from __future__ import annotations

import numpy as np

from qmt_drake.hands import hand_plugin


def bang_bang_acceleration_m_s2(scenario) -> float:
    """The largest tip acceleration the payload limit allows on a level straight line, m/s^2, as the
    hand's plug-in states it (hands.py): moment limit / (m_o r_G) for the magnet hand; for a tray,
    the smaller of the planning friction's mu g (no slide) and g r_c / h_G (no tip; both with the
    plan margin)."""
    return float(hand_plugin(scenario).bang_bang_acceleration_m_s2(scenario))


def closed_form_bound_s(scenario) -> float | None:
    """2*sqrt(L/A) for a task without vias (None with vias)."""
    pts = scenario.task.points_m
    if len(pts) != 2:
        return None
    return float(2 * np.sqrt(np.hypot(*(pts[1] - pts[0])) / bang_bang_acceleration_m_s2(scenario)))

