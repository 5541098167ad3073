"""Plan identity by content: a plan file records what its scenario WAS (arm, hand, limits, task,
family, ...), not just its name, and a plan is refused on a scenario whose content differs, whatever
the names say (issue 30: a copy of a scenario with the same name but 1 rad/s joint limits accepted a
plan made for the original and carried it at 3.14x its new limit).

The record, `scenario_identity` in every plan file (transfer, spatial, energy-time):

    {"sha256": <hash of the section hashes>, "sections": {"arm": <sha256>, "limits": <sha256>, ...}}

Each section's hash is the sha256 of a canonical JSON of the validated data of that section (floats
to 12 significant digits, so the last bits of a derived value never refuse a plan); a file the
scenario reads (the URDF) counts by its bytes, not its path. Left out: the name, the description,
notes, file locations, output paths, and what only steers a planner (GA settings, controller gains).
Each scenario kind says which data make up which section (`transfer_sections`, `spatial_sections`,
`energy_sections`).

Files written before the record existed are accepted with the checks they had (the scenario's name,
joint count, task points, start and goal): they are every plan saved so far, the goldens included,
and refusing them would break them all for a risk those checks already bound; `identity_line` says
so where a caller wants to tell the user.
"""

from __future__ import annotations

import hashlib
import json
import numbers
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import Any

import numpy as np

from qmt_drake.errors import QmtInputError

IDENTITY_KEY = "scenario_identity"
SIGNIFICANT_DIGITS = 12


def canonical(x: Any) -> Any:
    """JSON-ready data of validated sections: dataclasses, plain objects' public attributes, arrays;
    floats rounded to SIGNIFICANT_DIGITS and written as strings (exact, stable)."""
    if is_dataclass(x) and not isinstance(x, type):
        return {f.name: canonical(getattr(x, f.name)) for f in fields(x)}
    if isinstance(x, dict):
        return {str(k): canonical(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [canonical(v) for v in x]
    if isinstance(x, np.ndarray):
        return canonical(x.tolist())
    if isinstance(x, np.generic):
        return canonical(x.item())
    if isinstance(x, Path):  # a file counts by its bytes, never by where the checkout lies
        return {"file_sha256": file_sha256(x)} if x.is_file() else x.name
    if isinstance(x, bool) or x is None or isinstance(x, str):
        return x
    if isinstance(x, numbers.Integral):
        return int(x)
    if isinstance(x, numbers.Real):
        return f"{float(x):.{SIGNIFICANT_DIGITS}g}"
    if callable(x):
        return getattr(x, "__qualname__", type(x).__name__)
    if hasattr(x, "__dict__"):
        return {"type": type(x).__name__,
                **{k: canonical(v) for k, v in vars(x).items() if not k.startswith("_")}}
    raise TypeError(f"no canonical form for {type(x).__name__}")


def file_sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _sha(data: Any) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def identity(sections: dict[str, Any]) -> dict:
    """The `scenario_identity` record of {section name: its data}."""
    hashes = {name: _sha(canonical(data)) for name, data in sections.items()}
    return {"sha256": _sha(hashes), "sections": hashes}


def has_identity(d: dict) -> bool:
    rec = d.get(IDENTITY_KEY)
    return isinstance(rec, dict) and isinstance(rec.get("sha256"), str)


def differing_sections(d: dict, sections: dict[str, Any]) -> list[str] | None:
    """The plan file's mapping `d` against the scenario it is run on (its `sections`): None for a
    file written before identities, [] for the same content, else the names of the sections that
    differ (['content'] if the file's record names none)."""
    if not has_identity(d):
        return None
    rec, mine = d[IDENTITY_KEY], identity(sections)
    if rec["sha256"] == mine["sha256"]:
        return []
    theirs = rec.get("sections") if isinstance(rec.get("sections"), dict) else {}
    return sorted(k for k in set(theirs) | set(mine["sections"]) if theirs.get(k) != mine["sections"].get(k)) \
        or ["content"]


def differ_note(differ: list[str] | None) -> str:
    """' (limits, task differ)' for a refusal's line; '' without a record."""
    return f" ({', '.join(differ)} differ)" if differ else ""


def check_identity(d: dict, path: str | Path, sections: dict[str, Any], scenario_name: str) -> bool:
    """True when the plan file's mapping `d` carries an identity equal to that of `sections` (the
    scenario the plan is run on); False for a file written before identities (the caller keeps its
    name check then). Other content: one-line QmtInputError naming the sections that differ,
    whatever the names say."""
    differ = differing_sections(d, sections)
    if differ is None:
        return False
    if differ:
        raise QmtInputError(f"plan file {path} was made for scenario {d.get('scenario')!r} with other content than "
                            f"scenario {scenario_name!r}{differ_note(differ)}; plan again with `qmt-drake plan "
                            f"{scenario_name} --json PATH`")
    return True


def transfer_sections(sc: Any) -> dict[str, Any]:
    """A transfer scenario's (config/sections.Scenario) content that determines its plans: the arm
    (URDF bytes, hand frame), payload, hand, actuator, limits, task, family and world (gravity)."""
    arm = canonical(sc.arm_spec) if sc.arm_spec is not None else {}
    if isinstance(arm, dict):
        arm.pop("urdf_path", None)
    return {"arm": {"urdf_sha256": file_sha256(sc.urdf_path), "hand_frame": sc.hand_frame, "spec": arm},
            "payload": sc.payload, "hand": sc.hand, "actuator": sc.actuator, "limits": sc.limits,
            "task": sc.task, "family": sc.family, "world": sc.world}


def spatial_sections(sc: Any) -> dict[str, Any]:
    """A spatial scenario's (spatial_task.SpatialScenario) content that determines its plans."""
    grip = sc.grip
    grip_data = None if grip is None else {k: getattr(grip, k) for k in (
        "radius_m", "pull_force_N", "friction", "rim_points", "pyramid_edges", "pyramid_angle_rad", "basis")}
    return {"arm": {"urdf_sha256": file_sha256(sc.urdf), "hand_frame": sc.hand_frame,
                    "lock_joints": sc.lock_joints, "joint_names": sc.joint_names},
            "limits": {"velocity_rad_s": sc.velocity_limit_rad_s, "acceleration_rad_s2": sc.acceleration_limit_rad_s2,
                       "jerk_rad_s3": sc.jerk_limit_rad_s3, "torque_Nm": sc.torque_limit_Nm,
                       "moment_limit_Nm": sc.moment_limit_Nm, "check_rate_hz": sc.check_rate_hz},
            "task": {"poses_m": sc.poses_m, "path_points_m": sc.path_points_m, "pose_normals": sc.pose_normals,
                     "pose_rotations": sc.pose_rotations, "face_axis": sc.face_axis},
            "hand": {"kind": sc.hand_kind, "body": sc.body, "grip": grip_data, "cup": sc.cup},
            "actuator": {"drive": sc.drive, "motor": sc.motor},
            "world": {"gravity_m_s2": sc.gravity_m_s2}}


def energy_sections(E: Any) -> dict[str, Any]:
    """An energy-time experiment's (energy/experiments.Experiment) content that determines its plans:
    the arm (None: the Ohsaka arm), the task (start/goal coordinates, moving joints, a fixed motion
    time) and the torque limits. The cost weights, harmonics and divisions travel in the file itself."""
    return {"arm": E.arm, "task": {"coordinate_vector_m": E.coordinate_vector_m, "moving_joints": E.moving_joints,
                                   "fixed_T_s": E.fixed_T_s},
            "limits": {"torque_limit_Nm": E.torque_limit_Nm}}
