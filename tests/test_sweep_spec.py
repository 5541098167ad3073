"""Sweep specs: validation (one-line QmtInputError), the parameter table's mapping into cases,
Monte Carlo determinism and case keys."""

import numpy as np
import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.sweep.cases import build_cases
from qmt_drake.sweep.spec import PARAMETERS, load_spec


def spec(**kw):
    d = {"name": "t", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}]}
    d.update(kw)
    return d


@pytest.mark.parametrize("raw, words", [
    (spec(parameters={"frction": 0.3}), ["parameters.frction", "unknown parameter", "friction"]),
    (spec(parameters={"friction": {"dist": "normal", "mean": 0.3, "std": -0.01}},
          monte_carlo={"cases": 4}), ["std", "negative"]),
    (spec(parameters={"friction": {"dist": "uniform", "low": 0.4, "high": 0.2}},
          monte_carlo={"cases": 4}), ["low", "high", "spread"]),
    (spec(parameters={"friction": {"dist": "normal", "mean": 0.3, "std": 0.03}}), ["monte_carlo"]),
    (spec(monte_carlo={"cases": 3}), ["no parameter has a distribution"]),
    (spec(parameters={"friction": {"dist": "cauchy", "mean": 0.3}}, monte_carlo={"cases": 2}),
     ["unknown distribution"]),
    (spec(parameters={"mass_kg": -0.01}), ["mass_kg", "out of range"]),
    (spec(parameters={"mass_kg": 0.03, "mass_scale": 1.0}), ["same quantity"]),
    (spec(parameters={"friction": "high"}), ["must be a number"]),
    (spec(plans=[{"method": "bogus"}]), ["method 'bogus' is unknown"]),
    (spec(plans=[{"method": "ga"}, {"method": "ga"}]), ["share the label"]),
    (spec(sim={"feedforward": "lots"}), ["feedforward"]),
    (spec(bogus=1), ["unknown key 'bogus'"]),
    (spec(monte_carlo={"cases": 0}, parameters={"friction": {"dist": "normal", "mean": 0.3, "std": 0.1}}),
     ["monte_carlo.cases"]),
])
def test_bad_specs_raise_one_line_errors(raw, words):
    with pytest.raises(QmtInputError) as e:
        load_spec(raw)
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_missing_file_and_bad_yaml(tmp_path):
    with pytest.raises(QmtInputError, match="does not exist"):
        load_spec(tmp_path / "nope.yaml")
    p = tmp_path / "bad.yaml"
    p.write_text("name: [unclosed\n")
    with pytest.raises(QmtInputError, match="not valid YAML"):
        load_spec(p)


def test_grid_times_samples_and_common_random_numbers():
    s = load_spec(spec(plans=[{"method": "thesis"}, {"method": "optimum"}],
                       parameters={"friction": {"dist": "uniform", "low": 0.2, "high": 0.4},
                                   "time_scale": [1.0, 1.1, 1.2]},
                       monte_carlo={"cases": 5, "seed": 3}))
    cases, plans = build_cases(s)
    assert len(cases) == s.n_cases == 2 * 3 * 5
    assert len(plans) == 2  # time scale and friction never change the plan
    # sample i draws the same friction for every plan and grid point
    by_sample = {}
    for c in cases:
        by_sample.setdefault(c.sample, set()).add(c.parameters["friction"])
    assert all(len(v) == 1 for v in by_sample.values()) and len(by_sample) == 5
    fr = np.array([next(iter(by_sample[i])) for i in range(5)])
    assert np.all((fr >= 0.2) & (fr <= 0.4))
    # same seed, same draws and keys; another seed, other draws
    again, _ = build_cases(load_spec(s.raw))
    assert [c.key for c in again] == [c.key for c in cases]
    other = dict(s.raw, monte_carlo={"cases": 5, "seed": 4})
    assert {c.key for c in build_cases(load_spec(other))[0]}.isdisjoint({c.key for c in cases})
    assert len({c.key for c in cases}) == len(cases)


def test_normal_is_cut_where_the_file_says():
    # (without low, this normal loses 40 % of its mass below friction's bound 0: refused, test_outsider_s18)
    s = load_spec(spec(parameters={"friction": {"dist": "normal", "mean": 0.05, "std": 0.2, "low": 0.01}},
                       monte_carlo={"cases": 400, "seed": 0}))
    fr = np.array([d["friction"] for d in s.samples()])
    assert fr.min() >= 0.01 and fr.std() > 0.05


