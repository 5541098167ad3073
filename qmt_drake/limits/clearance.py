"""Clearance of a spatial arm and its carried part from the scenario's obstacles, by Drake's signed
distance, independently of any planner.

`CollisionModel(sc)` builds, once per scenario (cached), a MultibodyPlant of the arm (load_arm_plant)
registered with a SceneGraph: the arm's links carry the URDF's own <collision> shapes (boxes,
cylinders, spheres, meshes as their convex hulls: Drake's signed distance works on convex shapes; .stl
meshes, which Drake does not load, through their vertices, model/obstacles.read_mesh_points), the hand
carries the part (`carried_shapes`), and the world carries `sc.obstacles`. The arm's own pairs (self
and adjacent links) and the obstacles' pairs are filtered out, and so is every link welded to the world
(the base does not move: Drake filters it against the world's geometry), so
QueryObject.ComputeSignedDistancePairwiseClosestPoints returns exactly the moving-arm/part-against-
obstacle pairs.

`clearance(sc, traj, rate_hz)` samples a plan at rate_hz (the re-check rate), then refines around the
REFINE_MINIMA smallest local minima of the sampled distance (REFINE_PASSES passes of REFINE_POINTS
points between the neighbouring samples), and returns the smallest signed distance (m; < 0: the two
shapes overlap by that depth), the pair and the time. `clearance_of_states(sc, t, q, every=k)` does the
same on given joint states (the co-simulation's logged motion, sim/spatial_cosim.py): every k-th state,
then every state within k of the local minima less than REFINE_BAND_M above the smallest.

`certified_clearance(sc, traj, rate_hz, tol_m)` bounds the clearance BETWEEN samples: every point of the
arm's and part's shapes lies within rho_j of joint j's axis (`CollisionModel.speed_radii_m`: each shape's
bounding ball carried inwards joint by joint by the triangle inequality, the same at every configuration), so
no point moves faster than v = sum_j rho_j |qd_j| and the signed distance (the smallest over the pairs, capped
at HORIZON_M) changes no faster than v. On an interval [a, b] of length h with the speed bound V =
max(v_a, v_b) + h max(a_a, a_b) (a = sum_j rho_j |qdd_j|: the speed's change within the interval, first order)
the clearance is at least (d_a + d_b - V h) / 2; intervals whose bound is below the smallest found less tol_m
are halved until none is, so the true smallest lies in [clearance_lower_bound_m, clearance_m] and the two
differ by at most tol_m. The plans' re-check (`clearance`, above) is unchanged (the published numbers and the
golden files); the certified value is what the collision-free path (planners/collision_free.py) and
studies/obstacles_clearance --collision-free report.

The carried part's shape (`carried_shapes`): a suction or magnet hand's part is the solid box with the
payload's principal moments (a^2 = 6 (I_yy + I_zz - I_xx) / m, ...) centred at its centre of mass, in the
hand's axes; a tray hand's tray is its box (tray_size_m, upper face through the hand frame's origin) and
the cup a cylinder standing on the tray's centre.
"""

from __future__ import annotations

import heapq
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    Box,
    CollisionFilterDeclaration,
    Convex,
    Cylinder,
    GeometrySet,
    SceneGraph,
    Sphere,
)
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.systems.framework import DiagramBuilder

from qmt_drake.errors import QmtInputError
from qmt_drake.limits.contact_wrench import face_basis
from qmt_drake.model.obstacles import proximity, read_mesh_points, register_obstacles
from qmt_drake.model.urdf_check import load_arm_plant
from qmt_drake.model.urdf_package import mesh_file
from qmt_drake.planners.spatial_trajectory import sample_times

HORIZON_M = 0.1  # pairs farther apart are not computed: a clearance above it is reported as HORIZON_M, no pair
REFINE_MINIMA = 3
REFINE_PASSES = 2
REFINE_POINTS = 21
MIN_PART_SIDE_M = 1e-3
CERTIFY_TOL_M = 2e-4  # certified_clearance: the reported smallest is within this of the true smallest
REFINE_BAND_M = 0.02  # logged states: a minimum this close to the smallest is looked at state by state
_MODELS: dict = {}


def carried_shapes(sc) -> list[tuple[str, object, RigidTransform]]:
    """[(name, Shape, X_HG)] of what the hand carries (module docstring), in the hand frame H."""
    if sc.hand_kind == "tray":
        cup = sc.cup
        R = RotationMatrix(face_basis(sc.face_axis).T)  # the tray frame's z is the face axis (sim/spatial_cosim)
        a, b, c = cup.tray_size_m
        return [("tray", Box(a, b, c), RigidTransform(R, R @ np.array([0.0, 0.0, -c / 2]))),
                ("cup", Cylinder(cup.radius_m, cup.height_m),
                 RigidTransform(R, R @ np.array([0.0, 0.0, cup.height_m / 2])))]
    b = sc.body
    m, Ixx, Iyy, Izz = b.mass_kg, *np.diag(np.asarray(b.inertia_kgm2, float))
    sq = 6.0 / m * np.array([Iyy + Izz - Ixx, Ixx + Izz - Iyy, Ixx + Iyy - Izz])
    side = np.sqrt(np.maximum(sq, MIN_PART_SIDE_M ** 2))
    return [("part", Box(*side), RigidTransform(np.asarray(b.com_m, float)))]


