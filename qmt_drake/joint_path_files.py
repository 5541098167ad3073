"""Read a joint path made elsewhere: a CSV with a header of joint names, or a ROS 2
`trajectory_msgs/JointTrajectory` (YAML or JSON, also inside a moveit_msgs/RobotTrajectory), mapped to the
arm's joints BY NAME (`read_joint_path`). Only the geometry is kept; times, if given, must rise. Every
malformed input is refused in one line naming it (retime.py's docstring lists what is refused)."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import yaml

from qmt_drake.config.fields import show, yaml_problem
from qmt_drake.errors import QmtInputError

TIME_KEYS = ("time_s", "t_s", "time", "time_from_start")


def source_name(source) -> str:
    """How a path is named in a refusal: its file, or "joint path" for data given in memory."""
    return f"path {source}" if source is not None else "joint path"


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _rows_to_array(names, rows, joint_names, where: str) -> np.ndarray:
    """(K, n) in the scenario's joint order from rows of values under `names` (one line per misfit)."""
    names = [str(x).strip() for x in names]
    arm = list(joint_names)
    if len(set(names)) != len(names):  # before "missing": a name given twice is why another is missing
        twice = next(x for x in names if names.count(x) > 1)
        raise QmtInputError(f"{where}: joint {twice!r} is named twice; give each joint once")
    unknown = [x for x in names if x not in arm]
    if unknown:
        sep = next((c for c in ";\t|" if c in unknown[0]), None)
        if sep is not None:  # e.g. a spreadsheet's semicolon-separated export
            raise QmtInputError(f"{where}: columns separated by {sep!r}; separate them by commas")
        raise QmtInputError(f"{where}: joint {unknown[0]!r} is not a moving joint of the arm; its joints are "
                            f"{', '.join(arm)} (rename the column, drop it, or unlock that joint in the scenario)")
    missing = [x for x in arm if x not in names]
    if missing:
        raise QmtInputError(f"{where}: no column for joint {missing[0]!r}; give every joint of the arm: {', '.join(arm)}")
    out = []
    for k, row in enumerate(rows):
        if len(row) != len(names):
            raise QmtInputError(f"{where}: waypoint {k} has {len(row)} values for {len(names)} joints; give one "
                                "value per named joint")
        try:
            if any(isinstance(v, (bool, np.bool_)) for v in row):  # YAML's `true` is no angle (float() made it 1 rad)
                raise TypeError
            vals = [float(v) for v in row]
        except (TypeError, ValueError):
            raise QmtInputError(f"{where}: waypoint {k} has a value that is not a number ({row}); give radians") from None
        out.append(vals)
    Q = np.array(out, float).reshape(len(out), len(names))
    return Q[:, [names.index(x) for x in arm]]


def parse_csv(text: str, joint_names, where: str = "joint path") -> np.ndarray:
    """(K, n) waypoints of a CSV with a header row of joint names (a time column is dropped)."""
    rows = [r for r in csv.reader(io.StringIO(text)) if r and any(c.strip() for c in r)]
    if not rows:
        raise QmtInputError(f"{where}: empty; give a header row of joint names and one waypoint a row")
    header = [c.strip() for c in rows[0]]
    if all(_is_number(c) for c in header):  # the first row is already a waypoint
        raise QmtInputError(f"{where}: the first row holds numbers, not joint names; add a header row naming each "
                            f"column's joint ({', '.join(joint_names)})")
    keep = [i for i, c in enumerate(header) if c not in TIME_KEYS]
    body = [[r[i] for i in keep] if len(r) == len(header) else r for r in rows[1:]]
    Q = _rows_to_array([header[i] for i in keep], body, joint_names, where)
    for i in (i for i, c in enumerate(header) if c in TIME_KEYS):  # ignored, but refused out of order as YAML's are
        t = [r[i].strip() for r in rows[1:] if len(r) == len(header)]
        if not all(_is_number(x) for x in t):
            raise QmtInputError(f"{where}: column {header[i]} holds a value that is not a time ("
                                f"{next(x for x in t if not _is_number(x))!r}); give seconds or drop the column")
        _times_rise([float(x) for x in t], where, f"column {header[i]}", "waypoint")
    return Q


