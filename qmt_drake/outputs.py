"""Writing results: output paths probed before any work, atomic writes, JSON-ready data.

Every command that writes checks its output paths first (`check_output_path`, `check_output_dir`), so
an unwritable path stops in one line before a long computation; results are written to a temporary
file and renamed (`write_text_atomic`), so a crash never leaves half a file.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from qmt_drake.errors import QmtInputError


def _probe_folder(folder: Path, what: str) -> None:
    """Create `folder` if missing and write + remove a scratch file in it; one line if that fails."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise QmtInputError(f"{what}: {folder} is a file, not a folder; choose another path") from None
    except OSError as exc:
        raise QmtInputError(f"{what}: cannot create folder {folder} ({exc.strerror}); choose another "
                            "path") from None
    if not folder.is_dir():
        raise QmtInputError(f"{what}: {folder} is not a folder; choose another path")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".qmt-drake-probe-"):
            pass
    except OSError as exc:
        raise QmtInputError(f"{what}: folder {folder} is not writable ({exc.strerror}); choose another "
                            "path") from None


def check_output_path(path: str | Path | None, flag: str) -> None:
    """Before any long computation: `path` (a file to be written; '-' is stdout) must not be a
    directory, and its folder must exist or be creatable (it is created) and be writable (a
    scratch file is written and removed). One-line QmtInputError naming the flag."""
    if path is None or str(path) == "-":
        return
    if str(path) == "":
        raise QmtInputError(f"{flag}: empty path; give a file name")
    p = Path(path)
    if p.is_dir():
        raise QmtInputError(f"{flag} {p} is a directory; give a file name inside it")
    if p.exists() and not os.access(p, os.W_OK):
        raise QmtInputError(f"{flag} {p} exists and is not writable; choose another path")
    _probe_folder(p.parent if str(p.parent) else Path("."), f"{flag} {p}")


def check_output_dir(path: str | Path, flag: str) -> None:
    """Like check_output_path for a folder results are written into (created if missing)."""
    if str(path) == "":
        raise QmtInputError(f"{flag}: empty path; give a folder")
    _probe_folder(Path(path), f"{flag} {path}")


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write to a temporary file beside `path`, then rename: a crash never leaves half a file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def jsonable(x):
    """Plain JSON types for nested numpy data (non-finite floats become null)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    return x
