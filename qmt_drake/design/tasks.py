"""Tasks for the structural design (seed 003, sec. 2.1-2.2): unit tasks with a pose, direction sets
and weight a, plus the work and obstacle boxes, loaded from YAML and validated.

YAML (units in the key names; angles in degrees in the file, radians inside):

    name: task1
    description: ...
    link_radius_m: 0.04        # collision radius of links 1-5 (optional)
    tool_radius_m: 0.01        # collision radius of the tool link 6 (optional)
    work_boxes:   [{name: plate, center_m: [x, y, z], size_m: [sx, sy, sz]}]
    obstacles:    [{name: wall_left, center_m: [...], size_m: [...]}]
    units:
      - name: P0
        position_m: [x, y, z]          # tool point, base frame (z up, base at the origin)
        rpy_deg: [roll, pitch, yaw]    # task frame = required tool frame (z = tool axis)
        work: [x, y]                   # task-frame axes: x y z alpha beta gamma
        constrained: [z, alpha, beta]
        free: [gamma]                  # optional: the rest are free
        a: 0.5                         # eq. 6 weight (optional, default `a` at top level or 0.5)

Boxes are axis-aligned in the base frame. A unit task's position must lie within the largest arm's
reach (MAX_REACH_M) and outside every box, else QmtInputError.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml

from qmt_drake.design.arm_types import LEVEL_STEP_M, N_LEVELS
from qmt_drake.design.operability import AXES
from qmt_drake.errors import QmtInputError

# Largest distance from the base origin any design reaches: L1..L4 and L6 at level 15 (L5 = 0).
MAX_REACH_M = 5 * (N_LEVELS - 1) * LEVEL_STEP_M


@dataclass(frozen=True)
class UnitTask:
    name: str
    position_m: np.ndarray
    rotation: np.ndarray        # (3, 3) columns = task axes in the base frame
    work: np.ndarray            # (6,) bool over AXES
    constrained: np.ndarray     # (6,) bool
    a: float


@dataclass(frozen=True)
class Task:
    name: str
    description: str
    units: tuple
    work_boxes: tuple = ()      # ((center (3,), size (3,)), ...)
    obstacles: tuple = ()
    box_names: tuple = ()
    link_radius_m: float = 0.04
    tool_radius_m: float = 0.01
    source: str = ""

    @property
    def boxes(self) -> tuple:
        return tuple(self.work_boxes) + tuple(self.obstacles)

    def without_obstacles(self) -> "Task":
        return replace(self, name=self.name + "-no-obstacles", obstacles=(),
                       box_names=self.box_names[:len(self.work_boxes)])

    def arrays(self):
        """positions (k, 3), rotations (k, 3, 3), work (k, 6), constrained (k, 6), a (k,)."""
        u = self.units
        return (np.array([x.position_m for x in u]), np.array([x.rotation for x in u]),
                np.array([x.work for x in u]), np.array([x.constrained for x in u]),
                np.array([x.a for x in u]))


def _rpy_matrix(rpy_deg) -> np.ndarray:
    r, p, y = np.radians(np.asarray(rpy_deg, dtype=float))
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return Rz @ Ry @ Rx


def _vec3(v, what: str) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise QmtInputError(f"{what} = {v!r} must be three finite numbers")
    return a


def _axes_mask(names, what: str) -> np.ndarray:
    names = [] if names is None else names
    if isinstance(names, str):
        names = [names]
    m = np.zeros(6, dtype=bool)
    for n in names:
        key = str(n).strip().lower()
        if key not in AXES:
            raise QmtInputError(f"{what}: direction {n!r} is not a unit axis of the task frame; use "
                                f"{', '.join(AXES)}")
        m[AXES.index(key)] = True
    return m


def _boxes(items, what: str):
    out, names = [], []
    for i, b in enumerate(items or []):
        if not isinstance(b, dict):
            raise QmtInputError(f"{what}[{i}] must be a mapping with center_m and size_m")
        c = _vec3(b.get("center_m"), f"{what}[{i}].center_m")
        s = _vec3(b.get("size_m"), f"{what}[{i}].size_m")
        if np.any(s <= 0):
            raise QmtInputError(f"{what}[{i}].size_m = {s.tolist()} must be positive")
        out.append((c, s))
        names.append(str(b.get("name", f"{what}{i}")))
    return tuple(out), names


def task_from_dict(d: dict, source: str = "") -> Task:
    if not isinstance(d, dict):
        raise QmtInputError(f"task file {source}: top level must be a mapping with 'units'")
    units_in = d.get("units")
    if not units_in or not isinstance(units_in, list):
        raise QmtInputError(f"task file {source}: 'units' must be a non-empty list of unit tasks")
    a_default = float(d.get("a", 0.5))
    work, wn = _boxes(d.get("work_boxes"), "work_boxes")
    obst, on = _boxes(d.get("obstacles"), "obstacles")
    units = []
    for i, u in enumerate(units_in):
        nm = str(u.get("name", f"unit{i}"))
        what = f"unit {nm}"
        p = _vec3(u.get("position_m"), f"{what}.position_m")
        R = _rpy_matrix(_vec3(u.get("rpy_deg", [0, 0, 0]), f"{what}.rpy_deg"))
        wm = _axes_mask(u.get("work"), f"{what}.work")
        cm = _axes_mask(u.get("constrained"), f"{what}.constrained")
        fm = _axes_mask(u.get("free"), f"{what}.free")
        if np.any(wm & cm) or np.any(wm & fm) or np.any(cm & fm):
            raise QmtInputError(f"{what}: a direction is listed in more than one of work, constrained, "
                                f"free; list each axis once")
        a = float(u.get("a", a_default))
        if not 0.0 <= a <= 1.0:
            raise QmtInputError(f"{what}.a = {a} must be in [0, 1]")
        if np.linalg.norm(p) > MAX_REACH_M:
            raise QmtInputError(f"{what}.position_m = {p.tolist()} is {np.linalg.norm(p):.2f} m from the "
                                f"base: no design reaches beyond {MAX_REACH_M:.2f} m; move it closer")
        for (c, s), bn in zip(work + obst, wn + on):
            if np.all(np.abs(p - c) <= s / 2):
                raise QmtInputError(f"{what}.position_m = {p.tolist()} is inside box {bn!r}: no design "
                                    f"can reach it; move the point or the box")
        units.append(UnitTask(nm, p, R, wm, cm, a))
    return Task(str(d.get("name", Path(source).stem if source else "task")),
                str(d.get("description", "")), tuple(units), work, obst, tuple(wn + on),
                float(d.get("link_radius_m", 0.04)), float(d.get("tool_radius_m", 0.01)), source)


def load_task(path: str | Path) -> Task:
    """Load and validate a task YAML file; a bare name looks in models/tasks/."""
    p = Path(path)
    if not p.exists():
        cand = Path(__file__).resolve().parents[2] / "models" / "tasks" / f"{path}.yaml"
        if cand.exists():
            p = cand
        else:
            raise QmtInputError(f"task file {path!r} not found; give a path or one of "
                                f"{', '.join(builtin_tasks())}")
    try:
        d = yaml.safe_load(p.read_text())
    except yaml.YAMLError as e:
        raise QmtInputError(f"task file {p}: not valid YAML ({str(e).splitlines()[0]})")
    return task_from_dict(d, str(p))


def builtin_tasks() -> list[str]:
    folder = Path(__file__).resolve().parents[2] / "models" / "tasks"
    return sorted(x.stem for x in folder.glob("*.yaml"))
