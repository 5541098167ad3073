"""Issue 27 item 6: a refusal remains only where physics makes the combination meaningless, and says so;
the other feature x kind cells of docs/features.md run (session 13, helper refusals)."""

from __future__ import annotations

import pytest

from qmt_drake.apps.commands import check_own_actuator
from qmt_drake.config.scenario import load_scenario
from qmt_drake.errors import QmtInputError


def test_planar_actuator_flag_names_the_yaml_actuator():
    thesis = load_scenario("thesis-ch4")
    check_own_actuator(thesis, None)
    check_own_actuator(thesis, "dc_motor")  # its YAML actuator: DC motors with gears
    with pytest.raises(QmtInputError, match="actuator.kind dc_motor_gear \\(--actuator dc_motor\\)"):
        check_own_actuator(thesis, "ideal")
    tray = load_scenario("crane-tray")
    with pytest.raises(QmtInputError, match="Dynamixel position servos .* firmware closes the position loop"):
        check_own_actuator(tray, "dc_motor")