def test_every_parameter_lands_in_one_place():
    base = {"friction": 0.31, "mass_scale": 1.1, "com_offset_m": 0.027, "coil_current_scale": 0.9,
            "magnet_gap_m": 0.6e-3, "motor_torque_constant_scale": 0.95, "motor_resistance_scale": 1.05,
            "kp_scale": 2.0, "kd_scale": 0.5, "time_scale": 1.1, "time_step_s": 0.001}
    s = load_spec(spec(parameters=base))
    (c,), plans = build_cases(s)
    assert c.payload == {"friction": 0.31, "mass_kg": ["scale", 1.1], "com_offset_m": 0.027}
    assert c.magnet == {"coil_current_scale": 0.9, "effective_gap_m": 0.6e-3}
    assert c.motor_scales == {"torque_constant_Nm_per_A": 0.95, "resistance_ohm": 1.05}
    assert c.scenario_overrides["control"]["kp"] == pytest.approx([2 * 29.7, 2 * 5.5])
    assert c.scenario_overrides["control"]["kd"] == pytest.approx([0.5 * 104.0, 0.5 * 19.3])
    assert c.sim["time_scale"] == 1.1 and c.sim["time_step_s"] == 0.001
    # gains act in the co-simulation only: the plan is the nominal one
    (ref,) = plans.values()
    assert ref.overrides == {}
    assert set(base) <= set(PARAMETERS)


def test_planner_inputs_change_the_plan_key():
    s = load_spec(spec(plans=[{"method": "ga", "options": {"max_generations": 5}}],
                       parameters={"seed": [0, 1], "moment_limit_Nm": [0.5e-3, 0.57e-3]}))
    cases, plans = build_cases(s)
    assert len(cases) == 4 and len(plans) == 4
    assert {r.seed for r in plans.values()} == {0, 1}


def test_more_cases_extend_fewer():
    def keys(n, extra=None):
        params = {"friction": {"dist": "normal", "mean": 0.3, "std": 0.03},
                  "coil_current_scale": {"dist": "uniform", "low": 0.9, "high": 1.1}}
        params.update(extra or {})
        return [c.key for c in build_cases(load_spec(spec(parameters=params,
                                                         monte_carlo={"cases": n, "seed": 1})))[0]]
    assert keys(10)[:6] == keys(6)


def test_plan_file_key_ignores_wall_times(tmp_path):
    import json
    doc = {"scenario": "thesis-ch4", "method": "thesis", "genes": {"T1": 0.622, "T2": 0.532, "T3": 0.562},
           "trajectory": {"kind": "family", "family": "via_cubic"}, "planner_wall_s": 1.0}
    f = tmp_path / "p.json"
    f.write_text(json.dumps(doc))
    s = spec(plans=[{"file": str(f)}])
    k1 = build_cases(load_spec(s))[0][0].key
    f.write_text(json.dumps(dict(doc, planner_wall_s=2.0, extra={"log": [1, 2]})))
    assert build_cases(load_spec(s))[0][0].key == k1
    f.write_text(json.dumps(dict(doc, genes={"T1": 0.7, "T2": 0.532, "T3": 0.562})))
    assert build_cases(load_spec(s))[0][0].key != k1
    f.write_text("{not json")
    with pytest.raises(QmtInputError, match="cannot be read"):
        build_cases(load_spec(s))


def test_explicit_step_limit_agrees_with_the_simulation():
    from qmt_drake.sim.actuation import EXPLICIT_MAX_TIME_STEP_S
    from qmt_drake.sweep.spec import EXPLICIT_MAX_TIME_STEP_S as SPEC_LIMIT
    assert SPEC_LIMIT == EXPLICIT_MAX_TIME_STEP_S


@pytest.mark.parametrize("sim, params, words", [
    ({"time_step_s": 3.5}, {}, ["sim.time_step_s", "<= 0.005"]),
    ({}, {"time_step_s": [0.001, 0.5]}, ["time_step_s", "<= 0.005"]),
    ({"implicit_loop_damping": False, "time_step_s": 0.002}, {}, ["known unstable above 1 ms"]),
    ({"implicit_loop_damping": "yes"}, {}, ["implicit_loop_damping must be true or false"]),
    ({}, {"friction": "0.3"}, ["must be a number, got '0.3'"]),
])
def test_steps_and_types_refused(sim, params, words):
    with pytest.raises(QmtInputError) as e:
        load_spec(spec(sim=sim, parameters=params))
    for w in words:
        assert w in str(e.value), str(e.value)


def test_planner_options_are_the_planners_keywords():
    with pytest.raises(QmtInputError, match="not an option of the planar ga planner"):
        load_spec(spec(plans=[{"method": "ga", "options": {"max_generation": 5}}]))
    with pytest.raises(QmtInputError, match="max_generations 2.5 must be an integer"):
        load_spec(spec(plans=[{"method": "ga", "options": {"max_generations": 2.5}}]))
    s = load_spec(spec(plans=[{"method": "ga", "options": {"max_generations": 5, "stall_generations": 0}}]))
    assert s.plans[0]["options"] == {"max_generations": 5, "stall_generations": 0}


def test_duplicated_key_in_a_spec_file(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text("name: a\nscenario: thesis-ch4\nplans: [{method: thesis}]\nname: b\n")
    with pytest.raises(QmtInputError, match="duplicated key 'name'"):
        load_spec(p)
