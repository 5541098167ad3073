"""retime_path's inputs an outsider can get wrong (session 17): a CSV time column out of order, a boolean
read as 1 rad, a GA over the budget accepted only with allow_large, a scenario given by name or of the
wrong kind: each refused in one line before any timing (or, where valid, reaching the timing)."""

import numpy as np
import pytest

from qmt_drake import retime
from qmt_drake.errors import QmtInputError
from qmt_drake.retime import retime_path
from tests.test_retime import HAND_PATH, NAMES, joint_trajectory, sc  # noqa: F401 (sc: the module's fixture)


class Reached(Exception):
    """The timing was reached (every check passed)."""


@pytest.fixture
def no_timing(monkeypatch):
    def reached(*a, **k):
        raise Reached
    monkeypatch.setattr(retime, "_retime_toppra", reached)
    monkeypatch.setattr(retime, "plan_ga_spatial", reached)


def _csv(path, header, rows) -> str:
    path.write_text("\n".join([",".join(header)] + [",".join(str(v) for v in r) for r in rows]) + "\n")
    return str(path)


def test_csv_time_column_must_rise_as_yaml_times_must(sc, tmp_path, no_timing):  # noqa: F811
    t = [0.0, 1.0, 0.5, 2.0, 3.0]
    bad = _csv(tmp_path / "a.csv", ["time_s", *NAMES], [[ti, *q] for ti, q in zip(t, HAND_PATH)])
    with pytest.raises(QmtInputError, match=r"column time_s does not rise at waypoint 2 \(1 s then 0.5 s\)"):
        retime_path(sc, bad)
    text = _csv(tmp_path / "b.csv", ["time_s", *NAMES], [["x" if k == 1 else k, *q] for k, q in enumerate(HAND_PATH)])
    with pytest.raises(QmtInputError, match=r"column time_s holds a value that is not a time \('x'\)"):
        retime_path(sc, text)
    good = _csv(tmp_path / "c.csv", [*NAMES, "time_s"], [[*q, k] for k, q in enumerate(HAND_PATH)])
    with pytest.raises(Reached):  # a rising time column is read and ignored
        retime_path(sc, good)


def test_boolean_positions_are_refused(sc, no_timing):  # noqa: F811
    msg = joint_trajectory(NAMES, HAND_PATH)
    msg["points"][1]["positions"][0] = True  # YAML `true`: float() made it 1 rad
    with pytest.raises(QmtInputError, match=r"waypoint 1 has a value that is not a number"):
        retime_path(sc, msg)
    with pytest.raises(QmtInputError, match=r"joint path: a ndarray of ragged rows, text or booleans; give a \(K, 6\) array of numbers"):
        retime_path(sc, np.ones((3, 6), bool))


def test_ga_over_the_budget_runs_only_with_allow_large(sc, no_timing):  # noqa: F811
    with pytest.raises(QmtInputError, match=r"spatial GA .* over the budget.*allow_large=True"):
        retime_path(sc, HAND_PATH, "ga", generations=10 ** 8)
    with pytest.raises(Reached):
        retime_path(sc, HAND_PATH, "ga", generations=10 ** 8, allow_large=True)
    with pytest.raises(QmtInputError, match=r"allow_large 'yes' must be True or False"):
        retime_path(sc, HAND_PATH, "ga", allow_large="yes")
    with pytest.raises(QmtInputError, match=r"retime_path option population 1 must be >= 2"):
        retime_path(sc, HAND_PATH, "ga", population=1)
    with pytest.raises(QmtInputError, match=r"unknown keyword 'family'"):  # the via-cubic family is retime's own
        retime_path(sc, HAND_PATH, "ga", family="bspline")
    with pytest.raises(QmtInputError, match=r"'generations' is a GA option; drop it for method toppra"):
        retime_path(sc, HAND_PATH, generations=5)


@pytest.mark.parametrize("name, needle", [("thesis-ch4", r"retime_planar_path"),
                                          ("ohsaka-fig3", r"energy-time .*transfer_scenario_of"),
                                          (3, r"scenario 3 is not a spatial scenario")])
def test_scenario_of_another_kind_is_refused_by_name(name, needle, no_timing):
    with pytest.raises(QmtInputError, match=needle):
        retime_path(name, HAND_PATH)
