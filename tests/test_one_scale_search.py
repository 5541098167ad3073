"""One "slow until it holds" / "slow until carried" (issue 27 item 4): timescale.search_scale.

(a) No other module of qmt_drake bisects a scale, or grows a bracket by a factor, in a loop of its own (an
    AST criterion that fired on every loop this replaced; the remaining hits are listed with their reason,
    and each must still fire).
(b) Each variant against a closed-form predicate (holds iff k >= k*, or lam <= lam* on a limit scale):
    the answer holds, lies within the tolerance of the threshold, and no failing k is returned.
(c) Each caller's variant probes exactly the sequence of scales its own loop on main 0210711 (session 16's:
    main 1d491b2) probed (the loops are transcribed below as they were), so the published numbers stay
    bit-identical.
"""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from qmt_drake.energy.time_optimal import slowdown_search as energy_slowdown
from qmt_drake.errors import QmtInputError
from qmt_drake.jerk import jerk_time_scale
from qmt_drake.margin import OUTWARD_FACTORS, flip_search
from qmt_drake.planners.baselines.finish import slowdown_search as planar_slowdown
from qmt_drake.planners.baselines.ruckig_plan import _largest_scale
from qmt_drake.planners.optimum import _slow_until_confirmed, tight_scale
from qmt_drake.planners.spatial_carried import carried_bisection
from qmt_drake.planners.spatial_trajectory import _raised_until
from qmt_drake.sweep.robust import jerk_bisection, robust_bisection, scale_bisection
from qmt_drake.timescale import Grow, bisect_batch, search_scale, smallest_holding_scale

ROOT = Path(__file__).resolve().parents[1] / "qmt_drake"


# ------------------------------------------------------------------------------------ (a) no other loop
def _midpoint_operands(node):
    """{a, b} if node is 0.5 * (a + b), (a + b) / 2 or [np. | math.]sqrt(a * b) with a, b names or subscripts."""
    def pair(e, op):
        if isinstance(e, ast.BinOp) and isinstance(e.op, op):
            sides = [s.value if isinstance(s, ast.Subscript) else s for s in (e.left, e.right)]
            if all(isinstance(s, ast.Name) for s in sides):
                return {s.id for s in sides}
        return None

    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult):
        for c, e in ((node.left, node.right), (node.right, node.left)):
            if isinstance(c, ast.Constant) and c.value == 0.5:
                return pair(e, ast.Add)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div) and isinstance(node.right, ast.Constant) \
            and node.right.value == 2:
        return pair(node.left, ast.Add)
    if isinstance(node, ast.Call) and len(node.args) == 1:
        f = node.func
        name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else None
        if name == "sqrt":
            return pair(node.args[0], ast.Mult)
    return None


def _assigned(loop) -> dict[str, int]:
    """{name: last line in the loop where it (or an element of it) is assigned}."""
    out = {}
    for n in ast.walk(loop):
        targets = n.targets if isinstance(n, ast.Assign) else [n.target] if isinstance(n, (ast.AugAssign, ast.AnnAssign)) else []
        for t in targets:
            for x in ast.walk(t):
                name = x.id if isinstance(x, ast.Name) else x.value.id if isinstance(x, ast.Subscript) and \
                    isinstance(x.value, ast.Name) else None
                if name is not None:
                    out[name] = max(out.get(name, 0), n.lineno)
    return out


def bisection_loops(source: str) -> list[int]:
    """Lines of the `for` / `while` loops that compute a midpoint of two names (arithmetic or geometric) and
    then, later in the loop, assign one of those names again: the bracket update of every bisection."""
    hits = []
    for loop in ast.walk(ast.parse(source)):
        if not isinstance(loop, (ast.For, ast.While)):
            continue
        assigned = _assigned(loop)
        for n in ast.walk(loop):
            ops = _midpoint_operands(n)
            if ops and len(ops) == 2 and any(assigned.get(o, 0) > n.lineno for o in ops):
                hits.append(loop.lineno)
                break
    return hits


def _scaled_names(loop) -> set[str]:
    """Names the loop reassigns from themselves times something: x *= c, x = x * c, x = min(x * c, cap),
    lo, x = x, 2 * x."""
    out = set()
    for n in ast.walk(loop):
        if isinstance(n, ast.AugAssign) and isinstance(n.op, ast.Mult) and isinstance(n.target, ast.Name):
            out.add(n.target.id)
        if not isinstance(n, ast.Assign):
            continue
        pairs = []
        for t in n.targets:
            if isinstance(t, ast.Tuple) and isinstance(n.value, ast.Tuple) and len(t.elts) == len(n.value.elts):
                pairs += zip(t.elts, n.value.elts)
            else:
                pairs.append((t, n.value))
        for t, v in pairs:
            if isinstance(t, ast.Name) and any(
                    isinstance(b, ast.BinOp) and isinstance(b.op, ast.Mult)
                    and any(isinstance(s, ast.Name) and s.id == t.id for s in (b.left, b.right)) for b in ast.walk(v)):
                out.add(t.id)
    return out


