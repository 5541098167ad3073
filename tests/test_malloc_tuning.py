"""glibc malloc tuning (an explicit call: the CLI's main makes it, `import qmt_drake` does not): applied
on Linux/glibc, and left alone when the user set glibc's own variables or opted out (each checked in a
fresh interpreter, since it changes the process)."""

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc only")

PROBE = "import qmt_drake.malloc_tuning as m; print(m.tune())"


def _tuned(**env) -> str:
    clean = {k: v for k, v in os.environ.items()
             if k not in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "QMT_DRAKE_MALLOC_TUNING")}
    out = subprocess.run([sys.executable, "-c", PROBE], env={**clean, **env}, capture_output=True, text=True,
                         check=True)
    return out.stdout.strip()


def test_tuned_by_default_and_not_when_the_user_chose():
    assert _tuned() == "True"
    assert _tuned(QMT_DRAKE_MALLOC_TUNING="0") == "False"
    assert _tuned(MALLOC_TRIM_THRESHOLD_="1048576") == "False"
