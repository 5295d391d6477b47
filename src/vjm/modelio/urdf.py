"""A URDF read by pinocchio's parser (the ``pin`` package) into a :class:`~vjm.robot.tree.Tree`.

The URDF is in metres and kilograms; the tree is in millimetres and kilograms: lengths are
multiplied by 1000 here, at the edge, and nowhere else.  Fixed joints become frames of the
joint that carries them (pinocchio merges the masses of rigidly attached links into that
joint's body); floating and planar joints are refused (a robot here is fixed to its base).
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import VjmError
from ..robot.tree import Body, Frame, Tree, TreeJoint, axis_alignment

#: metres to millimetres (URDF to vjm)
MM = 1000.0
#: the model file's key this format reads (:mod:`vjm.modelio.robotformats`), and how a message names it
KEYS = ("urdf",)
DESCRIBES = "urdf: (a file)"
#: a URDF's size and its deepest chain of joints, checked before the parser gets it: the parser recurses
#: once per joint and overflows its stack (SIGSEGV) near 5,000; a real robot has tens
URDF_MAX_BYTES = 20_000_000
URDF_MAX_DEPTH = 1000

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def _se3(M) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = np.asarray(M.rotation)
    T[:3, 3] = np.asarray(M.translation) * MM
    return T


def _joint_kind(jm, name: str, path: str):
    """(type, axis (3,)) of a pinocchio joint model, or VjmError naming the joint."""
    short = jm.shortname()
    body = short.replace("JointModel", "")
    if body in ("RX", "RY", "RZ"):
        return "revolute", _AXES[body[1]]
    if body in ("RUBX", "RUBY", "RUBZ"):
        return "continuous", _AXES[body[3]]
    if body in ("PX", "PY", "PZ"):
        return "prismatic", _AXES[body[1]]
    ext = jm.extract()
    if body == "RevoluteUnaligned":
        return "revolute", tuple(np.asarray(ext.axis, dtype=float))
    if body == "RevoluteUnboundedUnaligned":
        return "continuous", tuple(np.asarray(ext.axis, dtype=float))
    if body == "PrismaticUnaligned":
        return "prismatic", tuple(np.asarray(ext.axis, dtype=float))
    kind = {"FreeFlyer": "floating", "Planar": "planar"}.get(body, body)
    raise VjmError(f"{path}: joint {name!r} is {kind}: vjm models robots fixed to their base with revolute, "
                   f"continuous, prismatic and fixed joints (floating and planar joints are refused)")


def _build(pin, path: str, mimic: bool):
    import contextlib
    import io

    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            return pin.buildModelFromUrdf(path, mimic=mimic)
    except (ValueError, RuntimeError, IndexError) as exc:
        msg = " ".join(str(exc).split()) or "unreadable"
        raise VjmError(f"{path}: not a valid URDF: {msg}") from None


def recognises(mapping) -> bool:
    """A model file naming a URDF (``urdf: robot.urdf``)."""
    return isinstance(mapping, dict) and "urdf" in mapping


def read(mapping: dict, base_dir: str) -> Tree:
    """The tree of a model file's ``urdf:`` (relative to ``base_dir``), its ``tools:`` the tool frames."""
    if not isinstance(mapping["urdf"], str):
        raise VjmError("urdf must be a file path")
    return read_urdf(os.path.normpath(os.path.join(base_dir, mapping["urdf"])), mapping.get("tools"))