def growth_loops(source: str) -> list[int]:
    """Lines of the loops that grow (or shrink) a name by a factor and probe it, passing it to a call in the
    loop's test or in an `if` test inside the loop: the bracketing steps of every "slow until it holds"."""
    hits = []
    for loop in ast.walk(ast.parse(source)):
        if not isinstance(loop, (ast.For, ast.While)):
            continue
        tests = ([loop.test] if isinstance(loop, ast.While) else []) + [n.test for n in ast.walk(loop)
                                                                           if isinstance(n, ast.If)]
        probed = {a.id for t in tests for c in ast.walk(t) if isinstance(c, ast.Call) for a in c.args
                  if isinstance(a, ast.Name)}
        if _scaled_names(loop) & probed:
            hits.append(loop.lineno)
    return hits


def scale_loops(source: str) -> list[int]:
    """The criterion: a bisection's bracket update or a bracket's growth written as a loop of its own."""
    return sorted(set(bisection_loops(source)) | set(growth_loops(source)))


# Loops the criterion finds that are not a scale search of one plan, or are another helper's this session.
ALLOWED = {  # (timescale.py, the one search itself, takes its midpoints through names the criterion does not follow)
    "planners/spatial_families.py": "bisection in time t for u(t) = a path knot (not a scale)",
    "sweep/certify.py": "certify_time_scale: sequential-test search; sweep/* owned by another helper this session",
}


def test_no_other_module_bisects_a_scale_on_its_own():
    found = {}
    for p in sorted(ROOT.rglob("*.py")):
        hits = scale_loops(p.read_text())
        if hits:
            found[p.relative_to(ROOT).as_posix()] = hits
    extra = sorted(set(found) - set(ALLOWED))
    assert extra == [], f"a scale bisection of its own (use timescale.search_scale): {[(m, found[m]) for m in extra]}"
    stale = sorted(set(ALLOWED) - set(found))
    assert stale == [], f"allowed but no longer found (drop from ALLOWED): {stale}"


OLD_LOOPS = {  # the loops this replaced, as on main 0210711 (abridged to their search): each must fire
    "finish": """
for _ in range(tries):
    if hi >= factor_cap:
        break
    hi = min(hi * 1.5, factor_cap)
    lo = hi
while hi / lo - 1 > rel_tol:
    mid = np.sqrt(lo * hi)
    lo, hi = (lo, mid) if ok(mid) else (mid, hi)
""",
    "ruckig": """
while hi / lo - 1 > rtol and steps < max_steps:
    mid = np.sqrt(lo * hi)
    if ok(mid):
        lo, lo_traj = mid, t
    else:
        hi = mid
""",
    "time_optimal": """
for _ in range(40):
    mid = 0.5 * (lo + hi)
    lo, hi = (mid, hi) if peak(mid)[0] > 1.0 else (lo, mid)
""",
    "spatial_tight": """
for _ in range(TIGHT_MAX_STEPS):
    m = np.where(inside, m, 0.5 * (lo[i] + hi[i]))
    lo[j], g_lo[j], kept[j] = m[left], gm[left], 1
""",
    "robust": """
while not lo_pt["meets_target"] and hi_s / lo_s - 1 > rel_tol:
    mid = math.sqrt(lo_s * hi_s)
    if ok(mid):
        hi_s, best = mid, pt
    else:
        lo_s = mid
""",
    "raised_until": """
while not holds(hi):
    if hi >= k_max:
        raise QmtInputError("...")
    lo, hi = hi, min(hi * 1.1, k_max)
""",
    "jerk": """
while ratio(hi) > 1.0:
    lo, hi = hi, 2.0 * hi
    if hi > JERK_K_MAX:
        raise QmtInputError("...")
""",
    "tight_scale": """
for _ in range(iterations):
    mid = 0.5 * (lo + hi)
    f = problem.peaks(problem.family.time_scaled(g, np.exp(mid))).feasible
    hi, lo = np.where(f, mid, hi), np.where(f, lo, mid)
""",
}


@pytest.mark.parametrize("name", sorted(OLD_LOOPS))
def test_the_criterion_fires_on_the_loops_it_replaced(name):
    assert scale_loops(OLD_LOOPS[name]), name


def test_the_criterion_ignores_a_midpoint_that_is_not_searched():
    assert bisection_loops("for x in xs:\n    c = 0.5 * (a + b)\n    y = x\n") == []
    assert bisection_loops("for a, b in xs:\n    c = 0.5 * (a + b)\n") == []  # a mean of each pair
    assert growth_loops("for x in xs:\n    y = 2.0 * x\n    if ok(y):\n        break\n") == []  # no x probed
    assert growth_loops("while ok(x):\n    y = x * 2\n") == []  # x itself never grows


