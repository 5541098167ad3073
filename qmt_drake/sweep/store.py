"""The sweep's own result store: one JSON file per finished case, keyed by the case's inputs.

Layout under <out>/<sweep name>/:
    cases/<case key>.json   one finished case (written atomically by the client as it arrives)
    plans/<plan key>.json   one plan document (planned once, shared by every case that uses it)
    spec.yaml, summary.json, summary.md, figures

Dask does not resume a sweep after its client dies; this store does: a rerun lists the keys that
have a file and submits only the others. Only the client writes (workers return their results),
so a sweep on a remote cluster needs no shared file system.
"""

from __future__ import annotations

import json
from pathlib import Path

from qmt_drake.outputs import jsonable, write_text_atomic


class SweepStore:
    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.cases_dir = self.root / "cases"
        self.plans_dir = self.root / "plans"

    # cases
    def case_path(self, key: str) -> Path:
        return self.cases_dir / f"{key}.json"

    def has_case(self, key: str) -> bool:
        return self.case_path(key).is_file()

    def finished_keys(self) -> set[str]:
        if not self.cases_dir.is_dir():
            return set()
        return {p.stem for p in self.cases_dir.glob("*.json")}

    def write_case(self, key: str, result: dict) -> None:
        write_text_atomic(self.case_path(key), json.dumps(jsonable(result), indent=1))

    def read_case(self, key: str) -> dict | None:
        try:
            return json.loads(self.case_path(key).read_text())
        except (FileNotFoundError, json.JSONDecodeError):
            return None  # a torn file cannot exist (atomic writes); a missing one is unfinished

    # plans
    def plan_path(self, key: str) -> Path:
        return self.plans_dir / f"{key}.json"

    def read_plan(self, key: str) -> dict | None:
        try:
            return json.loads(self.plan_path(key).read_text())
        except (FileNotFoundError, json.JSONDecodeError):
            return None

    def write_plan(self, key: str, doc: dict) -> None:
        write_text_atomic(self.plan_path(key), json.dumps(jsonable(doc)))

    def write_text(self, name: str, text: str) -> Path:
        path = self.root / name
        write_text_atomic(path, text)
        return path
