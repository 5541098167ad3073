"""z = integral (c1 tau'tau + c2) dt and its exact gradient (qmt_drake/energy/objective.py)."""

import numpy as np
import pytest

from qmt_drake.energy.dynamics import drake_inverse_dynamics, ohsaka_arm
from qmt_drake.energy.fourier import FourierVelocityFamily
from qmt_drake.energy.objective import EnergyObjective
from qmt_drake.energy.problem import EnergyProblem
from qmt_drake.errors import QmtInputError


@pytest.fixture
def setup():
    fam = FourierVelocityFamily([0.0, 0.3, -0.2], 5)
    obj = EnergyObjective(fam, ohsaka_arm(), c1=1.0, c2=1e5, divisions=40)
    y = np.random.default_rng(4).normal(scale=0.5, size=fam.n_reduced)
    y[-1] = 0.4
    return fam, obj, y


def test_gradient_matches_central_differences(setup):
    fam, obj, y = setup
    x, _ = fam.reduced_to_full(y)
    z, g = obj.value_and_gradient(x)
    h = 1e-6 * np.maximum(1, np.abs(x))
    gn = np.array([(obj.value(x + hk * e) - obj.value(x - hk * e)) / (2 * hk) for hk, e in zip(h, np.eye(x.size))])
    assert np.max(np.abs(g - gn)) <= 1e-6 * np.max(np.abs(g))
    zr, gr = obj.reduced_value_and_gradient(y)
    grn = np.array([(obj.reduced_value_and_gradient(y + 1e-6 * e)[0] - obj.reduced_value_and_gradient(y - 1e-6 * e)[0]) / 2e-6
                    for e in np.eye(y.size)])
    assert zr == pytest.approx(z)
    assert np.max(np.abs(gr - grn)) <= 1e-6 * np.max(np.abs(gr))


def test_value_equals_trapezoid_of_drake_torques(setup):
    fam, obj, y = setup
    x, _ = fam.reduced_to_full(y)
    T = x[-1]
    t = np.linspace(0, T, 41)
    q, qd, qdd = fam.sample(x, t)
    tau = drake_inverse_dynamics(q, qd, qdd)
    h = np.sum(tau ** 2, axis=1) + 1e5
    assert obj.value(x) == pytest.approx(np.trapezoid(h, t) if hasattr(np, "trapezoid") else np.trapz(h, t), rel=1e-12)


def test_fine_grid_converges(setup):
    fam, obj, y = setup
    x, _ = fam.reduced_to_full(y)
    z = [EnergyObjective(fam, ohsaka_arm(), 1.0, 1e5, n).value(x) for n in (500, 1000, 2000)]
    assert abs(z[2] - z[1]) < 0.3 * abs(z[1] - z[0]) + 1e-9 * z[2]  # second order


@pytest.mark.parametrize("kw,msg", [
    (dict(c1=-1.0), "c1 = -1"), (dict(c2=-5.0), "c2 = -5"), (dict(c2=0.0), "no stable solution"),
    (dict(m=0), "m = 0"), (dict(XT=[0.0, 0.71]), "out of reach"), (dict(X0=[0.9, 0.0]), "out of reach"),
])
def test_bad_input_is_one_line(kw, msg):
    args = dict(X0=[0.7, 0.0], XT=[0.0, 0.2])
    args.update(kw)
    with pytest.raises(QmtInputError, match=msg) as e:
        EnergyProblem(**args)
    assert "\n" not in str(e.value)