# ------------------------------------------------------------------------------ (b) closed-form predicate
def _threshold(k_star, probed, safe="above"):
    def holds(k):
        probed.append(k)
        return k >= k_star if safe == "above" else k <= k_star
    return holds


@pytest.mark.parametrize("midpoint", ["arithmetic", "geometric"])
@pytest.mark.parametrize("k_star", [1.0001, 1.37, 2.9999])
def test_bisection_lands_within_rel_tol_above_the_threshold(midpoint, k_star):
    probed = []
    r = search_scale(_threshold(k_star, probed), 1.0, 3.0, midpoint=midpoint, rel_tol=1e-6)
    assert r.status == "bisected" and r.holding == r.hi
    assert k_star <= r.holding <= k_star * (1 + 1e-6)
    assert all(k >= k_star for k in probed if k == r.holding)


@pytest.mark.parametrize("k_star", [0.3, 1.0, 1.6, 7.0, 50.0])
@pytest.mark.parametrize("variant", ["planar", "energy", "carried", "carried_not_planned", "robust", "scale"])
def test_every_variant_answers_a_closed_form(variant, k_star):
    probed = []
    holds = _threshold(k_star, probed)
    if variant == "planar":
        r, tol, top = planar_slowdown(holds, 40.0, 40, 1e-4), 1e-4, 40.0
    elif variant == "energy":
        r, tol, top = energy_slowdown(holds, 4.0), 2.0 ** -30, math.inf
    elif variant in ("carried", "carried_not_planned"):
        r, tol, top = carried_bisection(holds, 10.0, 20, variant == "carried"), 10.0 * 2.0 ** -20, 10.0
    elif variant == "robust":
        r, tol, top = robust_bisection(holds, 1.0, 10.0, 1e-3), 1e-3, 10.0
    else:
        r, tol, top = scale_bisection(holds, 10.0, 1e-3), 1e-3, 10.0
    assert r.holding is None or r.holding >= k_star, "never a scale that fails"
    target = max(k_star, 1.0)  # the bracket starts at 1 (the plan as planned)
    if k_star > top:
        assert r.holding is None
    elif k_star <= 1.0 and variant in ("carried", "robust", "scale"):  # these try 1 itself
        assert r.holding == 1.0  # the planned scale holds: no slowing
    else:  # the others are called once 1 is lost: the answer is then just above it
        assert r.holding is not None and target <= r.holding <= target * (1 + tol) + tol
    assert len(probed) == r.probes


@pytest.mark.parametrize("lam_star", [1e-6, 0.013, 0.5, 0.999, 3.0, 1e5])
def test_a_limit_scale_searched_from_below_answers_a_closed_form(lam_star):
    """Ruckig's variant: the largest lam holding, doubling from 1 while it holds, halving while it fails."""
    class T:
        def __init__(self, lam):
            self.lam, self.duration_s = lam, 1.0 / math.sqrt(lam)

    lam, traj, steps = _largest_scale(T, lambda t: 0.0 if t.lam <= lam_star else 2.0, None, 1e-4, 1e9)
    assert lam is not None and lam <= lam_star and lam >= lam_star / (1 + 1e-4)
    assert traj.lam == lam and steps <= 80


def test_batched_searches_answer_a_closed_form():
    roots = np.array([0.2, 0.5, 0.77, 0.999])
    for midpoint in ("illinois", "arithmetic"):
        def excess(v, i):  # increasing through 0 at the roots, non-linear so the secant is not exact
            return np.tanh(3.0 * (v - roots[i])) + (v - roots[i]) ** 3
        lo, hi = np.full(4, 0.1), np.full(4, 1.0)
        out = bisect_batch(excess, lo.copy(), hi.copy(), excess(lo, np.arange(4)), excess(hi, np.arange(4)),
                           rel_tol=1e-9, max_steps=200, midpoint=midpoint)
        assert np.all(out <= roots) and np.all(out >= roots * (1 - 1e-8)), (midpoint, out - roots)


# ------------------------------------------------------------- (c) the probed sequences of the old loops
def old_smallest_holding_scale(lo, hi, holds, rel_tol):
    while hi / lo - 1.0 > rel_tol:
        mid = 0.5 * (lo + hi)
        if holds(mid):
            hi = mid
        else:
            lo = mid
    return hi


def old_finish(holds, factor_cap, tries, rel_tol):
    lo, hi = 1.0, 1.0
    for _ in range(tries):
        if hi >= factor_cap:
            return hi
        hi = min(hi * 1.5, factor_cap)
        if holds(hi):
            break
        lo = hi
    while hi / lo - 1 > rel_tol:
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if holds(mid) else (mid, hi)
    return hi


