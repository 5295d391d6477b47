"""A URDF's XML checked by vjm before the URDF parser sees it.

The parser (urdfdom inside pinocchio) reports a malformed file by printing lines of its own C++ source on
stderr and then failing with a generic message, or not at all: a NaN mass is dropped, a kinematic cycle
makes joints vanish.  Every number it would read, and the tree it would build, is checked here first and
refused with one line naming the element and what is wrong.  Units are the URDF's: metres, kilograms.
"""
from __future__ import annotations

import numpy as np

from ..errors import VjmError

#: the joint types of URDF
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: a URDF's size and its deepest chain of joints, checked before the parser gets it: the parser recurses
#: once per joint and overflows its stack (SIGSEGV) near 5,000; a real robot has tens
URDF_MAX_BYTES = 20_000_000
URDF_MAX_DEPTH = 1000
#: attributes the parser reads as numbers, and how many each holds (0: one or more)
NUMERIC = {"xyz": 3, "rpy": 3, "value": 1, "ixx": 1, "ixy": 1, "ixz": 1, "iyy": 1, "iyz": 1, "izz": 1,
           "lower": 1, "upper": 1, "effort": 1, "velocity": 1, "damping": 1, "friction": 1, "multiplier": 1,
           "offset": 1, "radius": 1, "length": 1, "size": 3, "scale": 3, "soft_lower_limit": 1,
           "soft_upper_limit": 1, "k_position": 1, "k_velocity": 1, "rising": 1, "falling": 1}
#: no number of a URDF (m, kg, kg m^2, N, rad/s) is this large: 10 km, 10,000 t
URDF_MAX_VALUE = 1e4
#: the largest mass (kg) of one link: 100 t (the largest industrial robots weigh a few tonnes)
MAX_MASS_KG = 1e5


def _where(e, owner: dict) -> str:
    """``<origin> of joint 'j1'``: the element and the named link or joint it is in."""
    tag = e.tag if isinstance(e.tag, str) else "?"
    up = owner.get(e)
    while up is not None and up.get("name") is None:
        up = owner.get(up)
    return f"<{tag}>" + ("" if up is None or up is e else f" of {up.tag} {up.get('name')!r}")


def _numbers(root, path: str) -> None:
    """Every numeric attribute: finite numbers, as many as the parser reads, none beyond :data:`URDF_MAX_VALUE`."""
    owner = {c: p for p in root.iter() for c in p}
    for e in root.iter():
        for key, text in e.attrib.items():
            count = NUMERIC.get(key)
            if count is None or (key == "value" and e.tag != "mass"):
                continue
            parts = text.split()
            try:
                vals = [float(t) for t in parts]
            except ValueError:
                vals = []
            where = _where(e, owner)
            if not vals or (count and len(vals) != count) or not all(np.isfinite(vals)):
                n = f"{count} finite number{'s' if count > 1 else ''}" if count else "finite numbers"
                raise VjmError(f"{path}: {where}: {key} must be {n}, got {text!r}")
            if e.tag != "mass" and max(abs(v) for v in vals) > URDF_MAX_VALUE:
                raise VjmError(f"{path}: {where}: {key}={text!r} is beyond {URDF_MAX_VALUE:g} (10 km, or as many "
                               f"kg m^2, N or rad/s: a URDF is in metres and kilograms)")


def _joints(root, links: set, path: str) -> dict:
    """Joint types, names, limits and axes; returns {child link: joint}."""
    child_of: dict = {}
    names: set = set()
    for j in root.findall("joint"):
        name, jt = j.get("name"), j.get("type")
        if name in names:
            raise VjmError(f"{path}: two joints named {name!r}")
        names.add(name)
        if jt not in JOINT_TYPES:
            raise VjmError(f"{path}: joint {name!r}: unknown type {jt!r}; known: {', '.join(JOINT_TYPES)}")
        ends = []
        for tag in ("parent", "child"):
            e = j.find(tag)
            ln = None if e is None else e.get("link")
            if ln not in links:
                raise VjmError(f"{path}: joint {name!r}: its {tag} link {ln!r} is not defined in the file")
            ends.append(ln)
        if ends[0] == ends[1]:
            raise VjmError(f"{path}: joint {name!r}: link {ends[0]!r} is both its parent and its child (a cycle)")
        if ends[1] in child_of:
            raise VjmError(f"{path}: link {ends[1]!r} is the child of two joints ({child_of[ends[1]].get('name')!r} "
                           f"and {name!r}): a kinematic loop, which a URDF tree cannot describe")
        child_of[ends[1]] = j
        if jt in ("revolute", "prismatic", "continuous"):
            _moving(j, name, jt, path)
    return child_of


def _moving(j, name: str, jt: str, path: str) -> None:
    axis = j.find("axis")
    if axis is not None and axis.get("xyz") is not None:
        a = np.array([float(t) for t in axis.get("xyz").split()])
        if not np.linalg.norm(a) > 1e-9:
            raise VjmError(f"{path}: joint {name!r}: axis xyz={axis.get('xyz')!r} is zero; a {jt} joint needs a "
                           f"direction")
    if jt == "continuous":
        return
    lim = j.find("limit")
    if lim is None or lim.get("effort") is None or lim.get("velocity") is None:
        raise VjmError(f"{path}: joint {name!r}: a {jt} joint needs <limit lower=... upper=... effort=... "
                       f"velocity=...> (effort and velocity required)")
    lo, hi = float(lim.get("lower", 0)), float(lim.get("upper", 0))
    if lo > hi:
        raise VjmError(f"{path}: joint {name!r}: limit lower {lo:g} is above upper {hi:g}")


