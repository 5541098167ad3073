"""Runner mechanics on a real Dask LocalCluster with cheap fake cases (no Drake in the workers):
a worker killed mid-case is retried and no finished case is lost, a case that kills every worker
fails alone and is the only one a rerun computes, a rerun of a finished sweep computes nothing,
and an unreachable scheduler is a one-line error within 10 s."""

import gc
import json
import os
import time

import pytest

from qmt_drake.errors import QmtInputError
from qmt_drake.sweep.runner import dask_client, run_sweep
from qmt_drake.sweep.spec import load_spec

# The fake case functions reach the workers by name: LocalCluster workers start with this
# process's sys.path, which pytest gave the tests folder.

KILL_ONCE = 0.222  # friction values the fake case reacts to
KILL_ALWAYS = 0.111


def fake_plan(ref):
    return {"plan_key": ref.key, "method": "fake"}


def fake_case(case, plan_doc):
    """Sleeps a little, then 'holds' when friction >= 0.2. Kills its own worker process the first
    time it sees KILL_ONCE (a marker file remembers), and every time it sees KILL_ALWAYS unless a
    'disarm' file exists. The directory comes from QMT_TEST_KILL_DIR (inherited by the workers)."""
    import os
    import time
    d = os.environ["QMT_TEST_KILL_DIR"]
    fr = case.parameters["friction"]
    if fr == KILL_ONCE:
        marker = os.path.join(d, f"killed-{case.key}")
        if not os.path.exists(marker):
            open(marker, "w").close()
            os._exit(1)
    if fr == KILL_ALWAYS and not os.path.exists(os.path.join(d, "disarm")):
        with open(os.path.join(d, f"deaths-{case.key}"), "a") as fh:
            fh.write("x")
        os._exit(1)
    time.sleep(0.05)
    return {"key": case.key, "label": case.label, "parameters": case.parameters, "status": "ok",
            "held": fr >= 0.2, "max_slip_m": 1e-4 if fr >= 0.2 else 0.3, "motion_time_s": 1.0,
            "pid": os.getpid()}


def make_spec(frictions, name):
    return load_spec({"name": name, "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
                      "parameters": {"friction": list(frictions)}})


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    kill_dir = tmp_path_factory.mktemp("kill")
    os.environ["QMT_TEST_KILL_DIR"] = str(kill_dir)
    # Collect earlier test files' garbage (Drake diagrams) here, on the main thread: a collection that the
    # Dask client's event-loop thread triggers while destroying them aborted the process once (CI, xdist).
    gc.collect()
    with dask_client(None, 2, allowed_failures=1) as cl:
        cl.kill_dir = kill_dir
        yield cl


def test_killed_worker_is_retried_and_nothing_is_lost(client, tmp_path):
    spec = make_spec([0.3, 0.25, KILL_ONCE, 0.15, 0.35, 0.4], "killonce")
    out = run_sweep(spec, tmp_path, client=client, case_fn=fake_case, plan_fn=fake_plan,
                    progress=False, figures=False)
    assert out["failed"] == 0 and out["computed"] == 6 and out["from_store"] == 0
    assert len(list((tmp_path / "killonce" / "cases").glob("*.json"))) == 6
    assert len(list(client.kill_dir.glob("killed-*"))) == 1  # the worker really died once
    rows = out["rows"]  # one per friction value (a grid parameter)
    assert sum(r["n"] for r in rows) == 6 and sum(r["carried"] for r in rows) == 5


def test_case_that_always_kills_fails_alone_and_only_it_is_rerun(client, tmp_path):
    spec = make_spec([0.3, KILL_ALWAYS, 0.25, 0.35], "killalways")
    out = run_sweep(spec, tmp_path, client=client, case_fn=fake_case, plan_fn=fake_plan,
                    progress=False, figures=False)
    assert out["failed"] == 1 and out["computed"] == 3
    assert "KilledWorker" in out["failures"][0]["error"]
    deaths = next(client.kill_dir.glob("deaths-*")).read_text()
    # first try + allowed_failures=1 retry among the others, then the same two alone
    assert len(deaths) == 4
    cases = tmp_path / "killalways" / "cases"
    before = {p.name: p.stat().st_mtime_ns for p in cases.glob("*.json")}
    assert len(before) == 3
    (client.kill_dir / "disarm").write_text("")
    again = run_sweep(spec, tmp_path, client=client, case_fn=fake_case, plan_fn=fake_plan,
                      progress=False, figures=False)
    assert again["computed"] == 1 and again["from_store"] == 3 and again["failed"] == 0
    after = {p.name: p.stat().st_mtime_ns for p in cases.glob("*.json")}
    assert len(after) == 4 and all(after[k] == v for k, v in before.items())