def old_largest_scale(make, worst, lam_max, rtol, max_duration_s, max_steps=80):
    steps = 0
    lam = 1.0 if lam_max is None else lam_max
    traj = make(lam)
    steps += 1
    ok = worst(traj) <= 1.0
    if ok and lam_max is not None:
        return lam, traj, steps
    lo = hi = None
    if ok:
        lo, lo_traj = lam, traj
        while steps < max_steps:
            lam *= 2.0
            t = make(lam)
            steps += 1
            if worst(t) <= 1.0:
                if t.duration_s >= lo_traj.duration_s * (1 - 1e-9):
                    return lo, lo_traj, steps
                lo, lo_traj = lam, t
            else:
                hi = lam
                break
        if hi is None:
            return lo, lo_traj, steps
    else:
        hi = lam
        while lam > 1e-12 and steps < max_steps:
            lam *= 0.5
            t = make(lam)
            steps += 1
            if worst(t) <= 1.0:
                lo, lo_traj = lam, t
                break
            if t.duration_s > max_duration_s:
                return None, t, steps
        if lo is None:
            return None, t, steps
    while hi / lo - 1 > rtol and steps < max_steps:
        mid = np.sqrt(lo * hi)
        t = make(mid)
        steps += 1
        if worst(t) <= 1.0:
            lo, lo_traj = mid, t
        else:
            hi = mid
    return lo, lo_traj, steps


def old_time_optimal(peak1, raw_peak):
    lo, hi = 1.0, np.sqrt(raw_peak)
    while peak1(hi) > 1.0:
        hi *= 1.01
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if peak1(mid) > 1.0 else (lo, mid)
    return hi


def old_carried(carried, k_max, iterations, try_planned):
    if try_planned and carried(1.0):
        return 1.0, None
    if not carried(float(k_max)):
        return None, float(k_max)
    lo, hi = 1.0, float(k_max)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if carried(mid) else (mid, hi)
    return hi, lo


def old_robust(meets, s_min, s_max, rel_tol):
    if not meets(s_max):
        return None
    lo_ok = meets(s_min)
    best = s_min if lo_ok else s_max
    lo_s, hi_s = s_min, s_max
    while not lo_ok and hi_s / lo_s - 1 > rel_tol:
        mid = math.sqrt(lo_s * hi_s)
        if meets(mid):
            hi_s, best = mid, mid
        else:
            lo_s = mid
    return best


def old_scale(record, s_max, rel_tol):
    lo, hi = 1.0, float(s_max)
    if record(lo):
        best_s = lo
    else:
        if not record(hi):
            return None, None
        best_s = hi
        while hi / lo - 1 > rel_tol:
            mid = math.sqrt(lo * hi)
            if record(mid):
                hi = best_s = mid
            else:
                lo = mid
    return best_s, (lo if best_s > lo else None)


def old_jerk(record, T_of, lo, hi, rel_tol):
    if not record(lo):
        return None, None
    best_J, best_T = lo, T_of(lo)
    if record(hi):
        best_J = hi
    else:
        T_lost = T_of(hi)
        while best_T / T_lost - 1 > rel_tol and hi / lo > 1.0001:
            mid = math.sqrt(lo * hi)
            if record(mid):
                lo, best_T, best_J = mid, T_of(mid), mid
            else:
                hi, T_lost = mid, T_of(mid)
    return best_J, (hi if best_J < hi else None)


def old_spatial_ruckig(ok, iterations):
    lo, hi = 0.0, 1.0
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ok(mid) else (lo, mid)
    return lo, hi


def old_flip(probe, time_scale, held0, tolerance, max_runs):
    points = []

    def counted(s):
        points.append(s)
        return probe(s)
    same, other = time_scale, None
    for f in OUTWARD_FACTORS:
        if len(points) >= max_runs:
            break
        s = time_scale / f if held0 else time_scale * f
        if counted(s) != held0:
            other = s
            break
        same = s
    while other is not None and max(same, other) / min(same, other) - 1 > tolerance and len(points) < max_runs:
        mid = math.sqrt(same * other)
        if counted(mid) == held0:
            same = mid
        else:
            other = mid
    return same, other


