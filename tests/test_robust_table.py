"""The sequential certification of P(carried) >= 0.9 (sweep/certify.py) against the Wilson formula, and a tiny
search whose answer follows in closed form (the co-simulation replaced by a threshold rule per draw)."""

import math

import numpy as np
import pytest

from qmt_drake.sweep import certify
from qmt_drake.sweep.runner import dask_client
from qmt_drake.sweep.spec import load_spec
from qmt_drake.sweep.stats import wilson_interval


def test_failures_allowed_is_the_wilson_bound():
    assert certify.smallest_cases(0.9) == 35  # 34/34 gives 0.898, 35/35 gives 0.9091
    assert wilson_interval(34, 34)[0] < 0.9 <= wilson_interval(35, 35)[0]
    for n in (35, 40, 60, 100, 200):
        f = certify.failures_allowed(n)
        assert wilson_interval(n - f, n)[0] >= 0.9 > wilson_interval(n - f - 1, n)[0]
    assert certify.failures_allowed(34) == -1
    assert certify.failures_allowed(100) == 4 and certify.failures_allowed(200) == 11


def test_stopping_early_never_changes_the_verdict_of_all_n_cases():
    """A 'fail' after m < n cases: even if every case not yet run were carried the bound misses 0.9; a 'pass'
    needs all n cases; at m = n the verdict is the Wilson bound's."""
    for n in (35, 60, 100):
        reachable = [wilson_interval(n - lost, n)[0] >= 0.9 for lost in range(n + 1)]
        for m in range(1, n + 1):
            for lost in range(0, m + 1):
                v = certify.sequential_verdict(lost, m, n)
                best = reachable[lost]
                if v == "fail":
                    assert not best
                elif v == "pass":
                    assert m == n and best
                else:
                    assert m < n and best


@pytest.fixture(scope="module")
def client():
    with dask_client(None, 1) as cl:
        yield cl


def fake_plan(ref):
    return {"plan_key": ref.key}


def threshold_case(case, plan_doc):
    """Carried iff the time scale reaches this draw's threshold 1 + (0.4 - friction)."""
    fr, s = case.parameters["friction"], case.sim["time_scale"]
    return {"key": case.key, "index": case.index, "label": case.label, "parameters": case.parameters,
            "status": "ok", "held": s >= 1.0 + (0.4 - fr), "max_slip_m": 1e-4, "motion_time_s": 2.0 * s}


def test_certify_finds_the_closed_form_scale_and_checks_fresh_draws(tmp_path, client):
    raw = {"name": "rt", "scenario": "thesis-ch4", "plans": [{"method": "thesis"}],
           "monte_carlo": {"cases": 35, "seed": 5},
           "parameters": {"friction": {"dist": "uniform", "low": 0.3, "high": 0.4}}}
    spec = load_spec(raw)
    kw = dict(case_fn=threshold_case, plan_fn=fake_plan, client=client)
    # x1.0: about every draw is lost: the test stops after the first batch
    t = certify.test_time_scale(spec, 1.0, tmp_path, seed=5, n=35, batch=5, **kw)
    assert t["verdict"] == "fail" and t["stopped_early"] and t["run"] == 5
    r = certify.certify_time_scale(spec, tmp_path, n_search=35, n_fresh=35, batch=7, s_min=1.0, s_max=1.2,
                                   goal=1.1, rel_tol=0.005, **kw)
    # 35 cases allow no loss: the smallest passing scale is the largest threshold of the 35 search draws
    exact = max(1.0 + (0.4 - d["friction"]) for d in spec.samples())
    assert r["found"] and exact <= r["search_scale"] <= exact * 1.005 + 1e-12
    assert all((p["verdict"] == "pass") == (p["time_scale"] >= exact) for p in r["points"])
    f = r["fresh"][0]
    assert f["seed"] == 5 + certify.FRESH_SEED_STEP and f["time_scale"] == r["search_scale"]
    fresh_draws = load_spec({**raw, "monte_carlo": {"cases": 35, "seed": f["seed"]}}).samples()
    lost = sum(r["search_scale"] < 1.0 + (0.4 - d["friction"]) for d in fresh_draws)
    assert f["verdict"] == ("pass" if lost == 0 else "fail")
    if r["certified"]:
        assert math.isclose(r["time_scale"], r["fresh"][-1]["time_scale"])
    assert np.all(np.diff([p["time_scale"] for p in r["points"]]) > 0)
