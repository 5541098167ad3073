"""Ports on localhost (issue 30, item 6): the sweep's LocalCluster dashboard listens on 127.0.0.1 (a
free port) unless the user asks for another address with --dashboard; a bad address is one line."""

import distributed
import psutil
import pytest

from qmt_drake.apps.cli import main
from qmt_drake.errors import QmtInputError
from qmt_drake.sweep.cluster import DEFAULT_DASHBOARD_ADDRESS, check_dashboard_address, dask_client


class _Recorder:
    """Stands in for LocalCluster and Client: records the keywords, starts nothing."""

    seen: list = []

    def __init__(self, *args, **kwargs):
        _Recorder.seen.append(kwargs)

    def close(self):
        pass


def test_local_cluster_is_asked_for_localhost_unless_told(monkeypatch):
    monkeypatch.setattr(distributed, "LocalCluster", _Recorder)
    monkeypatch.setattr(distributed, "Client", _Recorder)
    _Recorder.seen = []
    with dask_client(None, 1):
        pass
    cluster_kw = _Recorder.seen[0]
    assert cluster_kw["dashboard_address"] == DEFAULT_DASHBOARD_ADDRESS == "127.0.0.1:0"
    assert cluster_kw["host"] == "127.0.0.1"
    _Recorder.seen = []
    with dask_client(None, 1, dashboard_address="0.0.0.0:8787"):  # the user asked for it
        pass
    assert _Recorder.seen[0]["dashboard_address"] == "0.0.0.0:8787"


@pytest.mark.parametrize("bad", ["", "8787", ":8787", "host:port", "127.0.0.1:70000", "127.0.0.1:-1"])
def test_a_bad_dashboard_address_is_one_line(bad):
    with pytest.raises(QmtInputError) as exc:
        check_dashboard_address(bad)
    assert str(exc.value).startswith(f"--dashboard '{bad}' is not HOST:PORT") and "\n" not in str(exc.value)


def test_cli_refuses_a_bad_dashboard_before_reading_the_spec(capsys):
    assert main(["sweep", "no-such-spec.yaml", "--dashboard", "everywhere"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--dashboard 'everywhere' is not HOST:PORT" in err and len(err.splitlines()) == 1


def test_real_local_cluster_dashboard_listens_on_localhost_only():
    """A one-worker LocalCluster (a few seconds): every socket listening on the dashboard's port is
    bound to 127.0.0.1 (Dask's ':0' bound 0.0.0.0 and ::)."""
    with dask_client(None, 1) as client:
        port = client.scheduler_info()["services"]["dashboard"]
        listening = [c.laddr for c in psutil.Process().net_connections(kind="inet")
                     if c.status == psutil.CONN_LISTEN and c.laddr.port == port]
    assert listening and all(a.ip == "127.0.0.1" for a in listening), listening
