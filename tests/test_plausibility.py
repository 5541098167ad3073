"""Physical plausibility at load (issue 30 item 4): each implausible input refused in one line naming it,
before any IK or planning; the rigid-body test checked against Drake's own RotationalInertia."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import yaml
from pydrake.multibody.tree import RotationalInertia

from qmt_drake.api import load_scenario
from qmt_drake.config import fields as F
from qmt_drake.config.scenario import SCENARIO_DIR
from qmt_drake.errors import QmtInputError

DROP = object()


def write(tmp_path, base: str, changes: dict, name: str = "case.yaml"):
    raw = copy.deepcopy(yaml.safe_load((SCENARIO_DIR / f"{base}.yaml").read_text()))
    for key, v in changes.items():
        x, keys = raw, key.split(".")
        for k in keys[:-1]:
            x = x[k]
        if v is DROP:
            x.pop(keys[-1], None)
        else:
            x[keys[-1]] = v
    p = tmp_path / name
    p.write_text(yaml.safe_dump(raw))
    return p


def test_principal_moments_accepted_exactly_when_drake_calls_them_physical():
    rng = np.random.default_rng(30)
    agree = 0
    for _ in range(400):
        m = rng.uniform(1e-4, 1e-2, 3) * (rng.uniform(0, 3, 3) ** 2)
        drake = RotationalInertia(*m).CouldBePhysicallyValid()
        try:
            F.principal_inertia({"I": m.tolist()}, "I", "payload")
            ours = True
        except QmtInputError as exc:
            assert "\n" not in str(exc) and "payload.I" in str(exc)
            ours = False
        # Drake's own test has a small relative tolerance; only clear cases must agree
        if abs(min(m[0] + m[1] - m[2], m[1] + m[2] - m[0], m[0] + m[2] - m[1])) > 1e-6 * m.sum():
            assert ours == drake, m
            agree += 1
    assert agree > 300


CASES = [  # (base scenario, changes, words the one line must have)
    ("ur5-suction-bins", {"payload.inertia_kgm2": [0.001, 0.001, 0.05]}, ["payload.inertia_kgm2", "no rigid body"]),
    ("ur5-suction-bins", {"payload.inertia_kgm2": [0.0, 0.01, 0.01]}, ["payload.inertia_kgm2", "positive"]),
    ("ur5-suction-bins", {"payload.mass_kg": 1e9}, ["payload", "at rest", "mass_kg"]),
    ("ur5-suction-bins", {"payload.com_m": [1.0, 0.0, 0.08]}, ["payload", "suction hand", "at rest"]),
    ("ur5-suction-bins", {"arm.face_axis": [0, 0, 0]}, ["arm.face_axis", "no direction"]),
    ("ur5-suction-bins", {"task.face_normal": [0.0, 0.0, 0.0]}, ["face_normal", "no direction"]),
    ("panda-tray-cup", {"arm.lock_joints": None}, ["arm.lock_joints", "list of joint names"]),
    ("panda-tray-cup", {"arm.lock_joints": "panda_finger_joint1"}, ["arm.lock_joints", "'panda_finger_joint1'"]),
    ("ur5-suction-bins", {"hand.rim_points": 10 ** 9}, ["hand.rim_points", "<= 32"]),
    ("ur5-suction-bins", {"hand.pyramid_edges": 10 ** 7}, ["hand.pyramid_edges", "<= 32"]),
    ("ur5-suction-bins", {"hand.rim_points": 32, "hand.pyramid_edges": 16}, ["rim_points x pyramid_edges", "256"]),
    ("ur5-suction-bins", {"limits.check_rate_hz": 1e9}, ["check_rate_hz", "cap"]),
    ("ur5-suction-bins", {"task.transfer_points": 10 ** 6}, ["transfer_points", "cap"]),
    ("ur5-suction-bins", {"task.poses_m": [[0.45, -0.3, 0.1 + 1e-3 * k] for k in range(101)]}, ["poses_m", "cap"]),
    ("ur5-suction-bins", {"task.seed_rad": [-34.0, -75.0, 92.0, -109.0, -90.0, 0.0]}, ["seed_rad", "degrees"]),
    ("ur5-suction-bins", {"task.face_normal": DROP, "task.hand_rpy_rad": [[180.0, 0.0, 0.0] for _ in range(4)]},
     ["hand_rpy_rad", "degrees"]),
    ("ur5-suction-bins", {"arm.package": DROP, "arm.urdf": "."}, ["arm.urdf", "is a directory"]),
    ("ur5-suction-bins", {"arm.package": DROP, "arm.urdf": "page.html"}, ["arm.urdf", "not a URDF"]),
    ("ur5-suction-bins", {"kind": "spatial_trasfer"}, ["kind 'spatial_trasfer'", "spatial_transfer"]),
    ("ur5-suction-bins", {"kind": DROP}, ["no top-level kind", "kind: spatial_transfer"]),
    ("crane-tray", {"actuator.p": [0, 0, 0], "actuator.i": [0, 0, 0], "actuator.d": [0, 0, 0]}, ["p = i = 0"]),
    ("crane-tray", {"actuator.control_period_s": 1e-7}, ["control_period_s", "0.0001"]),
    ("crane-tray", {"actuator.control_period_s": 1.0}, ["control_period_s", "0.1"]),
]


@pytest.mark.parametrize("base,changes,words", CASES, ids=[f"{c[0]}:{','.join(c[1])}" for c in CASES])
def test_implausible_input_is_refused_in_one_line_naming_it(tmp_path, base, changes, words):
    (tmp_path / "page.html").write_text("<!doctype html><html><body>a page</body></html>\n")
    with pytest.raises(QmtInputError) as err:
        load_scenario(write(tmp_path, base, changes))
    text = str(err.value)
    assert "\n" not in text
    for w in words:
        assert w in text, (w, text)


def test_plausible_neighbours_still_load(tmp_path):
    # the refusals are not over-broad: a valid inertia on the boundary's right side, a non-unit face axis,
    # a grip of 16 x 16 generators, lock_joints as a list and 2 pi radians all load
    ok = [("ur5-suction-bins", {"payload.inertia_kgm2": [0.005, 0.005, 0.0099]}),
          ("ur5-suction-bins", {"arm.face_axis": [0.0, 0.0, 2.0]}),
          ("ur5-suction-bins", {"hand.rim_points": 8, "hand.pyramid_edges": 8}),
          ("panda-tray-cup", {"arm.lock_joints": ["panda_finger_joint1", "panda_finger_joint2"]})]
    for k, (base, changes) in enumerate(ok):
        sc = load_scenario(write(tmp_path, base, changes, f"ok{k}.yaml"))
        assert sc.n_dof >= 6
    sc = load_scenario(write(tmp_path, "ur5-suction-bins", {"arm.face_axis": [0.0, 0.0, 2.0]}, "axis.yaml"))
    assert np.allclose(sc.face_axis, [0.0, 0.0, 1.0])


def test_yaml_aliases_and_oversized_files_are_refused_unread(tmp_path):
    p = tmp_path / "alias.yaml"
    p.write_text("a: &x [1, 2]\nb: *x\n")  # an alias is read as written out (yaml.safe_dump writes them)
    assert F.read_yaml_mapping(p) == {"a": [1, 2], "b": [1, 2]}
    lines = ["l0: &l0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"] + [
        f"l{k}: &l{k} [{', '.join([f'*l{k - 1}'] * 10)}]" for k in range(1, 9)]  # 10**9 values written out
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(QmtInputError, match="expands through aliases to over 1,000,000 values"):
        F.read_yaml_mapping(p)
    p.write_text("a: &x [1, *x]\n")
    with pytest.raises(QmtInputError, match="alias to itself"):
        F.read_yaml_mapping(p)
    big = tmp_path / "big.yaml"
    big.write_text("a: [" + ", ".join(["1.0"] * 60000) + "]\n")
    with pytest.raises(QmtInputError, match="KiB"):
        F.read_yaml_mapping(big)
    dup = tmp_path / "dup.yaml"
    dup.write_text("a: 1\na: 2\n")
    with pytest.raises(QmtInputError, match="duplicated key 'a' at line 2"):
        F.read_yaml_mapping(dup)
