"""glibc malloc tuning for the planners' and co-simulations' temporaries (Linux only).

The GA evaluates a population in numpy arrays of a few hundred kB that are allocated and freed
thousands of times per second, and Drake's simulator allocates and frees its own buffers every step.
glibc serves blocks above a dynamic threshold (128 kB to 32 MiB) by mmap and trims the top of the
heap once 2x that threshold is free, so each cycle can cost fresh zeroed pages from the kernel;
whether it does depends on where the heap's top happens to lie, which every imported library moves.
Measured (`python -m studies.bench_versions`, and the GA evaluation probe with the environment
variables below): the same evaluation code ran at 8,150 evaluations/s in a process that imported
little and at 7,100-7,400 in one that had imported scipy or pydrake.all, and at 9,600-10,000 in both
with a fixed mmap threshold of 32 MiB and a trim threshold of 256 MiB.

`tune()` sets those two (mallopt), unless the user set either through glibc's own
MALLOC_MMAP_THRESHOLD_ / MALLOC_TRIM_THRESHOLD_ or opted out with QMT_DRAKE_MALLOC_TUNING=0. It is an
explicit call, made by the programs that own their process: the `qmt-drake` command line
(apps/cli.main) and the studies that time things (studies/run_all.py, studies/bench_*.py).
`import qmt_drake` does not call it: a library leaves the allocator of the process that imports
it alone. A program of yours that runs many GA evaluations may call it first.
Cost: up to 256 MiB of freed memory stays mapped in the process instead of going back to the kernel.
"""

from __future__ import annotations

import ctypes
import os
import sys

M_TRIM_THRESHOLD = -1  # glibc malloc.h
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD_BYTES = 32 << 20  # glibc's largest (DEFAULT_MMAP_THRESHOLD_MAX on 64-bit)
TRIM_THRESHOLD_BYTES = 256 << 20
ENV_OPT_OUT = "QMT_DRAKE_MALLOC_TUNING"


def tune() -> bool:
    """Set the thresholds (module docstring); True when glibc accepted both."""
    if not sys.platform.startswith("linux") or os.environ.get(ENV_OPT_OUT, "1") == "0":
        return False
    if "MALLOC_MMAP_THRESHOLD_" in os.environ or "MALLOC_TRIM_THRESHOLD_" in os.environ:
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):  # not glibc (musl, ...): nothing to tune
        return False
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))