def _tree(root, links: list, child_of: dict, path: str) -> None:
    """One root link, no cycle, no mimic of a mimic, a chain no deeper than :data:`URDF_MAX_DEPTH`."""
    parent = {c: j.find("parent").get("link") for c, j in child_of.items()}
    rooted: set = set()  # links whose chain of parents ends at a root
    for start in parent:
        seen = [start]
        link = parent[start]
        while link in parent and link not in rooted and link not in seen:
            seen.append(link)
            link = parent[link]
        if link in seen:
            cyc = seen[seen.index(link):]
            names = [child_of[c].get("name") for c in cyc]
            raise VjmError(f"{path}: a kinematic cycle: links {' <- '.join(cyc + [link])} (joints "
                           f"{', '.join(names)}); a URDF is a tree")
        rooted.update(seen)
    roots = [ln for ln in links if ln not in parent]
    if len(roots) != 1:
        raise VjmError(f"{path}: {len(roots)} root links ({', '.join(roots[:5])}{' ...' if len(roots) > 5 else ''}): "
                       f"a URDF has one link that no joint holds, the others joined to it")
    mimics = {j.get("name"): j.find("mimic").get("joint") for j in root.findall("joint") if j.find("mimic") is not None}
    joints = {j.get("name") for j in root.findall("joint")}
    for name, master in mimics.items():
        if master not in joints:
            raise VjmError(f"{path}: joint {name!r}: mimics joint {master!r}, which the file does not define")
        if master in mimics:
            raise VjmError(f"{path}: joint {name!r}: mimics joint {master!r}, itself a mimic; mimic the joint "
                           f"{master!r} follows")
    _check_depth(path, parent)


def check_xml(raw: bytes, path: str) -> dict:
    """What the URDF parser reports badly or not at all, named here (see the module docstring); returns
    {link: its mass (kg)} of the links that declare an inertial."""
    import xml.etree.ElementTree as ET

    if raw[:2] in (b"\xff\xfe", b"\xfe\xff") or raw[:4] in (b"\x00<\x00?", b"<\x00?\x00"):
        raise VjmError(f"{path}: a URDF in UTF-16; the URDF parser reads UTF-8: save it as UTF-8")
    try:
        root = ET.fromstring(raw)
    except ET.ParseError as exc:
        raise VjmError(f"{path}: not a valid URDF: {exc}") from None
    if root.tag != "robot":
        raise VjmError(f"{path}: the root element is <{root.tag}>; a URDF's is <robot>")
    _numbers(root, path)
    names = [e.get("name") for e in root.findall("link")]
    twice = sorted({n for n in names if names.count(n) > 1}, key=str)
    if twice:
        raise VjmError(f"{path}: two links named {twice[0]!r}")
    if None in names:
        raise VjmError(f"{path}: a <link> without a name")
    child_of = _joints(root, set(names), path)
    _tree(root, names, child_of, path)
    return _inertials(root, path)


def _inertials(root, path: str) -> dict:
    declared = {}
    for link in root.findall("link"):
        inert = link.find("inertial")
        if inert is None:
            continue
        me = inert.find("mass")
        val = None if me is None else me.get("value")
        mass = float(val) if val is not None else None  # a number: _numbers checked it
        declared[link.get("name")] = mass
        if mass is None or mass < 0:
            raise VjmError(f"{path}: link {link.get('name')!r}: inertial mass must be a number >= 0 (kg), got {val!r}")
        if mass > MAX_MASS_KG:
            raise VjmError(f"{path}: link {link.get('name')!r}: a mass of {mass:g} kg, above {MAX_MASS_KG:g} kg (100 t) "
                           f"for one link: a URDF is in kilograms")
        if mass > 0 and inert.find("origin") is None:
            raise VjmError(f"{path}: link {link.get('name')!r}: a mass of {mass:g} kg without a centre of mass "
                           f"(<origin xyz=...> in <inertial>)")
        ie = inert.find("inertia")
        if ie is None or any(ie.get(k) is None for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")):
            raise VjmError(f"{path}: link {link.get('name')!r}: an inertial needs <inertia ixx=... ixy=... ixz=... "
                           f"iyy=... iyz=... izz=...> (all six)")
    return declared


def _check_depth(path: str, parent: dict) -> None:
    """Refuse a chain of more than :data:`URDF_MAX_DEPTH` joints (``parent``: {child link: parent link})."""
    depth: dict = {}
    for link in parent:
        chain = []
        while link in parent and link not in depth and len(chain) <= len(parent):
            chain.append(link)
            link = parent[link]
        d = depth.get(link, 0)
        for k in reversed(chain):
            d += 1
            depth[k] = d
            if d > URDF_MAX_DEPTH:
                raise VjmError(f"{path}: a chain of more than {URDF_MAX_DEPTH:,} joints (down to link {k!r}); a "
                               f"robot has tens, and the URDF parser cannot take such a depth")
