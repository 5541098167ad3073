"""Shared by the spatial tests: a shipped spatial scenario, or a skip when example-robot-data (a test
extra) is missing."""

import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.spatial_task import load_spatial_scenario


def load_or_skip(name: str):
    try:
        return load_spatial_scenario(name)
    except QmtInputError as exc:
        if "example-robot-data" not in str(exc):
            raise
        pytest.skip(str(exc))