def _mesh_path(uri: str, urdf: Path, where: str) -> Path:
    """A URDF mesh filename as a file (model/urdf_package.mesh_file); one line if it cannot be found."""
    path = mesh_file(uri, urdf)
    if path is None:
        raise QmtInputError(f"{where}: mesh {uri} not found above {urdf} nor in an installed package; install the "
                            "package or give the mesh's path")
    return path


def urdf_collision_shapes(urdf: Path) -> list[tuple[str, str, object, RigidTransform]]:
    """[(link, name, Shape, X_LG)] of the URDF's <collision> elements (meshes as convex hulls)."""
    urdf = Path(urdf)
    out = []
    for link in ET.parse(urdf).getroot().findall("link"):
        for k, col in enumerate(link.findall("collision")):
            where = f"{urdf.name}: link {link.get('name')!r} collision {k}"
            o = col.find("origin")
            xyz = [float(v) for v in (o.get("xyz", "0 0 0") if o is not None else "0 0 0").split()]
            rpy = [float(v) for v in (o.get("rpy", "0 0 0") if o is not None else "0 0 0").split()]
            g = col.find("geometry")
            el = g[0] if g is not None and len(g) else None
            if el is None:
                continue
            if el.tag == "box":
                shape = Box(*[float(v) for v in el.get("size").split()])
            elif el.tag == "cylinder":
                shape = Cylinder(float(el.get("radius")), float(el.get("length")))
            elif el.tag == "sphere":
                shape = Sphere(float(el.get("radius")))
            elif el.tag == "mesh":
                scale = np.array([float(v) for v in el.get("scale", "1 1 1").split()]) * np.ones(3)
                pts = read_mesh_points(_mesh_path(el.get("filename"), urdf, where), where) * scale
                shape = Convex(pts.T, f"{link.get('name')}_{k}")
            else:
                raise QmtInputError(f"{where}: collision shape <{el.tag}> is not read here; use box, cylinder, "
                                    "sphere or mesh")
            out.append((link.get("name"), f"{link.get('name')}/collision_{k}", shape,
                        RigidTransform(RollPitchYaw(rpy), xyz)))
    return out


class CollisionModel:
    """The arm, its carried part and the obstacles in one SceneGraph (module docstring)."""

    def __init__(self, sc) -> None:
        builder = DiagramBuilder()
        plant, H, _ = load_arm_plant(sc.urdf, sc.hand_frame, lock_joints=sc.lock_joints,
                                     effort_limit_Nm=sc.torque_limit_Nm, velocity_limit_rad_s=sc.velocity_limit_rad_s,
                                     finalize=False)
        builder.AddSystem(plant)
        sg = builder.AddSystem(SceneGraph())
        plant.RegisterAsSourceForSceneGraph(sg)
        model = H.model_instance()
        self.names = {}
        robot, balls = [], []  # balls: (body, centre in the body frame, radius m) of each arm/part geometry
        for link, name, shape, X in urdf_collision_shapes(sc.urdf):
            if plant.HasBodyNamed(link, model):
                body = plant.GetBodyByName(link, model)
                robot.append(plant.RegisterCollisionGeometry(body, X, shape, name, proximity()))
                self.names[robot[-1]] = name
                balls.append((body, X.translation(), shape_radius(shape)))
        X_BH = H.GetFixedPoseInBodyFrame()
        for name, shape, X_HG in carried_shapes(sc):
            robot.append(plant.RegisterCollisionGeometry(H.body(), X_BH @ X_HG, shape, f"carried/{name}", proximity()))
            self.names[robot[-1]] = f"carried/{name}"
            balls.append((H.body(), (X_BH @ X_HG).translation(), shape_radius(shape)))
        obs = register_obstacles(plant, sc.obstacles, illustration=False)
        self.names.update({i: f"obstacle/{ob.name}" for i, ob in zip(obs, sc.obstacles)})
        plant.Finalize()
        builder.Connect(plant.get_geometry_pose_output_port(), sg.get_source_pose_port(plant.get_source_id()))
        builder.Connect(sg.get_query_output_port(), plant.get_geometry_query_input_port())  # Drake's collision constraints
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self.plant, self.scene_graph, self.model = plant, sg, model
        self.plant_context = plant.GetMyMutableContextFromRoot(self.context)
        self.sg_context = sg.GetMyMutableContextFromRoot(self.context)
        decl = CollisionFilterDeclaration().ExcludeWithin(GeometrySet(robot))
        if obs:
            decl = decl.ExcludeWithin(GeometrySet(obs))
        sg.collision_filter_manager(self.sg_context).Apply(decl)
        self.n_robot_geometries, self.n_obstacles = len(robot), len(obs)
        self.speed_radii_m = _speed_radii(plant, model, balls)

    def distance(self, q) -> tuple[float, str, str]:
        """(smallest signed distance m, arm/part geometry, obstacle geometry) at joint positions q
        (HORIZON_M and empty names when no pair is closer than that)."""
        self.plant.SetPositions(self.plant_context, self.model, np.asarray(q, float))
        qo = self.scene_graph.get_query_output_port().Eval(self.sg_context)
        best = (HORIZON_M, "", "")
        for p in qo.ComputeSignedDistancePairwiseClosestPoints(HORIZON_M):
            if p.distance < best[0]:
                a, b = self.names[p.id_A], self.names[p.id_B]
                best = (float(p.distance), *((b, a) if a.startswith("obstacle/") else (a, b)))
        return best