def test_rerun_of_a_finished_sweep_computes_nothing(tmp_path):
    spec = make_spec([0.3, 0.1], "rerun")
    cases = tmp_path / "rerun" / "cases"
    cases.mkdir(parents=True)
    from qmt_drake.sweep.cases import build_cases
    for c in build_cases(spec)[0]:  # pretend a previous run finished both
        (cases / f"{c.key}.json").write_text(json.dumps({"label": "thesis", "held": True, "max_slip_m": 1e-4,
                                                         "parameters": {"friction": c.parameters["friction"]}}))

    def boom(*a):  # never called: nothing is pending, so not even a cluster is started
        raise AssertionError("recomputed a finished case")
    t = time.perf_counter()
    out = run_sweep(spec, tmp_path, case_fn=boom, plan_fn=boom, scheduler="tcp://127.0.0.1:1",
                    progress=False, figures=False)
    assert out["computed"] == 0 and out["from_store"] == 2 and out["workers"] is None
    assert time.perf_counter() - t < 5


def test_unreachable_scheduler_is_one_line_within_10_s(tmp_path):
    spec = make_spec([0.3], "unreachable")
    t = time.perf_counter()
    with pytest.raises(QmtInputError) as e:
        run_sweep(spec, tmp_path, scheduler="tcp://127.0.0.1:1", progress=False)
    assert time.perf_counter() - t < 10
    assert "\n" not in str(e.value) and "tcp://127.0.0.1:1" in str(e.value)
    with pytest.raises(QmtInputError, match="not an address"):
        run_sweep(spec, tmp_path, scheduler="http://x", progress=False)


def picky_plan(ref):
    if ref.method == "optimum":
        raise RuntimeError("planner crashed")
    return {"plan_key": ref.key}


def test_a_failed_plan_fails_only_its_cases(client, tmp_path):
    spec = load_spec({"name": "planfail", "scenario": "thesis-ch4",
                      "plans": [{"method": "thesis"}, {"method": "optimum"}],
                      "parameters": {"friction": [0.3, 0.25]}})
    out = run_sweep(spec, tmp_path, client=client, case_fn=fake_case, plan_fn=picky_plan,
                    progress=False, figures=False)
    assert out["computed"] == 2 and out["failed"] == 2
    assert any("planner crashed" in f["error"] for f in out["failures"])
    assert {r["label"] for r in out["rows"]} == {"thesis"}


def test_probe_refuses_a_closed_port_after_its_timeout():
    import time

    from qmt_drake.sweep.runner import probe_scheduler
    t = time.perf_counter()
    with pytest.raises(QmtInputError, match="no Dask scheduler answered within 0.5 s"):
        probe_scheduler("tcp://127.0.0.1:1", 0.5)
    assert 0.4 < time.perf_counter() - t < 3.0  # retried while refused (a starting scheduler), then one line


def test_a_case_on_a_cluster_without_workers_fails_instead_of_waiting_for_good():
    """A LocalCluster that has lost every worker (its nannies could not restart a killed one: it hung this
    file's kill test for good under load) fails the waiting case and the pending ones within no_worker_s."""
    from distributed import Client, LocalCluster

    from qmt_drake.sweep.runner import _completed_while_workers_live, _result_while_workers_live
    gc.collect()  # as in the fixture: Drake garbage collected on the main thread, not the client's loop
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster, \
            Client(cluster, set_as_default=False) as cl:
        # a cluster with a worker: futures come back as they finish, however long the poll
        futs = [cl.submit(time.sleep, 0.3, pure=False), cl.submit(abs, -2, pure=False)]
        assert set(_completed_while_workers_live(cl, futs, poll_s=0.1, no_worker_s=0.2)) == set(futs)
        assert _result_while_workers_live(cl, cl.submit(abs, -3, pure=False), poll_s=0.1, no_worker_s=0.2) == 3
        cluster.scale(0)
        gone = time.perf_counter() + 10.0
        while cl.scheduler_info().get("workers") and time.perf_counter() < gone:
            time.sleep(0.05)
        assert not cl.scheduler_info().get("workers")
        t = time.perf_counter()
        with pytest.raises(RuntimeError, match="no Dask worker alive for 1 s"):
            _result_while_workers_live(cl, cl.submit(abs, -4, pure=False), poll_s=0.25, no_worker_s=1.0)
        with pytest.raises(RuntimeError, match="no Dask worker alive"):
            list(_completed_while_workers_live(cl, [cl.submit(abs, -5, pure=False)], poll_s=0.25, no_worker_s=1.0))
        assert time.perf_counter() - t < 10.0