def read_urdf(path, tools=None) -> Tree:
    """The tree of a URDF file (mm, kg).  ``tools``: names of the tool frames (links or fixed
    joints); default: every link without a child."""
    path = os.path.abspath(os.fspath(path))
    if not os.path.isfile(path):
        raise VjmError(f"urdf: file not found: {path}")
    with_inertial = _check_xml(path)
    import pinocchio as pin

    plain = _build(pin, path, False)
    mim = _build(pin, path, True)
    joints: list[TreeJoint] = []
    for j in range(1, plain.njoints):
        name = plain.names[j]
        jtype, axis = _joint_kind(plain.joints[j], name, path)
        letter, align = axis_alignment(axis)
        kind = ("r" if jtype != "prismatic" else "t") + letter
        scale = 1.0 if jtype != "prismatic" else MM
        lo, hi = float(plain.lowerPositionLimit[plain.idx_qs[j]]), float(plain.upperPositionLimit[plain.idx_qs[j]])
        if jtype == "continuous":
            lo, hi = -np.inf, np.inf
        mimic = None
        jm = mim.joints[mim.getJointId(name)]
        if jm.shortname() == "JointModelMimic":
            ext = jm.extract()
            master = next(mim.names[k] for k in range(1, mim.njoints)
                          if mim.joints[k].shortname() != "JointModelMimic" and mim.idx_qs[k] == ext.idx_q)
            mimic = (master, float(ext.scaling), float(ext.offset) * scale)
        child = next((f.name for f in plain.frames if f.type == pin.FrameType.BODY and f.parentJoint == j), "")
        joints.append(TreeJoint(name, int(plain.parents[j]) - 1, _se3(plain.jointPlacements[j]), kind, jtype,
                                lo * scale, hi * scale, align, mimic, child))
    bodies = []
    for j in range(plain.njoints):
        I = plain.inertias[j]
        if I.mass > 0:
            bodies.append(Body(plain.names[j] if j else "base", j - 1, float(I.mass),
                               np.asarray(I.lever, dtype=float) * MM))
    frames, leaves = _frames(pin, plain)
    tools = tuple(tools) if tools else tuple(leaves)
    if not tools:
        raise VjmError(f"{path}: the URDF has no link without a child to serve as a tool frame; name one under tools:")
    declared = frozenset(f.joint for f in frames if f.name in with_inertial)
    return Tree(str(plain.name), tuple(joints), tuple(frames), tuple(bodies), tools, path, declared)


def _frames(pin, model):
    """The URDF's links and fixed joints as frames of their joints, and the links that have no child."""
    frames, parents = [], set()
    for f in model.frames:
        if f.name == "universe":
            continue
        parents.add(int(f.parentFrame))
        frames.append(Frame(f.name, int(f.parentJoint) - 1, _se3(f.placement)))
    leaves = []
    for i, f in enumerate(model.frames):
        if f.type == pin.FrameType.BODY and i not in parents:
            leaves.append(f.name)
    return frames, leaves


def _check_xml(path: str) -> set:
    """What urdfdom reports badly or not at all, named here: a link with two parents (a kinematic loop),
    a joint whose parent or child link does not exist, a joint of unknown type, a mass without an
    origin or a negative one.  Returns the names of the links that declare an inertial."""
    import xml.etree.ElementTree as ET

    from linkfea.files.atomic import read_user_file

    raw = read_user_file(path, "URDF", limit=URDF_MAX_BYTES, error=VjmError)
    try:
        root = ET.fromstring(raw)
    except ET.ParseError as exc:
        raise VjmError(f"{path}: not a valid URDF: {exc}") from None
    links = {e.get("name") for e in root.findall("link")}
    child_of: dict = {}
    for j in root.findall("joint"):
        name, jt = j.get("name"), j.get("type")
        known = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
        if jt not in known:
            raise VjmError(f"{path}: joint {name!r}: unknown type {jt!r}; known: {', '.join(known)}")
        for tag in ("parent", "child"):
            e = j.find(tag)
            ln = None if e is None else e.get("link")
            if ln not in links:
                raise VjmError(f"{path}: joint {name!r}: its {tag} link {ln!r} is not defined in the file")
        c = j.find("child").get("link")
        if c in child_of:
            raise VjmError(f"{path}: link {c!r} is the child of two joints ({child_of[c]!r} and {name!r}): a "
                           f"kinematic loop, which a URDF tree cannot describe")
        child_of[c] = name
    _check_depth(path, {j.find("child").get("link"): j.find("parent").get("link") for j in root.findall("joint")})
    declared = set()
    for link in root.findall("link"):
        inert = link.find("inertial")
        if inert is None:
            continue
        declared.add(link.get("name"))
        me = inert.find("mass")
        val = None if me is None else me.get("value")
        try:
            mass = float(val) if val is not None else None
        except ValueError:
            mass = None
        if mass is None or not np.isfinite(mass) or mass < 0:
            raise VjmError(f"{path}: link {link.get('name')!r}: inertial mass must be a number >= 0 (kg), got {val!r}")
        if mass > 0 and inert.find("origin") is None:
            raise VjmError(f"{path}: link {link.get('name')!r}: a mass of {mass:g} kg without a centre of mass "
                           f"(<origin xyz=...> in <inertial>)")
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