def old_illinois(g, lo, hi, g_lo, g_hi, rel_tol, max_steps):
    kept = np.zeros(len(lo), dtype=int)
    for _ in range(max_steps):
        open_ = hi > lo * (1.0 + rel_tol)
        if not np.any(open_):
            break
        i = np.flatnonzero(open_)
        m = (lo[i] * g_hi[i] - hi[i] * g_lo[i]) / (g_hi[i] - g_lo[i])
        inside = (m > lo[i]) & (m < hi[i])
        m = np.where(inside, m, 0.5 * (lo[i] + hi[i]))
        gm = g(m, i)
        left = gm <= 0.0
        j, k = i[left], i[~left]
        g_hi[j] = np.where(kept[j] == 1, 0.5 * g_hi[j], g_hi[j])
        g_lo[k] = np.where(kept[k] == -1, 0.5 * g_lo[k], g_lo[k])
        lo[j], g_lo[j], kept[j] = m[left], gm[left], 1
        hi[k], g_hi[k], kept[k] = m[~left], gm[~left], -1
    return lo


def old_raised_until(k, holds, k_max, rel_tol):  # planners/spatial_trajectory.py on main 1d491b2
    if holds(k):
        return k
    lo, hi = k, min(k * (1.0 + 16.0 * rel_tol), k_max)
    while not holds(hi):
        if hi >= k_max:
            raise QmtInputError(f"the trajectory breaks a limit between its samples even {k_max:g} times slower; "
                                "relax that limit")
        lo, hi = hi, min(hi * 1.1, k_max)
    return old_smallest_holding_scale(lo, hi, holds, rel_tol)


def old_jerk_doubling(ratio, ratio_before, k_max, rel_tol):  # jerk.jerk_limited_plan on main 1d491b2
    lo, hi = 1.0, 1.0
    if ratio_before > 1.0:
        hi = max(math.sqrt(ratio_before), 1.0 + rel_tol)
        while ratio(hi) > 1.0:
            lo, hi = hi, 2.0 * hi
            if hi > k_max:
                raise QmtInputError(f"the plan's jerk stays over the limit even {k_max:g} times slower; "
                                    "raise actuators.jerk_limit_rad_s3")
        hi = old_smallest_holding_scale(lo, hi, lambda k: ratio(k) <= 1.0, rel_tol)
    return hi


def old_tight_scale(problem, genes, *, lam_max=1e3, iterations=40):  # planners/optimum.py on main 1d491b2
    g = np.atleast_2d(genes)
    peaks = problem.peaks(g)
    ok = peaks.valid & peaks.joint_range_ok & np.isfinite(peaks.worst_ratio)
    if problem.limit_set.time_scaling_is_exact:
        return np.sqrt(np.where(ok, peaks.worst_ratio, np.nan))
    slowest_s = problem.family.motion_time_s(problem.upper[None])[0]
    lam_hi = np.clip(slowest_s / problem.family.motion_time_s(g), 1.0, lam_max)
    lo = np.full(len(g), -np.log(lam_max))
    hi = np.log(lam_hi)
    feasible_hi = problem.peaks(problem.family.time_scaled(g, np.exp(hi))).feasible
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        f = problem.peaks(problem.family.time_scaled(g, np.exp(mid))).feasible
        hi, lo = np.where(f, mid, hi), np.where(f, lo, mid)
    return np.where(ok & feasible_hi, np.exp(hi), np.nan)


def old_slow_until_confirmed(problem, genes, step=1e-6, tries=60):  # planners/optimum.py on main 1d491b2
    for k in range(tries):
        y = problem.family.time_scaled(genes, 1.0 + step * 2**k)[0]
        if problem.confirm(y):
            return y
    return genes


def _predicates():
    """Thresholds inside, below and beyond every bracket, and non-monotone verdicts (a hash of the bits)."""
    out = [("threshold", k) for k in (0.2, 0.999, 1.0, 1.00003, 1.2345, 1.5, 2.0, 2.5, 3.7, 9.99, 40.0, 1e3)]
    return out + [("noise", s) for s in range(8)]


def _recorder(kind, param, safe="above"):
    probed = []

    def holds(k):
        probed.append(float(k))
        if kind == "threshold":
            return k >= param if safe == "above" else k <= 1.0 / param
        return hash((float(k), param)) % 3 != 0
    return holds, probed


def _same(old, new):
    """Bit-identical probe sequences and answers (a float and its np.float64 compare equal only if the bits do)."""
    assert len(old) == len(new) and all(a == b for a, b in zip(old, new)), (old, new)


