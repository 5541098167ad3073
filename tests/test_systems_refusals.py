"""The Drake systems a user composes by hand (qmt_drake/systems/) refuse bad arguments with the library's
one-line QmtInputError (the CLI's exit 2), not a bare ValueError (outsider s18's last item)."""

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.systems.joint_tracking import JointPidController, PidGains, hold_offsets


def _gains(n=2):
    return PidGains(np.ones(n), np.zeros(n), np.zeros(n))


@pytest.mark.parametrize("kwargs, needle", [
    ({"torque_feedforward": True}, "feedforward needs the motor parameters"),
    ({"feedforward_velocity_port": True}, "nothing reads it"),
    ({"current_loop": True}, "current_loop is a held law's"),
    ({"hold_period_s": 0.5e-3}, "shorter than the control period"),
])
def test_joint_pid_controller_refuses_in_one_line(kwargs, needle):
    with pytest.raises(QmtInputError, match=needle) as exc:
        JointPidController(_gains(), 100.0, 24.0, **kwargs)
    assert "\n" not in str(exc.value)


def test_hold_offsets_refuse_a_bad_mode_and_period():
    with pytest.raises(QmtInputError, match="hold compensation 'bogus'"):
        hold_offsets(4e-3, 1e-3, "bogus")
    with pytest.raises(QmtInputError, match="need 0 < step <= period"):
        hold_offsets(1e-3, 4e-3)
