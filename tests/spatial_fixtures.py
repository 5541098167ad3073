"""Shared by the spatial tests: a shipped spatial scenario (or a skip when example-robot-data, a test
extra, is missing), every spatial planner's plan of it at a test budget, and an edited copy of its file."""

import functools
from pathlib import Path

import pytest
import yaml

from qmt_drake.errors import QmtInputError
from qmt_drake.planners.spatial_methods import (
    plan_family_optimum,
    plan_ga_spatial,
    plan_ruckig_spatial,
    plan_toppra_spatial,
    plan_trajopt_spatial,
)
from qmt_drake.spatial_task import SCENARIO_DIR, load_spatial_scenario


def load_or_skip(name: str):
    try:
        return load_spatial_scenario(name)
    except QmtInputError as exc:
        if "example-robot-data" not in str(exc):
            raise
        pytest.skip(str(exc))


@functools.cache
def shipped_toppra(name: str, n_grid: int | None = None):
    """plan_toppra_spatial of the shipped scenario `name`, computed once per test session (2-4 s each):
    several test files check the same plan (none changes it)."""
    sc = load_or_skip(name)
    return plan_toppra_spatial(sc) if n_grid is None else plan_toppra_spatial(sc, n_grid=n_grid)


def plans_of_every_method(sc) -> dict:
    """Each spatial method's plan of sc (TOPP-RA on 400 grid points, the GA at 8 generations of 20)."""
    shipped = Path(sc.path).resolve() == (SCENARIO_DIR / f"{sc.name}.yaml").resolve()
    toppra = shipped_toppra(sc.name, 400) if shipped else plan_toppra_spatial(sc, n_grid=400)
    return {"toppra": toppra, "ruckig": plan_ruckig_spatial(sc),
            "family_optimum": plan_family_optimum(sc), "ga": plan_ga_spatial(sc, generations=8, population=20),
            "trajopt": plan_trajopt_spatial(sc)}


def edited_copy(scenario_file: Path, tmp_path: Path, edit) -> Path:
    """scenario_file's YAML after edit(raw) (a function changing the dict in place), written to tmp_path."""
    raw = yaml.safe_load(Path(scenario_file).read_text())
    edit(raw)
    p = tmp_path / "variant.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p
