"""One Ruckig call (planners/ruckig_core.rest_to_rest): every Ruckig plan goes through it (the planar
baseline, the spatial arms, seed 002's tray line), and it gives what each caller's own Ruckig set-up gave
before (written out here with ruckig's API): the same duration and states bit for bit."""

import numpy as np
from ruckig import InputParameter, Result, Ruckig, Synchronization, Trajectory

from qmt_drake.planners.ruckig_core import RuckigProfile, rest_to_rest
from tests.test_one_toppra import _calls

CALLERS = {"planners/ruckig_core.py", "planners/spatial_ruckig.py", "tray/waypoints.py"}  # the core: rest_to_rest_profile


def test_every_ruckig_call_goes_through_the_one_core():
    for name in ("Ruckig", "InputParameter", "Trajectory"):
        assert set(_calls(name)) == {"planners/ruckig_core.py"}, (name, _calls(name))
    assert set(_calls("rest_to_rest")) == CALLERS


def _direct(start, goal, v, a, j, phase):
    """Ruckig set up as the callers did before the core."""
    n = len(start)
    inp = InputParameter(n)
    inp.current_position, inp.target_position = list(map(float, start)), list(map(float, goal))
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = list(map(float, v)), list(map(float, a)), list(map(float, j))
    if phase:
        inp.synchronization = Synchronization.Phase
    traj = Trajectory(n)
    assert Ruckig(n).calculate(inp, traj) in (Result.Working, Result.Finished)
    return traj


def _same(a, b):
    assert a.duration == b.duration
    for t in np.linspace(0.0, a.duration, 37):
        for x, y in zip(a.at_time(float(t)), b.at_time(float(t))):
            assert np.array_equal(x, y)


def test_the_core_is_each_callers_former_ruckig_call():
    rng = np.random.default_rng(3)
    for n, phase in ((1, False), (2, True), (6, False), (6, True)):
        start, goal = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
        v, a, j = rng.uniform(0.5, 2, n), rng.uniform(1, 5, n), rng.uniform(10, 50, n)
        traj, res = rest_to_rest(start, goal, v, a, j, phase_synchronization=phase)
        assert res in (Result.Working, Result.Finished)
        _same(traj, _direct(start, goal, v, a, j, phase))


def test_refused_input_is_none_with_ruckigs_reason():
    traj, res = rest_to_rest([0.0], [1.0], [1.0], [-1.0], [1.0])  # a negative acceleration limit
    assert traj is None and "maximum acceleration limit" in res


def test_the_one_evaluator_is_ruckigs_at_time_bit_for_bit():
    """planners/ruckig_core.RuckigProfile (the planar and the spatial Ruckig plans' evaluator) gives at_time's
    values exactly: at random times, at every phase switch and one ulp either side, at and after the end."""
    rng = np.random.default_rng(7)
    for trial in range(24):
        n, phase = int(rng.integers(1, 7)), bool(trial % 2)
        start, goal = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)
        if trial % 4 == 0:
            goal[0] = start[0]  # an axis that does not move
        traj, _ = rest_to_rest(start, goal, rng.uniform(0.1, 3, n), rng.uniform(0.1, 10, n), rng.uniform(0.5, 100, n),
                               phase_synchronization=phase)
        prof = RuckigProfile(traj)
        sw = prof.switch_times_s
        t = np.concatenate([rng.uniform(0, traj.duration, 50), sw, np.nextafter(sw, -1), np.nextafter(sw, 9),
                            [traj.duration * 1.01]])
        mine = np.hstack(prof.evaluate(t))
        theirs = np.array([np.concatenate(traj.at_time(float(x))) for x in t])
        assert np.array_equal(mine, theirs), (trial, np.abs(mine - theirs).max())
