"""The numbers and names of a URDF's joints, checked before anything reads them.

`check_joint_fields(root, source)` refuses, in one line naming the joint, the attribute and the fix
(QmtInputError), a joint without a name, a parent or a child link, or naming a link the file does
not declare; an <origin xyz/rpy> or <axis xyz> that is not three
finite numbers (Drake's parser names a zero axis itself); a <limit> attribute that is not a finite
number, or a revolute or prismatic joint whose lower limit exceeds its upper one. Without it, these reach Drake's parser, which raises a bare
ValueError or aborts in a C++ assertion (a joint's lower limit above its upper one), or this
package's own readers (locks, the chain walk), which raise AttributeError or ValueError."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

from qmt_drake.errors import QmtInputError

_LIMIT_ATTRS = ("lower", "upper", "effort", "velocity")


def _numbers(text: str, count: int) -> list[float] | None:
    """`count` finite floats from a whitespace-separated attribute, or None."""
    try:
        vals = [float(x) for x in text.split()]
    except ValueError:
        return None
    return vals if len(vals) == count and all(math.isfinite(v) for v in vals) else None


def check_joint_fields(root: ET.Element, source: str) -> None:
    """Refuse (QmtInputError, one line) the first malformed joint of `root` (module docstring)."""
    if root.tag != "robot":
        return  # the callers name a file without <robot> themselves
    links = {lk.get("name") for lk in root.findall("link")}
    if not links:
        raise QmtInputError(f"{source}: the URDF declares no <link> (a xacro file? expand it with `xacro FILE > "
                            "FILE.urdf` first); give a URDF with the arm's links and joints")
    for j in root.findall("joint"):
        name = j.get("name")
        if not name:
            raise QmtInputError(f"{source}: a <joint> has no name attribute; name every joint")
        for tag in ("parent", "child"):
            el = j.find(tag)
            link = None if el is None else el.get("link")
            if not link:
                raise QmtInputError(f"{source}: joint {name!r} has no <{tag} link=\"...\"/>; give its {tag} link")
            if link not in links:
                raise QmtInputError(f"{source}: joint {name!r} names {tag} link {link!r}, which the URDF does not "
                                    "declare (no <link name=...> of that name); fix the name or add the link")
        for tag, attr, default in (("origin", "xyz", "0 0 0"), ("origin", "rpy", "0 0 0"), ("axis", "xyz", "1 0 0")):
            el = j.find(tag)
            text = default if el is None else el.get(attr, default)
            vals = _numbers(text, 3)
            if vals is None:
                raise QmtInputError(f"{source}: joint {name!r} <{tag} {attr}=\"{text}\">: give three finite numbers")
        lim = j.find("limit")
        if lim is None:
            continue
        given = {}
        for attr in _LIMIT_ATTRS:
            if attr in lim.attrib:
                vals = _numbers(lim.get(attr), 1)
                if vals is None:
                    raise QmtInputError(f"{source}: joint {name!r} <limit {attr}=\"{lim.get(attr)}\">: give a finite "
                                        "number (rad or m; N m or N; rad/s or m/s)")
                given[attr] = vals[0]
        if (j.get("type") in ("revolute", "prismatic") and "lower" in given and "upper" in given
                and given["lower"] > given["upper"]):
            raise QmtInputError(f"{source}: joint {name!r} <limit lower=\"{lim.get('lower')}\" upper="
                                f"\"{lim.get('upper')}\">: the lower limit exceeds the upper one; swap them")
