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

Every key is checked (config/fields.py): unknown keys, wrong types and out-of-range numbers are
refused with one line. Boxes are axis-aligned in the base frame. A unit task's position must lie within the largest arm's
reach (MAX_REACH_M) and outside every box, else QmtInputError.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from qmt_drake.config.fields import check_keys, num, read_yaml_mapping, sequence, show, string, vector
from qmt_drake.config.resolve import refuse_scenario_file, resolve_task
from qmt_drake.design.arm_types import LEVEL_STEP_M, N_LEVELS
from qmt_drake.design.operability import AXES
from qmt_drake.errors import QmtInputError

# Largest distance from the base origin any design reaches: L1..L4 and L6 at level 15 (L5 = 0).
MAX_REACH_M = 5 * (N_LEVELS - 1) * LEVEL_STEP_M
MAX_RADIUS_M = 0.5  # a link or tool collision radius above this swallows every design's reach
TASK_KEYS = {"name", "description", "a", "link_radius_m", "tool_radius_m", "work_boxes", "obstacles", "units"}
UNIT_KEYS = {"name", "position_m", "rpy_deg", "work", "constrained", "free", "a"}
BOX_KEYS = {"name", "center_m", "size_m"}


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

    def without_obstacles(self) -> Task:
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


def _axes_mask(u: dict, key: str, what: str) -> np.ndarray:
    """The task-frame axes listed under u[key] (a list of names, or one name) as a (6,) mask."""
    names = u.get(key)
    names = [] if names is None else [names] if isinstance(names, str) else names
    if not isinstance(names, list):
        raise QmtInputError(f"{what}.{key} must be a list of task-frame axes ({', '.join(AXES)}), "
                            f"got {show(u.get(key))}")
    m = np.zeros(6, dtype=bool)
    for n in names:
        key_n = n.strip().lower() if isinstance(n, str) else None
        if key_n not in AXES:
            raise QmtInputError(f"{what}.{key}: direction {show(n)} is not a unit axis of the task frame; "
                                f"use {', '.join(AXES)}")
        if m[AXES.index(key_n)]:  # [x, x] for [x, y]: the y meant was left out without a word (an unlisted axis is free)
            raise QmtInputError(f"{what}.{key}: direction {key_n!r} is listed twice; list each axis once")
        m[AXES.index(key_n)] = True
    return m


def _boxes(d: dict, key: str, top: str):
    """(((center (3,), size (3,)), ...), names) of the list d[key] (missing or null: none)."""
    items = sequence(d, key, top, default=None, what="boxes {name, center_m: [x, y, z], size_m: [sx, sy, sz]} (or [] for none)")
    if items is None:
        return (), []
    out, names = [], []
    for i, b in enumerate(items):
        at = f"{top}: {key}[{i}]"
        if not isinstance(b, dict):
            raise QmtInputError(f"{at} must be a mapping {{name, center_m: [x, y, z], size_m: [sx, sy, sz]}}, "
                                f"got {show(b)}")
        check_keys(b, BOX_KEYS, at)
        c = vector(b, "center_m", at, length=3, what="box centre x, y, z in m")
        s = vector(b, "size_m", at, positive=True, length=3, what="box edge lengths in m")
        out.append((c, s))
        names.append(string(b, "name", at, default=f"{key}{i}"))
    return tuple(out), names


def task_from_dict(d: dict, source: str = "") -> Task:
    """A validated Task from the mapping of a task file: unknown keys, wrong types and out-of-range
    numbers are refused with one line naming the file and the key path (`file: units[2].position_m`;
    a misspelt `obstacles` is never dropped)."""
    top = source or "task"
    if not isinstance(d, dict):
        raise QmtInputError(f"{top}: the top level must be a mapping with 'units'")
    refuse_scenario_file(d, top, "a design task", "a design task lists its units (models/tasks/*.yaml)")
    check_keys(d, TASK_KEYS, top)
    units_in = d.get("units")
    if not isinstance(units_in, list) or not units_in:
        raise QmtInputError(f"{top}: units must be a non-empty list of unit tasks {{name, position_m, "
                            f"rpy_deg, work, constrained, free, a}}, got {show(units_in)}")
    a_default = num(d, "a", top, minimum=0.0, maximum=1.0, default=0.5)
    link_r = num(d, "link_radius_m", top, minimum=0.0, maximum=MAX_RADIUS_M, default=0.04)
    tool_r = num(d, "tool_radius_m", top, minimum=0.0, maximum=MAX_RADIUS_M, default=0.01)
    name = string(d, "name", top, default=Path(source).stem if source else "task")
    if not name.replace("-", "").replace("_", "").replace(".", "").isalnum() or name.startswith("."):
        raise QmtInputError(f"{top}: name {name!r} must be letters, digits, '-', '_' or '.' (it names the "
                            "output folder)")
    description = d.get("description") if d.get("description") is not None else ""
    if not isinstance(description, str):
        raise QmtInputError(f"{top}: description must be a string, got {show(description)}")
    work, wn = _boxes(d, "work_boxes", top)
    obst, on = _boxes(d, "obstacles", top)
    units = []
    for i, u in enumerate(units_in):
        what = f"{top}: units[{i}]"
        if not isinstance(u, dict):
            raise QmtInputError(f"{what} must be a mapping {{name, position_m, rpy_deg, work, "
                                f"constrained, free, a}}, got {show(u)}")
        check_keys(u, UNIT_KEYS, what)
        nm = string(u, "name", what, default=f"unit{i}")
        if nm in [un.name for un in units]:  # the reports' rows are named by unit
            raise QmtInputError(f"{what}.name {nm!r} is used by an earlier unit; give each unit its own name")
        p = vector(u, "position_m", what, length=3, what="tool point x, y, z in m")
        rpy = vector(u, "rpy_deg", what, length=3, what="roll, pitch, yaw in degrees") \
            if u.get("rpy_deg") is not None else np.zeros(3)
        R = _rpy_matrix(rpy)
        wm = _axes_mask(u, "work", what)
        cm = _axes_mask(u, "constrained", what)
        fm = _axes_mask(u, "free", what)
        if np.any(wm & cm) or np.any(wm & fm) or np.any(cm & fm):
            raise QmtInputError(f"{what} ({nm}): a direction is listed in more than one of work, constrained, "
                                f"free; list each axis once")
        a = num(u, "a", what, minimum=0.0, maximum=1.0, default=a_default)
        if np.linalg.norm(p) > MAX_REACH_M:
            raise QmtInputError(f"{what}.position_m = {p.tolist()} ({nm}) is {np.linalg.norm(p):.2f} m from the "
                                f"base: no design reaches beyond {MAX_REACH_M:.2f} m; move it closer")
        for (c, s), bn in zip(work + obst, wn + on):
            if np.all(np.abs(p - c) <= s / 2):
                raise QmtInputError(f"{what}.position_m = {p.tolist()} ({nm}) is inside box {bn!r}: no design "
                                    f"can reach it; move the point or the box")
        units.append(UnitTask(nm, p, R, wm, cm, a))
    return Task(name, description, tuple(units), work, obst, tuple(wn + on), link_r, tool_r, source)


def load_task(path: str | Path) -> Task:
    """Load and validate a task YAML file (duplicated keys refused); a bare name looks in models/tasks/
    (config/resolve.resolve_task)."""
    p = resolve_task(path)
    return task_from_dict(read_yaml_mapping(p, "design task"), str(p))
