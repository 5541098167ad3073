"""A collision-free path for the arm and its carried part (docs/obstacles.md, "The collision-free path"):
a sampling planner in joint space whose path is shortcut, smoothed into the C2 cubic every planner
times, and certified clear between its samples; then any planner and family times it.

    sc_free, info = collision_free_scenario(load_spatial_scenario("docs/examples/ur5-deep-totes.yaml"), seed=0)
    plan_toppra_spatial(sc_free)        # or any registry method: the task is now the collision-free path

1. RRT-Connect (Kuffner and LaValle 2000) from each task pose's joints to the next's (through="poses", the
   default: the task's lifts kept) or from the first to the last only ("ends": the inner poses dropped), in the box of
   the task path's joint values padded by BOX_PAD_RAD (inside the URDF ranges) first; a leg it does not join
   within MAX_NODES iterations is planned again in the whole joint ranges (the same generator carried on:
   deterministic given the seed; a detour wider than the pad, e.g. round a tall wall). A configuration is valid
   when Drake's signed distance of the arm's and the part's shapes from the obstacles
   (limits/clearance.CollisionModel) is at least margin_m and the hand's face normal is within
   max_tilt_rad of one of the task path's normals (a suction cup, a magnet and a tray are held near
   their task orientation; the hand's contact limits are TOPP-RA's rows afterwards). Distances are the
   `weighted` point-displacement bound sum_j rho_j |dq_j| (m; rho_j: CollisionModel.speed_radii_m, every
   point of the arm and part within rho_j of joint j's axis): an edge is checked every EDGE_STEP_M of it.
2. Shortcut: SHORTCUT_TRIES random pairs of points along the path (seeded) joined by a straight edge where
   that edge is valid; then waypoints that a straight edge can skip are dropped.
3. Smooth: the shortcut's vertices are the waypoints of spatial_toppra.joint_path (the C2 cubic in chord
   length that TOPP-RA and retime time; fewer waypoints, gentler turns: on the deep totes, points every 6 cm
   of the polyline took TOPP-RA 3.31 s, its vertices alone 2.56 s, same seed). That spline is
   certified (limits/clearance.certified_clearance on the path in its chord length, a Lipschitz bound
   between samples, tolerance CERTIFY_TOL_M), its tilt and the hand's limit ratio holding still sampled
   (50 a radian); where the certified lower bound is below margin_m / 2, the tilt exceeds max_tilt_rad +
   TILT_SLACK_RAD or the ratio at rest HOLD_AT_REST_MAX, the polyline's edges around that spot are
   halved, up to SMOOTH_ROUNDS times. A path that still does not clear is refused (QmtNoPlanError).

Deterministic given seed (numpy's default_rng). `collision_free_scenario` returns the scenario whose task is
this path: the shortcut's vertices are its task poses (hand positions and normals by Drake's forward
kinematics), the smoothed waypoints its geometric path (q_path_rad), so TOPP-RA (via_cubic) times exactly
the certified path and the other planners and families pass the same vertices (their shapes in between are
their own: the plan's clearance re-check, spatial_plan_io, tells whether they clear).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from qmt_drake.errors import QmtInputError, QmtNoPlanError
from qmt_drake.limits.clearance import certified_clearance, collision_model
from qmt_drake.limits.spatial_columns import joint_range_by_name
from qmt_drake.planners.spatial_toppra import joint_path, plan_toppra
from qmt_drake.planners.spatial_trajectory import PolyTrajectory, ToppraTrajectory

MARGIN_M = 0.005  # the planner's clearance at its configurations; the smoothed path is certified >= MARGIN_M / 2
MAX_TILT_RAD = 0.15
TILT_SLACK_RAD = 0.05
HOLD_AT_REST_MAX = 0.95  # the smoothed path: the hand's limit ratio holding still at most this (a TOPP-RA timing exists)
BOX_PAD_RAD = 0.5
STEP_M = 0.08  # RRT-Connect's extension step (point-displacement bound)
EDGE_STEP_M = 0.01
MAX_NODES = 4000
SHORTCUT_TRIES = 150
SMOOTH_ROUNDS = 8
CERTIFY_PER_RAD = 400  # the path's certification samples per radian of chord length (then halved as needed)
CERTIFY_TOL_M = 2e-4
TRY_GRID = 400  # TOPP-RA's grid when choosing between tries
THROUGH = ("poses", "ends")  # the path passes every task pose (one leg each), or only the first and the last


class Checker:
    """Validity of configurations and edges (module docstring, step 1)."""

    def __init__(self, sc, margin_m: float, max_tilt_rad: float) -> None:
        self.sc, self.cm, self.margin = sc, collision_model(sc), float(margin_m)
        self.rho = self.cm.speed_radii_m
        self.normals = np.asarray(sc.path_normals, float)
        self.cos_tilt = float(np.cos(max_tilt_rad))
        self.lo, self.hi = (np.asarray(v, float) for v in joint_range_by_name(sc.plant, sc.joint_names))
        self.checks = 0

    def tilt(self, q) -> float:
        """The hand's face normal's angle (rad) from the nearest task path normal."""
        n = self.sc.ik.pose(q)[1] @ self.sc.ik.face_axis
        return float(np.arccos(np.clip(np.max(self.normals @ n), -1.0, 1.0)))

    def valid(self, q) -> bool:
        self.checks += 1
        if (q < self.lo).any() or (q > self.hi).any():
            return False
        if np.max(self.normals @ (self.sc.ik.pose(q)[1] @ self.sc.ik.face_axis)) < self.cos_tilt:
            return False
        return self.cm.distance(q)[0] >= self.margin

    def length(self, qa, qb) -> float:
        return float(np.abs(np.asarray(qb) - qa) @ self.rho)

    def edge(self, qa, qb) -> bool:
        """Every EDGE_STEP_M (point displacement) of the straight edge valid (qa assumed valid), looked at
        in bisection order (the end, the middle, the quarters, ...: a blocked edge fails early)."""
        k = max(int(np.ceil(self.length(qa, qb) / EDGE_STEP_M)), 1)
        return all(self.valid(qa + (qb - qa) * (i / k)) for i in _bisection_order(k))


def _bisection_order(k: int) -> list[int]:
    """1..k, k first, then the midpoints of ever finer halvings."""
    out, seen, step = [k], {k}, k
    while step > 1:
        step = (step + 1) // 2
        for i in range(step, k, step):
            if i not in seen:
                seen.add(i)
                out.append(i)
    return out + [i for i in range(1, k) if i not in seen]


def _extend(chk, tree, parent, q_to) -> tuple[str, int]:
    """One RRT step of at most STEP_M from the tree's nearest node towards q_to: ('reached'|'advanced'|
    'trapped', index of the new node)."""
    nodes = np.asarray(tree)
    i = int(np.argmin(np.abs(nodes - q_to) @ chk.rho))
    q_near = nodes[i]
    d = chk.length(q_near, q_to)
    q_new = q_to if d <= STEP_M else q_near + (q_to - q_near) * (STEP_M / d)
    if not chk.edge(q_near, q_new):
        return "trapped", -1
    tree.append(q_new)
    parent.append(i)
    return ("reached" if d <= STEP_M else "advanced"), len(tree) - 1


def _trace(tree, parent, k) -> list:
    out = []
    while k >= 0:
        out.append(tree[k])
        k = parent[k]
    return out


def rrt_connect(chk, qa, qb, rng, box, where: str = "") -> list:
    """Joint-space RRT-Connect from qa to qb ((K, n) path incl. both), sampling uniformly in box (lo, hi);
    QmtNoPlanError after MAX_NODES iterations (`where` says which boxes were tried)."""
    if chk.edge(qa, qb):
        return [qa, qb]
    trees = ([qa], [-1], [qb], [-1])
    a_tree, a_par, b_tree, b_par = trees
    for _ in range(MAX_NODES):
        q_rand = rng.uniform(*box)
        status, k = _extend(chk, a_tree, a_par, q_rand)
        if status != "trapped":
            target = a_tree[k]
            while True:  # connect: the other tree goes straight for the new node
                s2, k2 = _extend(chk, b_tree, b_par, target)
                if s2 != "advanced":
                    break
            if s2 == "reached":
                pa, pb = _trace(a_tree, a_par, k), _trace(b_tree, b_par, k2)
                path = pa[::-1] + pb[1:]
                return path if np.array_equal(path[0], qa) else path[::-1]
        a_tree, a_par, b_tree, b_par = b_tree, b_par, a_tree, a_par
    raise QmtNoPlanError(f"collision-free path: RRT-Connect joined no path within {MAX_NODES} iterations "
                         f"(margin {chk.margin * 1e3:.1f} mm{where}); lower the margin or widen the tilt")


def rrt_widening(chk, qa, qb, rng, boxes) -> tuple[list, int]:
    """(path, index of the box it was found in): rrt_connect in each box of `boxes` in turn (the task's
    box first, then the joint ranges), each with its own MAX_NODES budget, the same generator carried on
    (deterministic given the seed; a leg the first box joins is the very path of a single try)."""
    for k, box in enumerate(boxes[:-1]):
        try:
            return rrt_connect(chk, qa, qb, rng, box), k
        except QmtNoPlanError:  # not joined within its budget: the next, wider box
            pass
    where = ", in the task's box, then in the joint ranges" if len(boxes) > 1 else ""
    return rrt_connect(chk, qa, qb, rng, boxes[-1], where), len(boxes) - 1


def shortcut(chk, path, rng, tries: int = SHORTCUT_TRIES) -> np.ndarray:
    """The path shortcut (module docstring, step 2)."""
    P = [np.asarray(q, float) for q in path]
    for _ in range(tries):
        if len(P) < 3:
            break
        seg = np.array([chk.length(a, b) for a, b in zip(P[:-1], P[1:])])
        c = np.r_[0.0, np.cumsum(seg)]
        u, v = np.sort(rng.uniform(0.0, c[-1], 2))
        i, j = (int(np.clip(np.searchsorted(c, x, side="right") - 1, 0, len(seg) - 1)) for x in (u, v))
        if i == j:
            continue
        qu = P[i] + (P[i + 1] - P[i]) * (u - c[i]) / seg[i]
        qv = P[j] + (P[j + 1] - P[j]) * (v - c[j]) / seg[j]
        if chk.edge(qu, qv):
            P = P[:i + 1] + [qu, qv] + P[j + 1:]
    k = 0
    while k < len(P) - 2:  # drop a waypoint that a straight edge skips
        if chk.edge(P[k], P[k + 2]):
            del P[k + 1]
        else:
            k += 1
    return np.array(P)


def hold_at_rest(sc, q) -> np.ndarray:
    """(S,) the hand's largest limit ratio holding still at each of the joint states q (S, n) (0 for a stand-in
    scenario without the arm's chain)."""
    if not hasattr(sc, "chain"):
        return np.zeros(len(q))
    zero = np.zeros_like(q)
    return sc.hand_term().columns(sc.chain.evaluate(q, zero, zero)).max(axis=1)


