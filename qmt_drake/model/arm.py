"""ArmModel: one arm on a Drake MultibodyPlant, with the batched hand state planning needs.

`ArmModel.from_urdf` builds the planning plant (continuous time; the carried part, if given, welded
to the hand frame, so its mass and inertia are in every joint torque) and picks a backend:

- `PlanarChain` (model/planar.py) when every joint turns about parallel axes along a world axis:
  batched numpy kinematics and inverse dynamics with gravity, analytic IK;
- `SpatialChain` (model/spatial_chain.py) otherwise: a batched spatial recursion, checked against
  `DrakeChain` (model/drake_chain.py: Drake's algorithms, sample by sample) and Pinocchio.

A planar model is checked against Drake at load time (hand pose, hand acceleration and inverse
dynamics with gravity at a few random states, 1e-9 relative): a URDF the planar reading gets wrong
is refused with one line instead of planning motions that miss their points.

URDF requirements, each refused with one line naming the fix: well-formed XML that Drake parses;
the arm welded to the world; one actuator per joint (`<transmission><actuator>`); a declared
`<drake:gear_ratio>` inside each actuator unless `require_gear_ratio=False` (a missing ratio would
otherwise silently be 1).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import FrameIndex, JointIndex

from qmt_drake.errors import QmtInputError
from qmt_drake.model.actuator_order import actuator_joint_names
from qmt_drake.model.drake_chain import DrakeChain
from qmt_drake.model.hand_state import HandState
from qmt_drake.model.planar import IK_BRANCHES, PlanarChain  # noqa: F401  (IK_BRANCHES is re-exported)
from qmt_drake.model.spatial_chain import SpatialChain

LOAD_CHECK_RTOL = 1e-9


class ArmModel:
    """Attributes: `plant` (finalized, continuous), `n_dof`, `joint_names`, `actuator_names`,
    `gear_ratio`, `rotor_inertia_kgm2` (motor side), `reflected_inertia_kgm2` (N^2 J_r, joint side),
    `joint_lower_rad`, `joint_upper_rad`, `effort_limit_Nm` (joint side, the drive's maximum),
    `planar` (PlanarChain or None), `backend` (what `hand_state` uses)."""

    def __init__(self, plant: MultibodyPlant, hand_frame: str = "hand", source: str = "") -> None:
        self.plant = plant
        self.source = source or "(plant)"
        self._context = plant.CreateDefaultContext()
        self.hand_frame_name = hand_frame
        self.hand_frame = _frame_or_error(plant, hand_frame, self.source)
        joints = [plant.get_joint(JointIndex(i)) for i in range(plant.num_joints())]
        self.joints = [j for j in joints if j.num_velocities() > 0]
        self.n_dof = len(self.joints)
        if self.n_dof == 0 or plant.num_positions() != self.n_dof or any(j.num_velocities() != 1 for j in self.joints):
            raise QmtInputError(f"{self.source}: the arm must be welded to the world with one-degree-of-freedom "
                                f"joints (found {plant.num_positions()} positions for {self.n_dof} joints); weld "
                                "the base link to 'world' with a fixed joint")
        actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
        by_joint = {a.joint().index(): a for a in actuators}
        missing = [j.name() for j in self.joints if j.index() not in by_joint]
        if missing:
            raise QmtInputError(f"{self.source}: joints {missing} have no actuator; add a <transmission> "
                                "with an <actuator> for each joint")
        acts = [by_joint[j.index()] for j in self.joints]
        self.actuator_names = [a.name() for a in acts]
        self.gear_ratio = np.array([a.default_gear_ratio() for a in acts])
        self.rotor_inertia_kgm2 = np.array([a.default_rotor_inertia() for a in acts])
        self.reflected_inertia_kgm2 = self.gear_ratio**2 * self.rotor_inertia_kgm2
        self.effort_limit_Nm = np.array([a.effort_limit() for a in acts])
        self.joint_lower_rad = np.array([j.position_lower_limits()[0] for j in self.joints])
        self.joint_upper_rad = np.array([j.position_upper_limits()[0] for j in self.joints])
        self.joint_names = [j.name() for j in self.joints]
        self.drake_chain = DrakeChain(plant, self.hand_frame)
        try:
            self.planar = PlanarChain.from_plant(plant, self._context, self.joints, self.hand_frame,
                                                 self.reflected_inertia_kgm2, self.source)
            self.not_planar_reason = ""
        except QmtInputError as exc:
            self.planar, self.not_planar_reason = None, str(exc)
        # any other serial arm: the batched spatial recursion (equal to DrakeChain to 1e-15, ~30x faster)
        self.spatial = None if self.planar is not None else SpatialChain(
            plant, self.hand_frame, reflected_inertia_kgm2=self.reflected_inertia_kgm2)
        self.backend = self.planar or self.spatial
        if self.planar is not None:
            self._check_planar_against_drake()
            self.gravity_does_no_work = not np.any(self.planar.gravity_in_plane_m_s2)
        else:
            rng = np.random.default_rng(1)
            q = rng.uniform(-np.pi, np.pi, (4, self.n_dof))
            zero = np.zeros_like(q)
            tau = self.drake_chain.hand_acceleration_and_joint_torque(q, zero, zero)[2]
            self.gravity_does_no_work = bool(np.max(np.abs(tau)) < 1e-12)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_urdf(cls, urdf_path: str | Path, hand_frame: str = "hand", *, carried_inertia=None,
                  require_gear_ratio: bool = True, gravity_m_s2=None) -> ArmModel:
        """Parse `urdf_path` into a continuous plant; `carried_inertia` (a Drake SpatialInertia about
        the hand frame's origin, expressed in it) is welded to the hand as the carried part;
        gravity_m_s2: the world's gravity vector [m/s^2] (None: Drake's default, (0, 0, -9.81))."""
        path = Path(urdf_path)
        if not path.is_file():
            raise QmtInputError(f"URDF file not found: {path}; check arm.urdf in the scenario "
                                "(relative paths are taken from the scenario file's folder)")
        gear_declared = _actuators_declaring_gear_ratio(path)
        plant = MultibodyPlant(time_step=0.0)
        if gravity_m_s2 is not None:
            plant.mutable_gravity_field().set_gravity_vector(np.asarray(gravity_m_s2, float))
        add_arm(plant, path)
        if carried_inertia is not None:
            hand = _frame_or_error(plant, hand_frame, path)
            body = plant.AddRigidBody("carried_part", plant.AddModelInstance("carried_part"), carried_inertia)
            plant.WeldFrames(hand, body.body_frame(), RigidTransform())
        plant.Finalize()
        arm = cls(plant, hand_frame=hand_frame, source=str(path))
        if require_gear_ratio:
            missing = [a for a in arm.actuator_names if a not in gear_declared]
            if missing:
                raise QmtInputError(f"{path}: actuator '{missing[0]}' declares no <drake:gear_ratio> inside "
                                    "<transmission><actuator>; add it (value 1 for a direct drive) so the motor "
                                    "torques are not silently computed with N = 1")
        return arm

    def _check_planar_against_drake(self) -> None:
        """Hand pose, acceleration and joint torques of the planar model against Drake's on random
        states (the reference is DrakeChain: the plant's own algorithms)."""
        rng = np.random.default_rng(20090101)
        lo = np.maximum(self.joint_lower_rad, -np.pi)
        hi = np.minimum(self.joint_upper_rad, np.pi)
        q = lo + (hi - lo) * rng.random((3, self.n_dof))
        qd, qdd = rng.normal(size=(2, 3, self.n_dof))
        ours = [*self.planar.hand_pose(q), *self.planar.hand_acceleration_and_joint_torque(q, qd, qdd)[:3]]
        ref = [*self.drake_chain.hand_pose(q), *self.drake_chain.hand_acceleration_and_joint_torque(q, qd, qdd)[:3]]
        for name, a, b in zip(("hand position", "hand orientation", "hand acceleration",
                               "hand angular acceleration", "joint torque"), ours, ref):
            scale = max(1.0, float(np.max(np.abs(b))))
            err = float(np.max(np.abs(a - b)))
            if err > LOAD_CHECK_RTOL * scale:
                raise QmtInputError(f"{self.source}: the planar model's {name} differs from Drake's by {err:.3g} "
                                    "on a random state; this URDF is outside what the planar model reads correctly "
                                    "(please report it)")

    # ------------------------------------------------------------------ hand state (any arm)
    def hand_state(self, q, qd, qdd) -> HandState:
        """Batched HandState (model/hand_state.py) of joint samples (S, n)."""
        return HandState(self.backend, q, qd, qdd)

    # ------------------------------------------------------------------ planar-only helpers
    def _planar(self) -> PlanarChain:
        if self.planar is None:
            raise QmtInputError(f"this needs a planar arm, and {self.not_planar_reason}")
        return self.planar

    @property
    def link_lengths_m(self) -> np.ndarray:
        return self._planar().link_lengths_m

    def tip_position(self, q) -> np.ndarray:
        """Hand origin in the arm's plane coordinates, (..., 2) m."""
        return self._planar().tip_position(q)

    def tool_angle(self, q) -> np.ndarray:
        return self._planar().tool_angle(q)

    def tip_velocity(self, q, qd) -> np.ndarray:
        return self._planar().tip_velocity(q, qd)

    def tip_acceleration(self, q, qd, qdd) -> np.ndarray:
        return self._planar().tip_acceleration(q, qd, qdd)

    def jacobian(self, q) -> np.ndarray:
        return self._planar().jacobian(q)

    def tip_acceleration_and_joint_torque(self, q, qd, qdd):
        """(in-plane hand acceleration (..., 2), joint torque (..., n)): the planning hot path."""
        return self._planar().acceleration_and_torque(q, qd, qdd)

    def joint_torque(self, q, qd, qdd) -> np.ndarray:
        """Inverse dynamics with gravity, reflected rotor inertia and the carried part, N*m."""
        if self.planar is not None:
            return self.planar.acceleration_and_torque(q, qd, qdd)[1]
        return self.hand_state(q, qd, qdd).joint_torque_Nm

    def motor_torque(self, q, qd, qdd) -> np.ndarray:
        """Motor-side torque, N*m: joint torque / gear ratio (eq. 2-34)."""
        return self.joint_torque(q, qd, qdd) / self.gear_ratio

    def inverse_kinematics(self, xy, tool_angle_rad: float | None = None, branch: str = "elbow_positive",
                           check_range: bool = True, what: str = "point") -> np.ndarray:
        """Analytic planar IK (PlanarChain.inverse_kinematics), then the joint-range check."""
        q = self._planar().inverse_kinematics(xy, tool_angle_rad, branch, what=what)
        if check_range:
            self.check_joint_range(q, what=f"IK solution of {what} (branch {branch})")
        return q

    def joint_motion_on_tip_path(self, p, v, a, tool_angle_rad=None, branch="elbow_positive"):
        """Joints that move the hand along a planar tip motion (PlanarChain.joint_motion_on_tip_path)."""
        return self._planar().joint_motion_on_tip_path(p, v, a, tool_angle_rad, branch)

    def check_joint_range(self, q, what: str = "joint trajectory") -> None:
        q = np.atleast_2d(q)
        lo_bad = q < self.joint_lower_rad - 1e-12
        hi_bad = q > self.joint_upper_rad + 1e-12
        if np.any(lo_bad | hi_bad):
            k, j = np.argwhere(lo_bad | hi_bad)[0]
            raise QmtInputError(
                f"{what}: joint {self.joint_names[j]} = {q[k, j]:.4f} rad leaves its range "
                f"[{self.joint_lower_rad[j]:.4f}, {self.joint_upper_rad[j]:.4f}] rad; choose the "
                "other IK branch or widen the joint limits in the URDF")

    # ------------------------------------------------------------------ Drake reference, one state
    def drake_inverse_dynamics(self, q, qd, qdd) -> np.ndarray:
        return self.drake_chain.hand_acceleration_and_joint_torque(q, qd, qdd)[2][0]

    def drake_tip_acceleration(self, q, qd, qdd) -> np.ndarray:
        """Hand-origin acceleration from Drake (J qdd + Jdot qd), in plane coordinates if planar."""
        a = self.drake_chain.hand_acceleration_and_joint_torque(q, qd, qdd)[0][0]
        return a @ self.planar.plane_axes if self.planar is not None else a

    def drake_tip_position(self, q) -> np.ndarray:
        p = self.drake_chain.hand_pose(q)[0][0]
        return p @ self.planar.plane_axes if self.planar is not None else p


def add_urdf(plant, urdf, *, source: str | None = None):
    """Parse a URDF into `plant` (the one place the project parses a URDF into a plant: the planning,
    co-simulation, controller, check and recording plants); returns its model instance. urdf: a file
    path, or the URDF's text (a str starting with '<'); source: how an error names it (default the path,
    or "URDF text"). A missing file or a file Drake cannot parse is one QmtInputError line."""
    is_text = isinstance(urdf, str) and urdf.lstrip().startswith("<")
    if not is_text and not Path(urdf).is_file():
        raise QmtInputError(f"URDF file not found: {urdf}; check arm.urdf in the scenario")
    name = source or ("URDF text" if is_text else str(urdf))
    try:
        parser = Parser(plant)
        models = parser.AddModelsFromString(urdf, "urdf") if is_text else parser.AddModels(str(urdf))
    except RuntimeError as exc:
        raise QmtInputError(f"{name}: Drake cannot parse this URDF ({_first_line(exc)}); fix the URDF") from None
    return models[0]


def add_arm(plant, urdf_path):
    """Parse the arm's URDF into `plant` (add_urdf: the planning plant here, the co-simulation's
    discrete plant in sim/plant.py) and refuse actuators out of joint order; returns its model instance."""
    path = Path(urdf_path)
    model = add_urdf(plant, path)
    _refuse_actuators_out_of_joint_order(plant, model, path)
    return model


def _refuse_actuators_out_of_joint_order(plant, model, path) -> None:
    """The co-simulation writes one torque per joint, base to tip, into the actuation input, whose order
    is the <transmission> elements' (Drake's parser): refuse a file whose order differs (by name)."""
    joints = [plant.get_joint(i) for i in plant.GetJointIndices(model)]
    inboard = {j.child_body().index(): j for j in joints}

    def depth(j) -> int:
        parent = inboard.get(j.parent_body().index())
        return 0 if parent is None else 1 + depth(parent)

    acting = actuator_joint_names(plant, model)
    order = [j.name() for j in sorted(joints, key=depth) if j.name() in acting]
    if acting != order:
        raise QmtInputError(f"{path}: its <transmission> elements drive {acting}, not the joints base to tip "
                            f"{order}; list the transmissions in that order")


def _all_frames(plant):
    return [FrameIndex(i) for i in range(plant.num_frames())]


def _frame_or_error(plant, name, path):
    if not plant.HasFrameNamed(name):
        names = sorted({plant.get_frame(f).name() for f in _all_frames(plant)})
        raise QmtInputError(f"{path} has no frame named '{name}'; set arm.hand_frame to one of: {', '.join(names)}")
    return plant.GetFrameByName(name)


def _first_line(exc) -> str:
    return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _actuators_declaring_gear_ratio(path: Path) -> set:
    """Names of the URDF's actuators with a <drake:gear_ratio> element; refuses non-XML with one line."""
    text = path.read_bytes().decode("utf-8", errors="replace")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        if "unbound prefix" not in str(exc):
            raise QmtInputError(f"{path} is not a well-formed URDF (XML error: {exc}); fix the file or "
                                "point arm.urdf at another") from None
        # Drake's parser accepts an undeclared drake: prefix; read the names without namespaces.
        root = ET.fromstring(re.sub(r"<(/?)(\w+):", r"<\1\2_", text))
    names = set()
    for act in root.iter():
        if act.tag.split("}")[-1].endswith("actuator") and act.get("name"):
            if any(child.tag.split("}")[-1].endswith("gear_ratio") for child in act):
                names.add(act.get("name"))
    return names
