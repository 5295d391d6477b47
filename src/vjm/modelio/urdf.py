"""A URDF read by pinocchio's parser (the ``pin`` package) into a :class:`~vjm.robot.tree.Tree`.

The URDF is in metres and kilograms; the tree is in millimetres and kilograms: lengths are
multiplied by 1000 here, at the edge, and nowhere else.  Fixed joints become frames of the
joint that carries them (pinocchio merges the masses of rigidly attached links into that
joint's body); floating and planar joints are refused (a robot here is fixed to its base).
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import VjmError, VjmWarning
from ..robot.tree import Body, Frame, Tree, TreeJoint, axis_alignment
from .urdfcheck import URDF_MAX_BYTES, check_xml

#: metres to millimetres (URDF to vjm)
MM = 1000.0
#: the model file's key this format reads (:mod:`vjm.modelio.robotformats`), and how a message names it
KEYS = ("urdf",)
DESCRIBES = "urdf: (a file)"
#: the tool frame a URDF without ``tools:`` prefers (ROS-Industrial's name of the flange's tool frame)
TOOL0 = "tool0"

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
    """The parser's model; what it prints on the process's stderr (file descriptor 2, written by C++, which
    ``sys.stderr`` does not see) captured and given as one line."""
    import tempfile

    with tempfile.TemporaryFile() as cap:
        import sys

        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(cap.fileno(), 2)
        try:
            model, exc = pin.buildModelFromUrdf(path, mimic=mimic), None
        except (ValueError, RuntimeError, IndexError) as e:
            model, exc = None, e
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        cap.seek(0)
        said = _parser_said(cap.read(4096).decode("utf-8", "replace"))
    if exc is not None:
        msg = said or " ".join(str(exc).split()) or "unreadable"
        raise VjmError(f"{path}: not a valid URDF: {msg}")
    if said:
        import warnings

        warnings.warn(f"{path}: the URDF parser says: {said}", VjmWarning, stacklevel=3)
    return model


def _parser_said(text: str) -> str:
    """The parser's first message without its C++ source location (``... at line 124 in .../joint.cpp``)."""
    import re

    for line in text.splitlines():
        line = re.sub(r"\s+at line \d+ in \S+$", "", line.strip())
        line = re.sub(r"^(Error|Warning|Info|Debug):\s*", "", line).strip()
        if line:
            return line
    return ""


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
    joints); default: the links without a child that a joint moves, ``tool0`` or the deepest first."""
    path = os.path.abspath(os.fspath(path))
    if not os.path.isfile(path):
        raise VjmError(f"urdf: file not found: {path}")
    from linkfea.files.atomic import read_user_file

    with_inertial = check_xml(read_user_file(path, "URDF", limit=URDF_MAX_BYTES, error=VjmError), path)
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
    _finite(path, joints, bodies, frames)
    given, got = sum(with_inertial.values()), sum(b.mass for b in bodies)
    if abs(got - given) > 1e-9 * max(given, 1.0):
        raise VjmError(f"{path}: the URDF parser gave the links {got:g} kg in all, the file's inertials "
                       f"{given:g} kg: it dropped or changed a mass it could not read")
    tools = tuple(tools) if tools else _default_tools(path, leaves, frames, joints)
    declared = frozenset(f.joint for f in frames if f.name in with_inertial)
    return Tree(str(plain.name), tuple(joints), tuple(frames), tuple(bodies), tools, path, declared)


def _finite(path: str, joints, bodies, frames) -> None:
    """What the parser gave back: every placement, limit, mass and centre of mass a number (a value it could
    not read it may leave NaN, or drop a link's mass)."""
    for j in joints:
        if not np.all(np.isfinite(j.placement)) or np.isnan(j.lower) or np.isnan(j.upper):
            raise VjmError(f"{path}: joint {j.name!r}: the URDF parser gave a placement or limit that is not a number")
    for b in bodies:
        if not (np.isfinite(b.mass) and np.all(np.isfinite(b.com))):
            raise VjmError(f"{path}: link {b.name!r}: the URDF parser gave a mass or centre of mass that is not a "
                           f"number")
    for f in frames:
        if not np.all(np.isfinite(f.placement)):
            raise VjmError(f"{path}: frame {f.name!r}: the URDF parser gave a placement that is not a number")


def _default_tools(path: str, leaves, frames, joints) -> tuple:
    """The tool frames of a URDF without ``tools:``: its links without a child that a joint moves (a frame fixed
    to the root is no tool), ``tool0`` first if it is one, else the deepest (most joints from the root; the
    first in the file of equals).  A choice among several is said once."""
    import warnings

    at = {f.name: f.joint for f in frames}

    def depth(j: int) -> int:
        n = 0
        while j >= 0:
            n, j = n + 1, joints[j].parent
        return n

    moving = [n for n in leaves if at[n] >= 0]
    if not moving:
        raise VjmError(f"{path}: no link without a child is moved by a joint (childless links: "
                       f"{', '.join(leaves) or 'none'}); name the tool frame under tools:")
    best = TOOL0 if TOOL0 in moving else max(moving, key=lambda n: depth(at[n]))
    tools = (best,) + tuple(n for n in moving if n != best)
    if len(tools) > 1:
        why = "ROS-Industrial's tool frame" if best == TOOL0 else f"{depth(at[best])} joints from the root, the deepest"
        warnings.warn(f"{os.path.basename(path)}: no tools: named; tool frame {best!r} chosen ({why}; the others: "
                      f"{', '.join(tools[1:])}); name it under tools: to say so", VjmWarning, stacklevel=4)
    return tools


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