def smooth(chk, V, margin_m: float, max_tilt_rad: float) -> dict:
    """The certified C2 path through the polyline V (module docstring, step 3)."""
    V = np.asarray(V, float)
    is_vertex = np.ones(len(V), bool)  # the shortcut's vertices; halving adds points that are not
    lo, hi = chk.lo, chk.hi
    for rounds in range(SMOOTH_ROUNDS + 1):
        Q, idx = V, np.flatnonzero(is_vertex)
        pp = joint_path(Q, lo, hi)
        path = PolyTrajectory(pp)  # the path in its chord length s (rad) as a trajectory: sampled in s
        cert = certified_clearance(chk.sc, path, CERTIFY_PER_RAD, tol_m=CERTIFY_TOL_M)
        s = np.linspace(0.0, path.duration_s, max(int(path.duration_s * 50), 2))
        qs = path.sample(s)[0]
        tilts = np.array([chk.tilt(q) for q in qs])
        held = hold_at_rest(chk.sc, qs)
        bad_s = [cert["clearance_time_s"]] if cert["clearance_lower_bound_m"] < 0.5 * margin_m else []
        bad_s += list(s[(tilts > max_tilt_rad + TILT_SLACK_RAD) | (held > HOLD_AT_REST_MAX)])
        if not bad_s:
            return {"Q": Q, "vertex_index": idx, "vertices": V, "certificate": cert, "smooth_rounds": rounds,
                    "max_tilt_rad": float(tilts.max()), "max_hold_ratio_at_rest": float(held.max()), "path": path}
        s_v = np.asarray(pp.get_segment_times())  # halve the polyline's edges next to each bad spot
        split = sorted({int(np.clip(np.searchsorted(s_v, x) - 1, 0, len(V) - 2)) for x in bad_s})
        split = sorted(set(split) | {max(k - 1, 0) for k in split} | {min(k + 1, len(V) - 2) for k in split})
        for k in reversed(split):
            V = np.insert(V, k + 1, 0.5 * (V[k] + V[k + 1]), axis=0)
            is_vertex = np.insert(is_vertex, k + 1, False)
    raise QmtNoPlanError(f"collision-free path: its smoothed spline still comes within "
                         f"{cert['clearance_lower_bound_m'] * 1e3:.2f} mm (certified), tilts {tilts.max():.2f} rad "
                         f"or needs {held.max():.3f} of the hand's limit at rest after {SMOOTH_ROUNDS} refinements; "
                         "lower the margin")


