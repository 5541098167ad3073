"""Scenario YAML files for tests: a built-in scenario with some values changed."""

import yaml

from qmt_drake.config.scenario import SCENARIO_DIR


def scenario_yaml(tmp_path, _base="thesis-ch4", **changes) -> str:
    """Write `_base` with `changes` (keys like task__points_m for nested values) to a file in
    tmp_path named after the changes; returns its path."""
    raw = yaml.safe_load((SCENARIO_DIR / f"{_base}.yaml").read_text())
    raw["arm"]["urdf"] = str((SCENARIO_DIR / raw["arm"]["urdf"]).resolve())
    for path, value in changes.items():
        d = raw
        keys = path.split("__")
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value
    p = tmp_path / f"s{abs(hash(repr(changes))) % 10**8}.yaml"
    p.write_text(yaml.safe_dump(raw))
    return str(p)
