"""6-DOF arms from a joint-combination type and six link lengths (seed 003, Fig. 3-4 reconstructed).

Model. Joints 1-3 place the wrist centre, joints 4-6 form a spherical wrist. The type's two letters
name the relation of joints 1->2 and 2->3 (Asama's classification as cited by the seed; Fig. 4 is not
in the text, so the letters are reconstructed, see README.md):

  P  axes parallel, link along their common normal        (PUMA shoulder -> elbow)
  B  axes perpendicular, link along the SECOND axis        (PUMA shoulder offset along joint 2)
  F  axes perpendicular, link along the FIRST axis         (a column along joint 1)
  T  axes perpendicular, link along their common normal

Why this assignment: it is the one (of the six ways to give B, F, T the three perpendicular
relations) under which the seed's exclusions and results make sense: FB puts all three axes
through one point (a spherical joint, no translation of the wrist centre: excluded by the seed's
criterion 2), PP cannot move vertically (criterion 2), BP is PUMA (joints 1 and 2 intersect, the
offset runs along the shoulder axis as in the PUMA 560), and all T-first arms are the excluded
class TP TB TF TT. The alternative F = second axis makes the seed's Task-2 winner BF spherical.

Joint 3 -> 4 is always "B" (the forearm L3 runs along the wrist-roll axis 4), L4 continues along
axis 4 to the wrist centre, L5 is the offset between wrist axes 5 and 6 (0 for a spherical wrist: the
seed's tables always have gene 5 = 0), L6 the tool along axis 6. Joint 1 is vertical through the
fixed base origin. Each relation fixes the next axis and link only up to a rotation about the current
axis, i.e. a joint offset, so the zero configuration chosen here (all links along world X, the axis,
or the next axis) loses no generality for arms without joint limits.

Consequences (checked in tests): L3 and L4 are collinear, so only L3 + L4 matters (the seed's
PB/PF/PT genes b05500, b08200, b00a00 tie); with L2 = 0, PB, PF, PT are one arm; with L1 = 0, BP
and FP are one arm; in BF, L1 and L2 are collinear along axis 2 (only L1 + L2 matters).

Levels and genes: each length is one of 16 levels, length = level * LEVEL_STEP_M; a design is six
hex digits (L1..L6), e.g. "0db000". The seed does not give its length unit; LEVEL_STEP_M = 0.10 m is
our choice (links up to 1.5 m; with 0.05 m the optimum ran into the 0.75 m bound, see README).

Kinematics is the product of exponentials over the zero configuration (space-frame axes `axes`,
points `origins`), batched in numpy; tests compare it with Drake's MultibodyPlant. Units: m, rad.
Drake plant: one body per joint, joint i's parent frame a FixedOffsetFrame whose translation
carries the lengths, so `set_lengths(plant, context, lengths)` changes an arm without rebuilding.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, Capsule, MeshcatVisualizer, MeshcatVisualizerParams, Role
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
from pydrake.multibody.tree import FixedOffsetFrame, RevoluteJoint, SpatialInertia, UnitInertia
from pydrake.systems.framework import DiagramBuilder

from qmt_drake.errors import QmtInputError

TYPES = ("BP", "BB", "BF", "BT", "PB", "PF", "PT", "FP", "FF", "FT")
RELATIONS = "PBFT"
N_LEVELS = 16
LEVEL_STEP_M = 0.10
N_JOINTS = 6
LINK_NAMES = ("L1", "L2", "L3", "L4", "L5", "L6")
_X = np.array([1.0, 0.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])


def check_type(type_name: str) -> str:
    t = str(type_name).upper()
    if len(t) != 2 or any(c not in RELATIONS for c in t):
        raise QmtInputError(f"arm type {type_name!r} unknown: use two letters of P, B, F, T, one of "
                            f"{', '.join(TYPES)}")
    return t


def levels_from_gene(gene: str) -> np.ndarray:
    """'0db000' -> array([0, 13, 11, 0, 0, 0])."""
    g = str(gene).strip().replace(" ", "").lower()
    if len(g) != N_JOINTS or any(c not in "0123456789abcdef" for c in g):
        raise QmtInputError(f"gene {gene!r} is not six hex digits (levels 0-f of L1..L6, e.g. 0db000)")
    return np.array([int(c, 16) for c in g])


def gene_from_levels(levels) -> str:
    lv = check_levels(levels)
    return "".join(f"{int(v):x}" for v in lv)


def check_levels(levels) -> np.ndarray:
    lv = np.asarray(levels)
    if lv.shape[-1] != N_JOINTS:
        raise QmtInputError(f"link levels {lv.tolist()} must have {N_JOINTS} entries (L1..L6)")
    if np.any(lv != np.round(lv)) or np.any(lv < 0) or np.any(lv > N_LEVELS - 1):
        shown = [int(v) if float(v).is_integer() else float(v) for v in np.ravel(lv)]
        raise QmtInputError(f"link levels {shown} must be integers 0-15 (L1..L6, "
                            f"{LEVEL_STEP_M} m per level)")
    return lv.astype(int)


def lengths_from_levels(levels) -> np.ndarray:
    return check_levels(levels) * LEVEL_STEP_M


@dataclass(frozen=True)
class ArmType:
    """The type-only part of the zero configuration: joint axes (6, 3) in the base frame, and the
    unit direction (6, 3) of each link Lk (link k goes from joint k's point to joint k+1's point,
    L6 from joint 6 to the tool point); `perp` (6, 3) gives the direction of link k when it is an
    offset perpendicular to both axes (only L5 uses a separate rule). Tool frame: z along axis 6."""
    name: str
    axes: np.ndarray
    link_dirs: np.ndarray
    tool_rotation: np.ndarray

    def origins(self, lengths) -> np.ndarray:
        """Joint points at the zero configuration, (..., 7, 3): joints 1..6 and the tool point."""
        L = np.asarray(lengths, dtype=float)
        steps = L[..., :, None] * self.link_dirs  # (..., 6, 3)
        pts = np.concatenate([np.zeros(L.shape[:-1] + (1, 3)), np.cumsum(steps, axis=-2)], axis=-2)
        return pts


# Our reconstruction: where each perpendicular letter puts its link (see the module docstring).
RELATIONS_DEFAULT = {"B": "second", "F": "first", "T": "normal"}
# The other assignments that keep all ten of the seed's types non-spherical (a sensitivity check).
RELATIONS_ALTERNATIVES = {
    "T-column": {"B": "second", "F": "normal", "T": "first"},   # spherical TB excluded
    "B-normal": {"B": "normal", "F": "second", "T": "first"},   # spherical TF excluded
}


def _relation(letter: str, a: np.ndarray, relations: dict) -> tuple[np.ndarray, np.ndarray]:
    """(next axis, link direction) for a relation from axis `a` (a is in the world YZ plane, so the
    reference direction X is always perpendicular to it)."""
    if letter == "P":
        return a.copy(), _X.copy()
    if letter not in relations:
        raise QmtInputError(f"relation {letter!r} unknown: use P, B, F or T")
    nxt = np.cross(_X, a)
    where = relations[letter]
    if where == "first":
        return nxt, a.copy()
    if where == "second":
        return nxt, nxt.copy()
    return nxt, _X.copy()  # X is perpendicular to a and nxt: their common normal


def arm_type(type_name: str, relations: dict | None = None) -> ArmType:
    """The arm type; `relations` overrides which link direction B, F, T mean (default: ours)."""
    t = check_type(type_name)
    rel = RELATIONS_DEFAULT if relations is None else relations
    axes, dirs = [_Z.copy()], []
    # 1->2, 2->3, then 3->4: the forearm along the wrist-roll axis (link along the second axis)
    for letter, r in ((t[0], rel), (t[1], rel), ("B", RELATIONS_DEFAULT)):
        nxt, d = _relation(letter, axes[-1], r)
        axes.append(nxt)
        dirs.append(d)
    a4 = axes[3]
    dirs.append(a4.copy())          # L4: along axis 4 to the wrist centre
    a5 = np.cross(_X, a4)
    axes.append(a5)
    axes.append(a4.copy())          # axis 6 = axis 4 at zero (ZYZ wrist)
    dirs.append(_X.copy())          # L5: common normal of axes 5 and 6 (0 for a spherical wrist)
    dirs.append(a4.copy())          # L6: tool along axis 6
    z = axes[5]
    x = _X.copy()
    R = np.column_stack([x, np.cross(z, x), z])
    return ArmType(t, np.array(axes), np.array(dirs), R)


# ---------------------------------------------------------------- batched kinematics (numpy)

def rotation(axis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rodrigues: rotations (N, 3, 3) about a fixed unit axis (3,) by angles q (N,)."""
    q = np.asarray(q, dtype=float)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s, c = np.sin(q)[..., None, None], np.cos(q)[..., None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


@dataclass
class Pose:
    """Batched forward kinematics: joint points (N, 7, 3) (joints 1-6 and the tool point, world),
    current joint axes (N, 6, 3), tool rotation (N, 3, 3)."""
    points: np.ndarray
    axes: np.ndarray
    tool_rotation: np.ndarray

    @property
    def tool_position(self) -> np.ndarray:
        return self.points[:, 6]


def forward(at: ArmType, origins: np.ndarray, q: np.ndarray) -> Pose:
    """Forward kinematics of N configurations q (N, 6) for zero-configuration points origins
    (N, 7, 3) (one arm per row; broadcastable from (7, 3))."""
    q = np.atleast_2d(q)
    N = q.shape[0]
    o = np.broadcast_to(origins, (N, 7, 3))
    R = np.broadcast_to(np.eye(3), (N, 3, 3)).copy()
    t = np.zeros((N, 3))
    pts = np.empty((N, 7, 3))
    axes = np.empty((N, 6, 3))
    for i in range(6):
        # T_{<i} applied to joint i's zero point and axis
        pts[:, i] = np.einsum("nij,nj->ni", R, o[:, i]) + t
        axes[:, i] = R @ at.axes[i]
        Ri = rotation(at.axes[i], q[:, i])
        # T <- T * exp(xi_i q_i), exp = rotation about the line through o_i
        t = t + np.einsum("nij,nj->ni", R, o[:, i] - np.einsum("nij,nj->ni", Ri, o[:, i]))
        R = R @ Ri
    pts[:, 6] = np.einsum("nij,nj->ni", R, o[:, 6]) + t
    return Pose(pts, axes, R @ at.tool_rotation)


def jacobian(pose: Pose) -> np.ndarray:
    """Geometric Jacobian (N, 6, 6) of the tool point, rows (vx, vy, vz, wx, wy, wz) in the base
    frame (the seed's order: translation first), columns joints 1..6."""
    w = pose.axes                                  # (N, 6, 3)
    r = pose.points[:, 6:7] - pose.points[:, :6]   # (N, 6, 3)
    v = np.cross(w, r)
    return np.concatenate([v, w], axis=2).transpose(0, 2, 1)


# ---------------------------------------------------------------- URDF and Drake plant

def _link_inertial(mass=0.1) -> str:
    return (f'<inertial><mass value="{mass}"/><inertia ixx="1e-4" iyy="1e-4" izz="1e-4" ixy="0" '
            f'ixz="0" iyz="0"/></inertial>')


def _segment_visual(p0, p1, radius, tag="visual") -> str:
    """A cylinder from p0 to p1 (link frame coordinates)."""
    d = np.asarray(p1) - np.asarray(p0)
    L = float(np.linalg.norm(d))
    if L < 1e-9:
        return ""
    z = d / L
    mid = (np.asarray(p0) + np.asarray(p1)) / 2
    # rpy that maps local z onto d: pitch about y then yaw about z
    yaw = np.arctan2(z[1], z[0])
    pitch = np.arccos(np.clip(z[2], -1, 1))
    return (f'<{tag}><origin xyz="{mid[0]:.6g} {mid[1]:.6g} {mid[2]:.6g}" rpy="0 {pitch:.9g} '
            f'{yaw:.9g}"/><geometry><cylinder radius="{radius}" length="{L:.6g}"/></geometry></{tag}>')


def urdf_text(type_name: str, lengths, link_radius_m: float = 0.04, relations: dict | None = None) -> str:
    """URDF of the arm: links base, link1..link6, tool; every link frame is world-aligned at the zero
    configuration and sits at its joint's point; joint axes as in `arm_type`. Visuals are cylinders
    along the links (L3 and L4 both on link3/link4)."""
    at = arm_type(type_name, relations)
    L = np.asarray(lengths, dtype=float)
    o = at.origins(L)
    name = f"arm_{at.name}_" + "_".join(f"{v:.3f}" for v in L)
    out = ['<?xml version="1.0"?>', f'<robot name="{name}">',
           f'  <!-- qmt_drake.design.arm_types: type {at.name}, lengths L1..L6 [m] = {L.tolist()} -->',
           '  <link name="world"/>',
           f'  <link name="base">{_link_inertial()}</link>',
           '  <joint name="base_weld" type="fixed"><parent link="world"/><child link="base"/></joint>']
    parent = "base"
    for i in range(6):
        child = f"link{i + 1}"
        seg = _segment_visual(np.zeros(3), o[i + 1] - o[i], link_radius_m if i < 5 else 0.01)
        out.append(f'  <link name="{child}">{_link_inertial()}{seg}</link>')
        off = o[i] - (o[i - 1] if i > 0 else np.zeros(3))
        a = at.axes[i]
        out.append(f'  <joint name="joint{i + 1}" type="continuous"><parent link="{parent}"/>'
                   f'<child link="{child}"/><origin xyz="{off[0]:.9g} {off[1]:.9g} {off[2]:.9g}" '
                   f'rpy="0 0 0"/><axis xyz="{a[0]:.9g} {a[1]:.9g} {a[2]:.9g}"/></joint>')
        parent = child
    off = o[6] - o[5]
    rpy = RollPitchYaw(RotationMatrix(at.tool_rotation)).vector()
    out.append(f'  <link name="tool">{_link_inertial(0.01)}</link>')
    out.append(f'  <joint name="tool_fixed" type="fixed"><parent link="link6"/><child link="tool"/>'
               f'<origin xyz="{off[0]:.9g} {off[1]:.9g} {off[2]:.9g}" rpy="{rpy[0]:.12g} '
               f'{rpy[1]:.12g} {rpy[2]:.12g}"/></joint>')
    out.append("</robot>")
    return "\n".join(out) + "\n"


@dataclass
class DrakeArm:
    """A MultibodyPlant (+ SceneGraph) of one arm type. `joint_frames[i]` is joint i's parent frame
    (a FixedOffsetFrame whose translation holds the lengths), `tool_frame` the tool frame;
    `visualizer` the MeshcatVisualizer if one was asked for."""
    type: ArmType
    diagram: object
    plant: object
    scene_graph: object
    joint_frames: list
    tool_frame: object
    env_geometry_ids: list
    visualizer: object = None

    def set_lengths(self, plant_context, lengths) -> None:
        """Move the joint frames for new link lengths in this context (no rebuild). Collision
        geometry keeps the lengths the plant was built with."""
        o = self.type.origins(np.asarray(lengths, dtype=float))
        for i, fr in enumerate(self.joint_frames):
            prev = o[i - 1] if i > 0 else np.zeros(3)
            fr.SetPoseInParentFrame(plant_context, RigidTransform(o[i] - prev))
        self.tool_frame.SetPoseInParentFrame(
            plant_context, RigidTransform(_rot(self.type.tool_rotation), o[6] - o[5]))


    def min_env_distance(self, plant_context) -> float:
        """Smallest SceneGraph signed distance (m) between an arm link and a work/obstacle box
        (negative: penetration), queried pair by pair: only arm-environment pairs matter, and
        Drake 1.51 did not return from the all-pairs query for collinear arm capsules."""
        qo = self.plant.get_geometry_query_input_port().Eval(plant_context)
        insp = qo.inspector()
        env = set(self.env_geometry_ids)
        arm = [g for g in insp.GetAllGeometryIds(Role.kProximity) if g not in env]
        d = [qo.ComputeSignedDistancePairClosestPoints(a, b).distance for a in arm for b in env]
        return float(min(d)) if d else float("inf")


def _rot(R):
    return RotationMatrix(np.asarray(R))


def build_plant(type_name: str, lengths, *, boxes=(), link_radius_m: float = 0.04,
                tool_radius_m: float = 0.01, relations: dict | None = None,
                meshcat=None) -> DrakeArm:
    """Drake plant of the arm with capsule collision geometry along each link (radius
    link_radius_m; the tool L6 with tool_radius_m) and anchored boxes [(center (3,), size (3,)),
    ...] for the work and obstacles, in a diagram with a SceneGraph."""
    at = arm_type(type_name, relations)
    L = np.asarray(lengths, dtype=float)
    o = at.origins(L)
    builder = DiagramBuilder()
    plant, sg = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
    M = SpatialInertia(0.1, np.zeros(3), UnitInertia(1e-3, 1e-3, 1e-3))
    parent = plant.world_frame()
    frames, bodies = [], []
    fric = CoulombFriction(0.5, 0.5)
    for i in range(6):
        body = plant.AddRigidBody(f"link{i + 1}", M)
        prev = o[i - 1] if i > 0 else np.zeros(3)
        F = plant.AddFrame(FixedOffsetFrame(f"joint{i + 1}_parent", parent, RigidTransform(o[i] - prev)))
        plant.AddJoint(RevoluteJoint(f"joint{i + 1}", F, body.body_frame(), at.axes[i]))
        frames.append(F)
        bodies.append(body)
        parent = body.body_frame()
        d = o[i + 1] - o[i]
        n = np.linalg.norm(d)
        if n > 1e-9:
            r = link_radius_m if i < 5 else tool_radius_m
            z = d / n
            R = RotationMatrix.MakeFromOneVector(z, 2)
            plant.RegisterCollisionGeometry(body, RigidTransform(R, d / 2), Capsule(r, n),
                                            f"link{i + 1}_capsule", fric)
            plant.RegisterVisualGeometry(body, RigidTransform(R, d / 2), Capsule(r, n),
                                         f"link{i + 1}_visual", np.array([0.8, 0.5, 0.2, 1.0]))
    tool = plant.AddFrame(FixedOffsetFrame("tool", bodies[5].body_frame(),
                                           RigidTransform(RotationMatrix(at.tool_rotation), o[6] - o[5])))
    env = []
    for k, (c, s) in enumerate(boxes):
        gid = plant.RegisterCollisionGeometry(plant.world_body(), RigidTransform(np.asarray(c, float)),
                                              Box(*np.asarray(s, float)), f"box{k}", fric)
        plant.RegisterVisualGeometry(plant.world_body(), RigidTransform(np.asarray(c, float)),
                                     Box(*np.asarray(s, float)), f"box{k}_visual",
                                     np.array([0.6, 0.6, 0.7, 0.5]))
        env.append(gid)
    plant.Finalize()
    vis = None
    if meshcat is not None:
        vis = MeshcatVisualizer.AddToBuilder(builder, sg, meshcat,
                                             MeshcatVisualizerParams(role=Role.kIllustration))
    diagram = builder.Build()
    return DrakeArm(at, diagram, plant, sg, frames, tool, env, vis)
