"""The one scenario resolver (config/resolve.py) and the one number rule (config/fields.py)."""

import pytest

from qmt_drake.config.fields import load_yaml_text
from qmt_drake.config.resolve import SCENARIO_DIR, builtin_scenarios, kind_of, resolve_scenario
from qmt_drake.errors import QmtInputError


@pytest.mark.parametrize("name,kind", [("thesis-ch4", "transfer"), ("ur5-suction-bins", "spatial_transfer"),
                                       ("ohsaka-fig3", "energy_time")])
def test_a_builtin_resolves_to_its_file_and_kind(name, kind):
    assert resolve_scenario(name, kind) == SCENARIO_DIR / f"{name}.yaml"
    assert kind_of(name) == kind and name in builtin_scenarios(kind)
    assert kind_of(str(SCENARIO_DIR / f"{name}.yaml")) == kind


@pytest.mark.parametrize("name,asked,says", [
    ("ur5-suction-bins", "transfer", "is a spatial (3-D) scenario: plan it with `qmt-drake plan ur5-suction-bins"),
    ("ohsaka-fig3", "spatial_transfer", "is a seed-001 energy-time scenario"),
    ("thesis-ch4", "energy_time", "is a transfer scenario"),
])
def test_a_file_of_another_kind_is_answered_with_the_command_that_takes_it(name, asked, says):
    with pytest.raises(QmtInputError, match=None) as e:
        resolve_scenario(name, asked)
    assert says in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("bad", [None, 123, "", "no-such-scenario", "/no/such/file.yaml", "."])
def test_neither_a_builtin_nor_a_file_is_one_line(bad):
    with pytest.raises(QmtInputError) as e:
        resolve_scenario(bad)
    assert "\n" not in str(e.value) and "thesis-ch4" in str(e.value)
    assert kind_of(bad) == ""


def test_one_number_rule_reads_exponents_without_a_dot_as_numbers():
    d = load_yaml_text("a: 1e5\nb: -2.5E-3\nc: 1.0e+5\nd: '1e5'\ne: e5\nf: 12\n", "t")
    assert d == {"a": 1e5, "b": -2.5e-3, "c": 1e5, "d": "1e5", "e": "e5", "f": 12}
    assert isinstance(d["a"], float) and isinstance(d["f"], int)