@pytest.mark.parametrize("kind,param", _predicates())
def test_every_variant_probes_what_its_old_loop_probed(kind, param):
    for lo, hi, tol in ((1.0, 2.5, 1e-4), (1.0, 10.0, 1e-6), (0.9, 1.1, 1e-12)):  # the spatial holding scale
        h0, p0 = _recorder(kind, param)
        h1, p1 = _recorder(kind, param)
        assert old_smallest_holding_scale(lo, hi, h0, tol) == smallest_holding_scale(lo, hi, h1, tol)
        _same(p0, p1)
    for cap, tries in ((math.inf, 40), (3.0, 40), (1.0, 40), (0.5, 40), (1e3, 3), (2.25, 0)):  # planar baselines
        h0, p0 = _recorder(kind, param)
        h1, p1 = _recorder(kind, param)
        assert old_finish(h0, cap, tries, 1e-4) == planar_slowdown(h1, cap, tries, 1e-4).hi
        _same(p0, p1)
    for raw in (1.0004, 1.7, 9.0):  # seed 001's TOPP-RA end
        if kind == "noise" or param > 1.0:  # the old growth never ends if nothing above 1 holds
            h0, p0 = _recorder(kind, param)
            h1, p1 = _recorder(kind, param)
            assert old_time_optimal(lambda k, h0=h0: 0.0 if h0(k) else 2.0, raw) == energy_slowdown(h1, raw).holding
            _same(p0, p1)
    for k_max, its, planned in ((2.5, 7, True), (2.5, 7, False), (1.2, 3, True)):  # spatial --carried
        h0, p0 = _recorder(kind, param)
        h1, p1 = _recorder(kind, param)
        chosen, _lost = old_carried(h0, k_max, its, planned)
        assert chosen == carried_bisection(h1, k_max, its, planned).holding
        _same(p0, p1)
    for s_min, s_max, tol in ((1.0, 1.5, 0.005), (1.0, 2.0, 0.002), (1.2, 1.3, 0.5)):  # sweeps and carried scale
        h0, p0 = _recorder(kind, param)
        h1, p1 = _recorder(kind, param)
        assert old_robust(h0, s_min, s_max, tol) == robust_bisection(h1, s_min, s_max, tol).holding
        _same(p0, p1)
        h0, p0 = _recorder(kind, param)
        h1, p1 = _recorder(kind, param)
        best, lost = old_scale(h0, s_max, tol)
        r = scale_bisection(h1, s_max, tol)
        assert best == r.holding and lost == (r.lo if r.holding is not None and r.holding > r.lo else None)
        _same(p0, p1)


@pytest.mark.parametrize("kind,param", _predicates())
def test_the_spatial_ruckig_factor_probes_what_its_old_loop_probed(kind, param):
    """planners/spatial_methods.ruckig_segments: the largest factor c in (0, 1] of Ruckig's limits, 14 halvings."""
    h0, p0 = _recorder(kind, param, safe="below")
    h1, p1 = _recorder(kind, param, safe="below")
    lo, hi = old_spatial_ruckig(h0, 14)
    r = search_scale(h1, 0.0, 1.0, safe="below", steps=14)
    assert (lo, hi) == (r.lo, r.hi) and r.holding == lo
    _same(p0, p1)


@pytest.mark.parametrize("kind,param", _predicates())
def test_the_margin_flip_probes_what_its_old_loop_probed(kind, param):
    """margin.flip_time_scale: outward from the run's scale by OUTWARD_FACTORS, then geometric, max_runs in all."""
    for ts, tol, runs in ((1.0, 0.01, 12), (1.3, 0.001, 30), (0.8, 0.01, 2), (1.0, 0.5, 1)):
        h = _recorder(kind, param)[0]
        held0 = bool(h(ts))
        h0, p0 = _recorder(kind, param)
        h1, p1 = _recorder(kind, param)
        same, other = old_flip(h0, ts, held0, tol, runs)
        r = flip_search(h1, ts, held0, tol, runs)
        new_same, new_other = (r.hi, r.lo) if held0 else (r.lo, r.hi)
        assert (same, other) == (new_same, None if r.status == "exhausted" else new_other)
        _same(p0, p1)


@pytest.mark.parametrize("kind,param", _predicates())
def test_the_jerk_search_probes_what_its_old_loop_probed(kind, param):
    T_of = lambda J: 1.0 / J ** (1 / 3)  # noqa: E731  a line's motion time falls as J^(-1/3)
    for lo, hi, tol in ((0.3, 300.0, 0.002), (1.0, 300.0, 0.01), (1.0, 1.00005, 0.002)):
        h0, p0 = _recorder(kind, param, safe="below")
        h1, p1 = _recorder(kind, param, safe="below")
        best, lost = old_jerk(h0, T_of, lo, hi, tol)
        r = jerk_bisection(h1, T_of, lo, hi, tol)
        assert best == r.holding and lost == (r.hi if r.holding is not None and r.holding < r.hi else None)
        _same(p0, p1)


