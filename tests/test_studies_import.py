"""Every study script and application module imports (the main job calls them; a renamed name would
otherwise surface only in `make run`)."""

import importlib
import pkgutil
from pathlib import Path

import pytest

import qmt_drake

ROOT = Path(__file__).resolve().parents[1]
STUDIES = sorted(p.stem for p in (ROOT / "studies").glob("*.py") if p.stem != "__init__")
MODULES = sorted(m.name for m in pkgutil.walk_packages(qmt_drake.__path__, "qmt_drake."))


@pytest.mark.parametrize("name", STUDIES)
def test_study_imports(name):
    importlib.import_module(f"studies.{name}")


def test_every_package_module_imports():
    for name in MODULES:
        importlib.import_module(name)
