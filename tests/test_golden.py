"""The golden files (tests/golden, studies/record_goldens.py): a fast subset of the recorded plans,
co-simulation summaries and diagrams recomputed and compared bit for bit. The whole set:
`PYTHONPATH=. python -m studies.record_goldens --check`. A difference names the file and the first
differing field; if a change of a number is intended, say which, by how much and why, and re-record
(`python -m studies.record_goldens --only CASE`)."""

import json

import numpy as np
import pytest

from studies.record_goldens import (
    CASES,
    DEFAULT_DIR,
    FAST,
    check,
    first_difference,
    golden_path,
    normalise_graphviz,
)

BY_NAME = {c.name: c for c in CASES}


@pytest.mark.parametrize("name", FAST)
def test_fast_cases_are_bit_identical_to_their_golden_files(name):
    msg = check(BY_NAME[name])
    assert msg is None, msg


def test_every_case_has_its_golden_file_and_every_file_its_case():
    files = {p.stem for p in DEFAULT_DIR.glob("*.json")}
    assert files == set(BY_NAME), (sorted(set(BY_NAME) - files), sorted(files - set(BY_NAME)))
    kinds = {json.loads(golden_path(DEFAULT_DIR, c).read_text())["plan_json"].get("scenario_kind") for c in CASES}
    assert kinds == {"transfer", "energy_time", "spatial_transfer"}


def test_the_comparison_sees_one_ulp_a_type_change_and_a_missing_field():
    golden = json.loads(golden_path(DEFAULT_DIR, BY_NAME["ch4-toppra"]).read_text())
    fresh = json.loads(json.dumps(golden))
    assert first_difference(golden, fresh) is None
    fresh["plan"]["q_rad"][7][1] = float(np.nextafter(fresh["plan"]["q_rad"][7][1], np.inf))
    assert first_difference(golden, fresh).startswith(".plan.q_rad[7][1]: ")
    assert first_difference({"a": 1.0}, {"a": 1}).startswith(".a: float")
    assert first_difference({"a": 1.0, "b": 2}, {"a": 1.0}) == ".b: missing now"
    assert first_difference({"a": float("nan")}, {"a": float("nan")}) is None


def test_graphviz_normalisation_removes_only_ids_order_and_addresses():
    a = 'digraph _12 {\nsubgraph clusters12out {\n}\ns12 [label="Plant@00005616214bdf90"]\ns13 [label="x"]\ns12:y0 -> s13:u0\ns13:y0 -> s12:u1\n}'
    b = 'digraph _40 {\nsubgraph clusters40out {\n}\ns40 [label="Plant@00005576d0d0ed70"]\ns41 [label="x"]\ns41:y0 -> s40:u1\ns40:y0 -> s41:u0\n}'
    assert normalise_graphviz(a) == normalise_graphviz(b)
    assert normalise_graphviz(a) != normalise_graphviz(a.replace('"x"', '"y"'))
