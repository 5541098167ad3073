"""The Dask cluster a sweep runs on: a LocalCluster with one single-threaded worker process per
core, or a user's scheduler at tcp://HOST:PORT, checked before Dask's client connects (an unreachable
or non-Dask address is a one-line QmtInputError after the connect timeout). Dask itself is imported
only when a cluster is made (start-up time of the CLI)."""

from __future__ import annotations

import logging
import os
import socket
import time
from contextlib import contextmanager

from qmt_drake.errors import QmtInputError

DEFAULT_ALLOWED_FAILURES = 3  # Dask's own default, stated so a LocalCluster sweep does not depend on it
CONNECT_TIMEOUT_S = 3.0  # an unroutable --scheduler is refused after this
# The LocalCluster's dashboard: this machine only, a free port (Dask's default ':8787' listens on every
# interface); another address only when the user asks (`qmt-drake sweep --dashboard HOST:PORT`).
DEFAULT_DASHBOARD_ADDRESS = "127.0.0.1:0"
LOCAL_HOST = "127.0.0.1"  # the LocalCluster's scheduler and workers


def check_dashboard_address(address: str) -> str:
    """HOST:PORT for the LocalCluster's dashboard (PORT 0: a free one); anything else: QmtInputError."""
    host, sep, port = str(address).strip().rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) < 65536:
        raise QmtInputError(f"--dashboard '{address}' is not HOST:PORT (e.g. 127.0.0.1:8787; port 0 picks a "
                            "free one; 0.0.0.0:PORT opens it to the network)")
    return f"{host}:{int(port)}"


def check_scheduler_address(address: str) -> str:
    """tcp://HOST:PORT (a bare HOST:PORT gets tcp://); anything else: QmtInputError."""
    addr = address.strip()
    if "://" not in addr:
        addr = "tcp://" + addr
    proto, _, rest = addr.partition("://")
    host, _, port = rest.rpartition(":")
    if proto not in ("tcp", "tls") or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise QmtInputError(f"--scheduler '{address}' is not an address of the form tcp://HOST:PORT "
                            "(a Dask scheduler prints it when started: `dask scheduler`)")
    return addr


def probe_scheduler(addr: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """A plain TCP connection to tcp://HOST:PORT within timeout_s, before Dask's client (whose
    failed connection leaves a TimeoutError traceback behind): one line if nothing answers."""
    rest = addr.partition("://")[2]
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    why = None
    deadline = time.monotonic() + timeout_s
    while True:  # a scheduler still starting refuses connections: retry until the timeout, as Dask does
        try:
            with socket.create_connection((host, int(port)), timeout=max(0.05, deadline - time.monotonic())):
                why = None
            break
        except ConnectionRefusedError as exc:
            why = exc.strerror or "refused"
            if time.monotonic() + 0.1 >= deadline:
                break
            time.sleep(0.1)
        except OSError as exc:  # unroutable (timeout), unknown host
            why = "timed out" if isinstance(exc, TimeoutError) else (exc.strerror or type(exc).__name__)
            break
    if why is None:  # something listens (or a proxy accepts anything): ask it who it is
        why = _dask_identity(addr, timeout_s)
    if why is not None:
        raise QmtInputError(f"--scheduler {addr}: no Dask scheduler answered within {timeout_s:g} s "
                            f"({why}); start one there with `dask scheduler` and workers with "
                            f"`dask worker {addr}`, or omit --scheduler for a local cluster") from None


def _dask_identity(addr: str, timeout_s: float) -> str | None:
    """None if a Dask scheduler at `addr` answers the identity request within timeout_s, else why not."""
    import asyncio

    # lazy: Dask (~0.4 s) only when a sweep runs
    from distributed.comm import connect

    async def ask():
        comm = await connect(addr, timeout=timeout_s)
        try:
            await comm.write({"op": "identity"})
            return await comm.read()
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout_s))
    except Exception as exc:  # noqa: BLE001 - timeouts, OSError, or garbage from a non-Dask server
        return f"something accepted the connection but gave no Dask handshake: {type(exc).__name__}"
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        return "something answered, but not a Dask scheduler"
    return None


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None, *,
                allowed_failures: int = DEFAULT_ALLOWED_FAILURES, connect_timeout_s: float = CONNECT_TIMEOUT_S,
                dashboard_address: str = DEFAULT_DASHBOARD_ADDRESS):
    """A distributed.Client on a new LocalCluster (`workers` single-threaded processes, default one
    per core; scheduler and workers on 127.0.0.1, the dashboard at `dashboard_address`, by default
    127.0.0.1 and a free port) or on the scheduler at `scheduler`; closed (and the local cluster shut
    down) on exit."""
    dashboard_address = check_dashboard_address(dashboard_address)
    # lazy: Dask (~0.4 s) only when a sweep runs
    import dask
    from distributed import Client, LocalCluster
    # worker-saturation 1.0: a worker holds only the case it runs (default 1.1 rounds up to two per
    # thread), so a worker that dies makes only that case suspicious, not an innocent queued one.
    cfg = {"distributed.scheduler.allowed-failures": int(allowed_failures),
           "distributed.scheduler.worker-saturation": 1.0,
           "distributed.comm.timeouts.connect": f"{connect_timeout_s}s"}
    with dask.config.set(cfg):
        if scheduler:
            addr = check_scheduler_address(scheduler)
            try:
                client = Client(addr, timeout=f"{connect_timeout_s}s", set_as_default=False)
            except Exception as exc:  # noqa: BLE001 - OSError/TimeoutError, or garbage from a non-Dask port
                raise QmtInputError(
                    f"--scheduler {addr}: no Dask scheduler answered within {connect_timeout_s:g} s "
                    f"({type(exc).__name__}); start one there with `dask scheduler` and workers with "
                    f"`dask worker {addr}`, or omit --scheduler for a local cluster") from None
            try:
                yield client
            finally:
                client.close()
            return
        n = int(workers or os.cpu_count() or 1)
        if n < 1:
            raise QmtInputError(f"--workers must be >= 1, got {workers}")
        # Each worker is one process running one case at a time; numpy's BLAS threads would only
        # compete with the other workers for the cores.
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(var, "1")
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host=LOCAL_HOST,
                               dashboard_address=dashboard_address, silence_logs=logging.CRITICAL)
        client = Client(cluster, set_as_default=False)
        try:
            yield client
        finally:
            client.close()
            cluster.close()