def collision_free_path(sc, *, margin_m: float = MARGIN_M, seed: int = 0, max_tilt_rad: float = MAX_TILT_RAD,
                        box_pad_rad: float = BOX_PAD_RAD, through: str = "poses", widen: bool = True) -> dict:
    """The certified collision-free path from the first to the last task pose (module docstring): Q (K, n)
    waypoints of the smoothed spline, vertex_index, vertices (the shortcut's), certificate
    (certified_clearance of the spline in its chord length), counts, widened_legs (the legs joined only in
    the joint ranges: module docstring, step 1; widen=False: the task's box only)."""
    if not sc.obstacles:
        raise QmtInputError(f"scenario {sc.name} has no world.obstacles: nothing to avoid; drop the collision-free "
                            "path option or describe the cell (docs/obstacles.md)")
    if not (np.isfinite(margin_m) and margin_m > 0):
        raise QmtInputError(f"collision-free margin {margin_m!r} must be a positive distance in m (e.g. 0.005)")
    if through not in THROUGH:
        raise QmtInputError(f"collision-free path through {through!r}: give one of {', '.join(THROUGH)}")
    chk = Checker(sc, margin_m, max_tilt_rad)
    Qs = np.asarray(sc.q_poses_rad, float)
    stops = list(range(len(Qs))) if through == "poses" else [0, len(Qs) - 1]
    for k in stops:
        if not chk.valid(Qs[k]):
            d = chk.cm.distance(Qs[k])
            if d[0] < 0.0:  # a margin cannot help a pose that overlaps an obstacle
                raise QmtInputError(f"collision-free path: task pose {k} collides with {d[2]} by {-d[0] * 1e3:.1f} mm "
                                    f"({d[1]}); move the obstacle or the pose")
            raise QmtInputError(f"collision-free path: task pose {k} is itself within the margin or tilted "
                                f"({d[0] * 1e3:.1f} mm, {d[1]} vs {d[2]}); give a margin below it")
    rng = np.random.default_rng(seed)
    Qp = np.asarray(sc.q_path_rad, float)
    box = (np.maximum(Qp.min(axis=0) - box_pad_rad, chk.lo), np.minimum(Qp.max(axis=0) + box_pad_rad, chk.hi))
    boxes = [box] + ([(chk.lo, chk.hi)] if widen and not (np.array_equal(box[0], chk.lo)
                                                          and np.array_equal(box[1], chk.hi)) else [])
    V, n_raw, widened = [Qs[stops[0]]], 0, []
    for leg, (a, b) in enumerate(zip(stops[:-1], stops[1:])):  # one RRT-Connect and shortcut per leg between stops
        raw, k = rrt_widening(chk, Qs[a], Qs[b], rng, boxes)
        if k:
            widened.append(leg)
        V += list(shortcut(chk, raw, rng)[1:])
        n_raw += len(raw) - 1
    out = smooth(chk, np.array(V), margin_m, max_tilt_rad)
    return {**out, "rrt_waypoints": n_raw + 1, "checks": chk.checks, "margin_m": margin_m, "seed": seed,
            "through": through, "widened_legs": widened}