def shape_radius(shape) -> float:
    """Radius (m) of a ball about the shape's own origin that holds the whole shape."""
    if isinstance(shape, Box):
        return 0.5 * float(np.linalg.norm(shape.size()))
    if isinstance(shape, Cylinder):
        return float(np.hypot(shape.radius(), 0.5 * shape.length()))
    if isinstance(shape, Sphere):
        return float(shape.radius())
    hull = shape.GetConvexHull()
    return float(max(np.linalg.norm(hull.vertex(i)) for i in range(hull.num_vertices())))


def _speed_radii(plant, model, balls) -> np.ndarray:
    """(n,) rho_j: every arm/part geometry point lies within rho_j (m) of joint j's origin at EVERY
    configuration (prismatic joints: 1), so that no point moves faster than sum_j rho_j |qd_j| (m/s).
    A ball (centre c in body B, radius r) is carried inwards joint by joint: about the inboard joint's
    origin it is the ball of radius |c - o_child| + r, which is that same point on the parent (the joint
    frames coincide at their origins for a revolute joint), whatever the joint's angle (the triangle
    inequality; configuration independent, hence conservative)."""
    inboard = {plant.get_joint(j).child_body().index(): plant.get_joint(j) for j in plant.GetJointIndices()}
    rho = np.zeros(plant.num_positions(model))
    for body, c, r in balls:
        while body.index() in inboard:
            joint = inboard[body.index()]
            radius = float(np.linalg.norm(np.asarray(c) - joint.frame_on_child().GetFixedPoseInBodyFrame().translation())) + r
            if joint.num_positions():
                e = np.zeros(plant.num_positions())
                e[joint.position_start()] = 1.0
                k = int(np.argmax(plant.GetPositionsFromArray(model, e)))
                rho[k] = max(rho[k], radius if joint.type_name() == "revolute" else np.inf)  # others: no bound
            body, c, r = joint.parent_body(), joint.frame_on_parent().GetFixedPoseInBodyFrame().translation(), radius
    return rho


def collision_model(sc) -> CollisionModel:
    """The scenario's CollisionModel, built once per scenario object."""
    key = id(sc)
    if key not in _MODELS or _MODELS[key][0] is not sc:
        _MODELS[key] = (sc, CollisionModel(sc))
    return _MODELS[key][1]


def _result(d: float, a: str, b: str, t: float, n: int) -> dict:
    return {"clearance_m": float(d), "clearance_pair": [a, b] if a else None, "clearance_time_s": float(t),
            "clearance_samples": int(n)}


def clearance_of_states(sc, t_s, q_rad, every: int = 1) -> dict:
    """Smallest clearance over given states (t (S,), q (S, n)), looked at every `every`-th state and then
    state by state near the smallest (module docstring): clearance_m, clearance_pair [arm/part geometry,
    obstacle geometry], clearance_time_s, clearance_samples."""
    cm = collision_model(sc)
    t, q = np.asarray(t_s, float), np.asarray(q_rad, float)
    done = {}
    coarse = np.r_[np.arange(0, len(t), max(int(every), 1)), len(t) - 1]
    for k in coarse:
        done[int(k)] = cm.distance(q[k])
    d = np.array([done[int(k)][0] for k in coarse])
    near = (np.r_[True, d[1:] <= d[:-1]]) & (np.r_[d[:-1] <= d[1:], True]) & (d <= d.min() + REFINE_BAND_M)
    for k in coarse[near]:
        for j in range(max(k - every, 0), min(k + every, len(t) - 1) + 1):
            if j not in done:
                done[j] = cm.distance(q[j])
    hits = [j for j in done if done[j][0] < 0.0]
    first = None
    if hits:  # the first touch, to the state: every state back to the coarse sample before the first hit
        j0 = min(hits)
        for j in range(max(j0 - every, 0), j0):
            if j not in done:
                done[j] = cm.distance(q[j])
        first = min(j for j in done if done[j][0] < 0.0)
    k = min(done, key=lambda j: done[j][0])
    out = _result(*done[k], float(t[k]), len(done))
    out["first_contact"] = None if first is None else {"time_s": float(t[first]), "pair": list(done[first][1:]),
                                                       "depth_m": float(-done[first][0])}
    return out