@pytest.mark.parametrize("lam_star", [1e-13, 1e-7, 0.3, 0.99, 1.0, 1.7, 1e4, 1e30])
@pytest.mark.parametrize("lam_max", [None, 1.0 - 1e-9])
@pytest.mark.parametrize("jerk_bound", [False, True])
def test_ruckig_probes_what_its_old_loop_probed(lam_star, lam_max, jerk_bound):
    class T:  # a profile: the duration stops falling once the jerk binds (lam above 50)
        def __init__(self, lam):
            self.lam = lam
            self.duration_s = 1.0 / math.sqrt(min(lam, 50.0) if jerk_bound else lam)

    runs = []
    for fn in (old_largest_scale, _largest_scale):
        probed = []

        def make(lam, probed=probed):
            probed.append(float(lam))
            return T(lam)
        lam, traj, steps = fn(make, lambda t: 0.5 if t.lam <= lam_star else 2.0, lam_max, 1e-4, 30.0)
        runs.append((lam, traj.lam, steps, probed))
    assert runs[0][:3] == runs[1][:3]
    _same(runs[0][3], runs[1][3])


def test_the_batched_search_is_the_old_illinois_loop():
    rng = np.random.default_rng(3)
    roots = rng.uniform(0.2, 0.9, 40)
    calls = [[], []]

    def g_of(which):
        def g(v, i):
            calls[which].append((v.copy(), i.copy()))
            return np.where(v > roots[i], np.sqrt(np.abs(v - roots[i])), -((roots[i] - v) ** 2))
        return g
    lo, hi = np.full(40, 0.1), np.full(40, 1.0)
    g_lo = -((roots - lo) ** 2)
    g_hi = (hi - roots) ** 0.5
    a = old_illinois(g_of(0), lo.copy(), hi.copy(), g_lo.copy(), g_hi.copy(), 1e-9, 60)
    b = bisect_batch(g_of(1), lo.copy(), hi.copy(), g_lo.copy(), g_hi.copy(), rel_tol=1e-9, max_steps=60)
    assert np.array_equal(a, b)
    assert len(calls[0]) == len(calls[1])
    assert all(np.array_equal(x[0], y[0]) and np.array_equal(x[1], y[1]) for x, y in zip(*calls))


def test_a_grow_from_a_holding_start_stops_when_the_caller_says():
    seen = []
    r = search_scale(lambda x: seen.append(x) or True, safe="below", grow=Grow(start=1.0, factor=2.0, start_holds=True),
                     stop=lambda x, held, kept: x >= 8.0, max_probes=80)
    assert r.status == "stopped" and r.holding == 4.0 and seen == [2.0, 4.0, 8.0]


def _outcome(fn, *args):
    """fn's answer, or the message of the QmtInputError it raised."""
    try:
        return fn(*args)
    except QmtInputError as e:
        return ("raised", str(e))


@pytest.mark.parametrize("kind,param", _predicates())
def test_the_refined_raise_probes_what_its_old_loop_probed(kind, param):
    """spatial_trajectory._raised_until: k if it holds, else 1 + 16 rel_tol, then 10 % steps up to k_max, bisected."""
    for k, k_max, tol in ((1.0, 20.0, 1e-4), (1.37, 20.0, 1e-4), (1.0, 1.5, 1e-4), (19.99, 20.0, 1e-4),
                          (20.0, 20.0, 1e-4), (2.0, 1e3, 1e-6)):
        h0, p0 = _recorder(kind, param)
        h1, p1 = _recorder(kind, param)
        assert _outcome(old_raised_until, k, h0, k_max, tol) == _outcome(_raised_until, k, h1, k_max, tol)
        _same(p0, p1)


@pytest.mark.parametrize("kind,param", _predicates())
def test_the_jerk_doubling_probes_what_its_old_loop_probed(kind, param):
    """jerk.jerk_time_scale: doubling from sqrt(ratio before) while over, no step beyond k_max, then bisected."""
    for before, k_max in ((0.5, 1e4), (1.0, 1e4), (1.00001, 1e4), (4.0, 1e4), (2.3, 1e4), (1e6, 1e4),
                          (1e9, 1e4), (4.0, 64.0), (4.0, 63.9), (4.0, 2.0)):
        h0, p0 = _recorder(kind, param)
        h1, p1 = _recorder(kind, param)
        r0, r1 = (lambda k, h=h: 0.5 if h(k) else 2.0 for h in (h0, h1))
        old = _outcome(old_jerk_doubling, r0, before, k_max, 1e-4)
        new = _outcome(jerk_time_scale, r1, before, "the plan's", k_max, 1e-4)
        assert old == new, (before, k_max)
        _same(p0, p1)