def toppra_time_s(sc, pp) -> float:
    """TOPP-RA's time (s) along the path pp under the scenario's limits (the planners' spatial TOPP-RA)."""
    r = plan_toppra(pp, sc.chain, velocity_limit=sc.velocity_limit_rad_s, acceleration_limit=sc.acceleration_limit_rad_s2,
                    terms=sc.terms(), n_grid=TRY_GRID)
    return float(ToppraTrajectory(pp, r["grid"], r["sd"]).duration_s)


def collision_free_scenario(sc, *, margin_m: float = MARGIN_M, seed: int = 0, tries: int = 1,
                            max_tilt_rad: float = MAX_TILT_RAD, through: str = "poses") -> tuple:
    """(scenario whose task is the collision-free path, the path's facts) (module docstring); tries > 1:
    the paths of seeds seed, seed + 1, ..., the one TOPP-RA times fastest kept (a path TOPP-RA cannot time,
    e.g. the hand's limit broken at rest, is passed over)."""
    if not (isinstance(tries, int) and tries >= 1):
        raise QmtInputError(f"collision-free tries {tries!r} must be an integer >= 1 (seeded paths to choose from)")
    best = None
    for k in range(tries):
        r = collision_free_path(sc, margin_m=margin_m, seed=seed + k, max_tilt_rad=max_tilt_rad, through=through)
        try:
            r["toppra_time_s"] = toppra_time_s(sc, r["path"].pp)
        except QmtInputError:
            r["toppra_time_s"] = np.inf
        if best is None or r["toppra_time_s"] < best["toppra_time_s"]:
            best = r
    r = best
    Q, idx = r["Q"], r["vertex_index"]
    poses = [sc.ik.pose(q) for q in Q]
    pts = np.array([p for p, _ in poses])
    normals = np.array([R @ sc.ik.face_axis for _, R in poses])
    rot = None if sc.pose_rotations is None else np.array([R for _, R in poses])
    new = replace(sc, q_path_rad=Q, path_points_m=pts, path_normals=normals, path_rotations=rot,
                  path_pose_index=idx, q_poses_rad=Q[idx], poses_m=pts[idx], pose_normals=normals[idx],
                  pose_rotations=None if rot is None else rot[idx])
    c = r["certificate"]
    facts = {"margin_m": margin_m, "through": through, "seed": r["seed"], "tries": tries, "tilt_limit_rad": max_tilt_rad, "toppra_time_s": r["toppra_time_s"],
             "rrt_waypoints": r["rrt_waypoints"], "vertices": len(idx),
             "waypoints": len(Q), "smooth_rounds": r["smooth_rounds"], "validity_checks": r["checks"],
             "path_length_rad": float(r["path"].duration_s), "max_tilt_rad": r["max_tilt_rad"],
             "max_hold_ratio_at_rest": r["max_hold_ratio_at_rest"],
             "path_clearance_m": c["clearance_m"], "path_clearance_lower_bound_m": c["clearance_lower_bound_m"],
             "path_clearance_pair": c["clearance_pair"], "path_certificate_samples": c["clearance_samples"]}
    return new, facts
