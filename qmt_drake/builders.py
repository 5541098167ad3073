"""Builders: a scenario (plain data) turned into the numpy and Drake objects planners and the
co-simulation use. One builder for each thing: the arm model, the limit set, the tray's bottle.

Transitional façade: today these read the scenario's cached properties; the one-stack work (issue 18)
moves the implementations here so that the scenario imports nothing above it. Call these, not the
scenario's attributes, from new code.
"""

from __future__ import annotations


def build_arm(scenario):
    """The scenario's ArmModel (URDF chain with the carried body's inertia on the hand), built once
    per scenario object."""
    return scenario.arm


def build_limit_set(scenario):
    """The scenario's LimitSet (payload / tray / suction terms, motor torques, joint speeds and
    ranges), built once per scenario object."""
    return scenario.limit_set


def build_bottle(scenario):
    """Tray scenarios: the BottleSpec of the payload and the tray hand; None for other hands."""
    return scenario.bottle