class _Batch:
    """A stand-in planning problem for tight_scale: a row's gene 0 is its duration (s, scaled by lam), gene 1
    its threshold; it holds at lam iff duration >= threshold (or a hash of the bits: non-monotone); rows with
    gene 2 < 0 are invalid. Records every batch of genes it is asked about."""

    class limit_set:
        time_scaling_is_exact = False

    def __init__(self, kind, param):
        self.kind, self.param, self.asked = kind, param, []
        self.upper = np.array([6.0, 1.0, 1.0])
        self.family = self

    def motion_time_s(self, g):
        return np.atleast_2d(g)[:, 0].copy()

    def time_scaled(self, g, lam):
        g = np.atleast_2d(np.asarray(g, float))
        return g * np.asarray(lam, float).reshape(-1, 1) ** np.array([1, 0, 0])

    def peaks(self, g):
        self.asked.append(np.array(g, copy=True))
        if self.kind == "threshold":
            f = g[:, 0] >= g[:, 1] * self.param
        else:
            f = np.array([hash((float(a), float(b), self.param)) % 3 != 0 for a, b in g[:, :2]])
        valid = g[:, 2] >= 0
        return type("Peaks", (), {"valid": valid, "joint_range_ok": np.ones(len(g), bool), "feasible": f & valid,
                                  "worst_ratio": np.where(f, 0.5, 2.0)})


@pytest.mark.parametrize("kind,param", _predicates())
def test_the_ga_tight_scale_asks_what_its_old_loop_asked(kind, param):
    """planners/optimum.tight_scale (timescale.bisect_batch, fixed rounds over the whole batch, safe above):
    the same batches of genes in the same order, and the same lam to the bit."""
    rng = np.random.default_rng(11)
    g = np.column_stack([rng.uniform(0.05, 8.0, 30), rng.uniform(0.01, 3.0, 30), rng.uniform(-0.2, 1.0, 30)])
    for lam_max, iterations in ((1e3, 40), (50.0, 7), (1.5, 0)):
        old, new = _Batch(kind, param), _Batch(kind, param)
        a = old_tight_scale(old, g, lam_max=lam_max, iterations=iterations)
        b = tight_scale(new, g, lam_max=lam_max, iterations=iterations)
        assert np.array_equal(a, b, equal_nan=True)
        assert len(old.asked) == len(new.asked) == iterations + 2
        assert all(np.array_equal(x, y) for x, y in zip(old.asked, new.asked))


def test_the_ga_tight_scale_of_a_planar_arm_with_gravity_is_the_old_loops():
    """The same on a real problem whose limits are not exact under time scaling (crane-tray: gravity)."""
    from qmt_drake.problem import PlanningProblem
    from qmt_drake.transfer_scenario import load_scenario
    P = PlanningProblem(load_scenario("crane-tray"))
    assert not P.limit_set.time_scaling_is_exact
    g = P.lower + (P.upper - P.lower) * np.random.default_rng(5).random((3, P.lower.size))
    n0 = P.evaluations
    a = old_tight_scale(P, g, iterations=8)  # (40 halvings of 25 rows: 22 s; the same to the bit, checked once)
    n1 = P.evaluations
    b = tight_scale(P, g, iterations=8)
    assert np.array_equal(a, b, equal_nan=True) and np.any(np.isfinite(a))
    assert P.evaluations - n1 == n1 - n0  # the GA's evaluation count too


def test_a_batch_searched_from_above_answers_a_closed_form():
    """bisect_batch with safe="above" and the Illinois midpoint: the smallest x holding of a decreasing excess."""
    roots = np.array([0.2, 0.5, 0.77, 0.999])

    def excess(v, i):
        return -(np.tanh(3.0 * (v - roots[i])) + (v - roots[i]) ** 3)
    lo, hi = np.full(4, 0.1), np.full(4, 1.0)
    out = bisect_batch(excess, lo.copy(), hi.copy(), excess(lo, np.arange(4)), excess(hi, np.arange(4)),
                       rel_tol=1e-9, max_steps=200, safe="above")
    assert np.all(out >= roots) and np.all(out <= roots * (1 + 1e-8)), out - roots


@pytest.mark.parametrize("kind,param", _predicates())
def test_the_optimums_confirming_slowdown_probes_what_its_old_loop_probed(kind, param):
    """planners/optimum._slow_until_confirmed: 1 + 1e-6 2^k for k < tries until confirmed (Grow.table, steps=0)."""
    class Confirming(_Batch):
        def confirm(self, y):
            return self.holds(float(y[0]))

    genes = np.array([1.0, 0.3, 1.0])
    for step, tries in ((1e-6, 60), (1e-3, 5), (0.5, 3), (1e-6, 0)):
        runs = []
        for fn in (old_slow_until_confirmed, _slow_until_confirmed):
            problem = Confirming(kind, param)
            problem.holds, probed = _recorder(kind, param)
            runs.append((fn(problem, genes, step, tries), probed))
        assert np.array_equal(runs[0][0], runs[1][0])
        _same(runs[0][1], runs[1][1])


def test_a_growth_with_neither_factor_nor_table_is_refused():
    with pytest.raises(ValueError, match="factor > 0 or a non-empty table"):
        search_scale(lambda x: True, grow=Grow(start=1.0, table=()))