def certified_clearance(sc, traj, rate_hz: float, tol_m: float = CERTIFY_TOL_M, max_points: int = 200_000) -> dict:
    """The smallest clearance along traj with a bound between samples (module docstring, "certified"):
    sampled at rate_hz, then every interval whose lower bound is below (smallest found - tol_m) is
    halved until none is. The keys of `clearance` plus clearance_lower_bound_m (the true smallest
    signed distance lies in [clearance_lower_bound_m, clearance_m], clearance_m - lower bound <= tol_m
    unless max_points ran out: 'certified' False) and speed_bound_m_s (the largest point-speed bound)."""
    cm = collision_model(sc)
    rho = cm.speed_radii_m

    def at(tt):
        q, qd, qdd = traj.sample(np.atleast_1d(np.asarray(tt, float)))
        return ([cm.distance(qk) for qk in q], np.abs(np.asarray(qd)) @ rho, np.abs(np.asarray(qdd)) @ rho)

    t = sample_times(traj.duration_s, rate_hz)
    res, v, a = at(t)
    pts = {float(tk): (r, vk, ak) for tk, r, vk, ak in zip(t, res, v, a)}
    best = min(pts.items(), key=lambda kv: kv[1][0][0])

    def lower(ta, tb):
        (da, va, aa), (db, vb, ab) = pts[ta], pts[tb]
        h = tb - ta
        speed = max(va, vb) + h * max(aa, ab)  # bound on |d(clearance)/dt| over the interval
        return min(da[0], db[0], 0.5 * (da[0] + db[0] - speed * h)), speed

    heap = []
    for ta, tb in zip(t[:-1], t[1:]):
        heapq.heappush(heap, (lower(float(ta), float(tb))[0], float(ta), float(tb)))
    vmax = float(max(v))
    while heap and heap[0][0] < best[1][0][0] - tol_m and len(pts) < max_points:
        _, ta, tb = heapq.heappop(heap)
        tm = 0.5 * (ta + tb)
        r, vm, am = at([tm])
        pts[tm] = (r[0], float(vm[0]), float(am[0]))
        vmax = max(vmax, float(vm[0]))
        if r[0][0] < best[1][0][0]:
            best = (tm, pts[tm])
        for lo, hi in ((ta, tm), (tm, tb)):
            heapq.heappush(heap, (lower(lo, hi)[0], lo, hi))
    bound = min(best[1][0][0], heap[0][0]) if heap else best[1][0][0]
    out = _result(*best[1][0], best[0], len(pts))
    return {**out, "clearance_lower_bound_m": float(bound), "tolerance_m": float(tol_m),
            "certified": bool(best[1][0][0] - bound <= tol_m), "speed_bound_m_s": vmax}


def clearance(sc, traj, rate_hz: float) -> dict:
    """Smallest clearance along traj sampled at rate_hz and refined near the smallest local minima
    (module docstring); the keys of clearance_of_states."""
    cm = collision_model(sc)
    t = sample_times(traj.duration_s, rate_hz)
    q = traj.sample(t)[0]
    d = np.array([cm.distance(qk)[0] for qk in q])
    n, count = len(t), len(t)
    inner = (np.r_[True, d[1:] <= d[:-1]]) & (np.r_[d[:-1] <= d[1:], True])  # local minima of the samples
    best = (np.inf, "", "", 0.0)
    for k in np.flatnonzero(inner)[np.argsort(d[inner])][:REFINE_MINIMA]:
        lo, hi = t[max(k - 1, 0)], t[min(k + 1, n - 1)]
        for _ in range(REFINE_PASSES):
            tt = np.linspace(lo, hi, REFINE_POINTS)
            res = [cm.distance(qk) for qk in traj.sample(tt)[0]]
            count += len(tt)
            j = int(np.argmin([r[0] for r in res]))
            if res[j][0] < best[0]:
                best = (*res[j], float(tt[j]))
            step = tt[1] - tt[0]
            lo, hi = max(tt[j] - step, t[0]), min(tt[j] + step, t[-1])
    return _result(best[0], best[1], best[2], best[3], count)
