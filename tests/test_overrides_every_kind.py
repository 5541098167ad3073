"""`overrides` on every scenario kind: merged into the YAML mapping before it is validated (one rule,
config/fields.merge_overrides), so an override changes what the scenario is (and its plan identity), and a
bad override stops with one line naming the key, as the same value in a copied file would."""

import pytest

from qmt_drake.api import load_scenario
from qmt_drake.config.fields import merge_overrides
from qmt_drake.errors import QmtInputError
from qmt_drake.plan_identity import identity, spatial_sections


def test_merge_is_key_by_key_and_replaces_gene_maps_whole():
    base = {"a": {"x": 1, "y": 2}, "genes": {"T": 1, "u": 2}}
    out = merge_overrides(base, {"a": {"y": 3}, "genes": {"T": 5}})
    assert out == {"a": {"x": 1, "y": 3}, "genes": {"T": 5}}
    assert base["a"]["y"] == 2  # the base is not changed


def test_spatial_override_changes_the_payload_and_its_identity():
    plain = load_scenario("ur5-magnet-part")
    heavy = load_scenario("ur5-magnet-part", overrides={"payload": {"mass_kg": 0.045}})
    assert plain.body.mass_kg == pytest.approx(0.030) and heavy.body.mass_kg == pytest.approx(0.045)
    assert identity(spatial_sections(plain))["sha256"] != identity(spatial_sections(heavy))["sha256"]


def test_energy_override_changes_the_weights():
    plain = load_scenario("ohsaka-fig3")
    other = load_scenario("ohsaka-fig3", overrides={"objective": {"c2": 0.5 * plain.c2}})
    assert other.c2 == pytest.approx(0.5 * plain.c2) and other.c1 == plain.c1


@pytest.mark.parametrize(("name", "overrides", "needle"), [
    ("ur5-magnet-part", {"payload": {"mass_kg": -1.0}}, "mass_kg"),
    ("ur5-magnet-part", {"payload": {"mass_kgg": 1.0}}, "mass_kgg"),
    ("ohsaka-fig3", {"objective": {"c2": "much"}}, "c2"),
])
def test_a_bad_override_stops_in_one_line_naming_the_key(name, overrides, needle):
    with pytest.raises(QmtInputError) as e:
        load_scenario(name, overrides=overrides)
    assert needle in str(e.value) and "\n" not in str(e.value)