def _seconds(t, where: str, k: int) -> float:
    """time_from_start as seconds: {sec, nanosec} (ROS 2), {secs, nsecs} (ROS 1) or a number."""
    try:
        if isinstance(t, dict):
            return float(t.get("sec", t.get("secs", 0))) + 1e-9 * float(t.get("nanosec", t.get("nsecs", 0)))
        return float(t)
    except (TypeError, ValueError):
        raise QmtInputError(f"{where}: point {k}'s time_from_start {t!r} is not a time; give {{sec, nanosec}}") from None


def _times_rise(times: list, where: str, what: str, item: str) -> None:
    """Refuse times that do not rise (points out of order or repeated)."""
    if len(times) > 1 and np.any(np.diff(times) <= 0):
        k = int(np.argmax(np.diff(times) <= 0)) + 1
        raise QmtInputError(f"{where}: {what} does not rise at {item} {k} ({times[k - 1]:g} s then "
                            f"{times[k]:g} s); the {item}s are out of order or repeated")


def parse_joint_trajectory(msg, joint_names, where: str = "joint path") -> np.ndarray:
    """(K, n) waypoints of a JointTrajectory mapping (or a RobotTrajectory's joint_trajectory)."""
    if isinstance(msg, dict) and "joint_names" not in msg and isinstance(msg.get("joint_trajectory"), dict):
        msg = msg["joint_trajectory"]
    if not isinstance(msg, dict) or "joint_names" not in msg or not isinstance(msg.get("points"), list):
        raise QmtInputError(f"{where}: not a trajectory_msgs/JointTrajectory (needs joint_names and points); "
                            "give the message as MoveIt writes it, or a CSV with a header of joint names")
    points = msg["points"]
    if any(not isinstance(p, dict) or not isinstance(p.get("positions"), list) for p in points):
        raise QmtInputError(f"{where}: every point needs a positions list (radians)")
    times = [_seconds(p["time_from_start"], where, k) for k, p in enumerate(points) if "time_from_start" in p]
    if len(times) == len(points):
        _times_rise(times, where, "time_from_start", "point")
    if not isinstance(msg["joint_names"], (list, tuple)):  # a string was read letter by letter
        raise QmtInputError(f"{where}: joint_names must be a list of joint names, got {show(msg['joint_names'])}")
    return _rows_to_array(msg["joint_names"], [p["positions"] for p in points], joint_names, where)


def read_joint_path(source, joint_names) -> np.ndarray:
    """(K, n) waypoints (rad) in `joint_names` order from a file (.csv, or .yaml/.yml/.json: a
    JointTrajectory), a JointTrajectory mapping, or a (K, n) array already in that order."""
    if isinstance(source, (str, Path)):
        p = Path(source)
        where = source_name(p)
        try:
            text = p.read_text(encoding="utf-8-sig")  # -sig: a spreadsheet's CSV starts with a byte-order mark
        except OSError as exc:
            raise QmtInputError(f"{where}: cannot read it ({exc.strerror}); give a CSV or a JointTrajectory "
                                "YAML/JSON file") from None
        except UnicodeDecodeError:
            raise QmtInputError(f"{where}: not a text file (not UTF-8); give a CSV or a JointTrajectory "
                                "YAML/JSON file") from None
        if p.suffix.lower() == ".csv":
            return parse_csv(text, joint_names, where)
        if p.suffix.lower() not in (".yaml", ".yml", ".json"):
            raise QmtInputError(f"{where}: unknown file type {p.suffix!r}; give .csv (header of joint names) or "
                                ".yaml/.yml/.json (a JointTrajectory)")
        try:
            msg = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise QmtInputError(f"{where}: not YAML/JSON ({yaml_problem(exc, text)})") from None
        return parse_joint_trajectory(msg, joint_names, where)
    if isinstance(source, dict):
        return parse_joint_trajectory(source, joint_names)
    fix = (f"give a (K, {len(joint_names)}) array of numbers (radians) in the order {', '.join(joint_names)}, or a "
           "file with joint names")
    try:
        if np.asarray(source).dtype.kind == "b":
            raise TypeError
        Q = np.asarray(source, float)
    except (TypeError, ValueError):  # ragged rows, text, booleans
        raise QmtInputError(f"joint path: a {type(source).__name__} of ragged rows, text or booleans; {fix}") from None
    if Q.ndim != 2 or Q.shape[1] != len(joint_names):
        raise QmtInputError(f"joint path: give a (K, {len(joint_names)}) array in the order {', '.join(joint_names)} "
                            f"(got shape {Q.shape}), or a file with joint names")
    return Q
