"""The kinematic tree of a serial or tree robot (read from a URDF or a DH table), in mm and kg.

A :class:`Tree` is pinocchio's model reduced to what the virtual joint method needs: joints
(revolute, continuous, prismatic; a ``mimic`` joint follows another one), the frames fixed to
them (tool frames, spring frames) and the bodies' masses and centres of mass.  Every quantity
here is in mm, kg and rad: a URDF's metres are converted where it is read (:mod:`vjm.modelio.urdf`).

From the tree, :func:`path_chain` writes the :class:`vjm.kinematics.chain.Chain` from the base to one
frame -- the product of constant placements, joint factors and virtual springs (eq. 1) -- so
that a serial robot's Jacobians, stiffness and nonlinear equilibrium come from the same chain
machinery as a parallel machine's.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import VjmError
from ..kinematics.chain import Chain, ChainBuilder
from ..kinematics.transforms import KINDS, elementary

JOINT_TYPES = ("revolute", "continuous", "prismatic")


@dataclass(frozen=True)
class TreeJoint:
    """One joint: ``placement`` (4x4, mm) from its parent joint's frame (the base if ``parent`` is -1)
    at zero joint value, then ``kind(coef * q + offset)`` about/along an axis of the frame ``align``
    (a constant rotation taking the joint's axis to the axis of ``kind``; identity if None).

    ``mimic`` is None or (master joint name, multiplier, offset): the joint's value is then
    ``multiplier * q[master] + offset`` and it has no coordinate of its own."""

    name: str
    parent: int
    placement: np.ndarray = field(compare=False)
    kind: str
    type: str
    lower: float = -np.inf
    upper: float = np.inf
    align: np.ndarray | None = field(default=None, compare=False)
    mimic: tuple | None = None
    child: str = ""     # the link it moves (for messages)


@dataclass(frozen=True)
class Body:
    """A rigid body carried by joint ``joint`` (-1: the base): mass (kg) and centre of mass (mm, joint frame)."""

    name: str
    joint: int
    mass: float
    com: np.ndarray = field(compare=False)


@dataclass(frozen=True)
class Frame:
    """A named frame fixed to joint ``joint`` (-1: the base), ``placement`` (4x4, mm) in the joint frame."""

    name: str
    joint: int
    placement: np.ndarray = field(compare=False)


@dataclass(frozen=True, eq=False)
class Tree:
    """Joints in topological order (a parent before its children), frames, bodies and tool frames.

    ``source`` says where the tree came from (the URDF path, or ``"dh"``); ``q_names`` are the
    joints with a coordinate of their own (every joint but the mimic ones), in order: a
    configuration ``q`` has one value per name (rad, or mm for prismatic joints).
    """

    name: str
    joints: tuple[TreeJoint, ...]
    frames: tuple[Frame, ...]
    bodies: tuple[Body, ...]
    tools: tuple[str, ...]
    source: str = ""
    #: joints whose body has a declared inertial (a mass of 0 declared is one): see weight.check_inertials
    declared: frozenset = frozenset()

    def __post_init__(self):
        for i, j in enumerate(self.joints):
            if not -1 <= j.parent < i:
                raise VjmError(f"{self.source}: joint {j.name!r}: its parent must come before it")
            if j.kind not in KINDS or j.type not in JOINT_TYPES:
                raise VjmError(f"{self.source}: joint {j.name!r}: unknown kind {j.kind!r} / type {j.type!r}")
        names = [j.name for j in self.joints]
        for j in self.joints:
            if j.mimic is not None and j.mimic[0] not in self.q_names:
                raise VjmError(f"{self.source}: joint {j.name!r} mimics {j.mimic[0]!r}, which is no independent "
                               f"joint of {', '.join(names)}")
        for t in self.tools:
            self.frame(t)

    @property
    def q_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints if j.mimic is None)

    @property
    def nq(self) -> int:
        return len(self.q_names)

    def joint_index(self, name: str) -> int:
        for i, j in enumerate(self.joints):
            if j.name == name:
                return i
        raise VjmError(f"{self.source}: no joint {name!r}; joints: {', '.join(j.name for j in self.joints)}")

    def frame(self, name: str) -> Frame:
        for f in self.frames:
            if f.name == name:
                return f
        raise VjmError(f"{self.source}: no frame {name!r}; frames: {', '.join(f.name for f in self.frames)}")

    def path(self, joint: int) -> list[int]:
        """Joint indices from the base to ``joint`` (inclusive; empty for the base)."""
        out = []
        while joint >= 0:
            out.append(joint)
            joint = self.joints[joint].parent
        return out[::-1]

    @property
    def limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper limits (nq,) of the independent joints (-inf, inf for continuous joints)."""
        js = [j for j in self.joints if j.mimic is None]
        return np.array([j.lower for j in js]), np.array([j.upper for j in js])


@dataclass(frozen=True)
class ChainSprings:
    """The virtual springs a chain carries: 1-dof joint springs (by joint name), 6x6 joint springs
    (``name.spring6``) and link springs (name -> (joint index, 4x4 spring frame in that joint's frame))."""

    joint: frozenset = frozenset()
    joint6: frozenset = frozenset()
    links: tuple = ()


def _rigid_inverse(T: np.ndarray) -> np.ndarray:
    Ti = np.eye(4)
    Ti[:3, :3] = T[:3, :3].T
    Ti[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return Ti


def _const(b: ChainBuilder, T) -> None:
    if T is not None and not np.array_equal(T, np.eye(4)):
        b.const(T)


def _joint_factor(b: ChainBuilder, j: TreeJoint, springs: ChainSprings) -> None:
    """``align kind(coef q + offset) [kind(theta)] align^-1``: the joint, its 1-dof spring and its 6x6 spring."""
    _const(b, j.placement)
    _const(b, j.align)
    if j.mimic is None:
        if j.name in springs.joint:
            b.actuated(j.kind, j.name, spring=j.name)
        else:
            b.actuated(j.kind, j.name, spring=f"{j.name}.rigid")
    else:
        master, mult, off = j.mimic
        b.coupled(j.kind, master, float(mult), master if master in springs.joint else f"{master}.rigid")
        if off:
            b.const(elementary(j.kind, np.array([float(off)]))[0])
        if j.name in springs.joint:
            b.spring1(j.kind, j.name)
    if j.align is not None:
        _const(b, _rigid_inverse(j.align))
    if j.name in springs.joint6:
        b.spring6(f"{j.name}.spring6")


def path_chain(tree: Tree, joint: int, end: np.ndarray, springs: ChainSprings, name: str):
    """The chain from the base to the frame ``end`` (4x4, mm) of joint ``joint``, and its marks.

    Every independent joint on the path is an actuated variable (its value is ``q``; its spring,
    if any, is named after it), a mimic joint reuses its master's variable with its multiplier,
    and the link springs of each joint's body sit after the joint, in their own frames.

    ``marks``: {joint index: (pre, post)}, the factor indices after which a point moves with the
    joint's body (``pre``: inside the link, before its link springs -- where its own centre of
    mass sits) and with the link's tip (``post``: after them -- frames, payloads, what hangs on).
    """
    b = ChainBuilder(name)
    marks = {}
    for ji in tree.path(joint):
        _joint_factor(b, tree.joints[ji], springs)
        pre = b.size - 1
        for sname, sj, S in springs.links:
            if sj == ji:
                _const(b, S)
                b.spring6(sname)
                _const(b, _rigid_inverse(S))
        marks[ji] = (pre, b.size - 1)
    _const(b, end)
    return b.build(), marks


def chain_values(chain: Chain, tree: Tree, q: np.ndarray) -> np.ndarray:
    """Variable values (n, n_vars) of a chain at configurations q (n, nq): q for the joints, 0 for springs."""
    idx = {name: i for i, name in enumerate(tree.q_names)}
    v = np.zeros((q.shape[0], chain.n_vars))
    for k, (vn, role) in enumerate(zip(chain.var_names, chain.roles)):
        if role == "actuated":
            v[:, k] = q[:, idx[vn]]
    return v


def origin_transform(xyz, rpy) -> np.ndarray:
    """4x4 of a URDF ``origin``: translation ``xyz`` then fixed-axis roll, pitch, yaw (``Rz(y) Ry(p) Rx(r)``)."""
    r, p, y = (float(a) for a in rpy)
    T = elementary("rz", np.array([y]))[0] @ elementary("ry", np.array([p]))[0] @ elementary("rx", np.array([r]))[0]
    T[:3, 3] = np.asarray(xyz, dtype=float)
    return T


def axis_alignment(axis) -> tuple[str, np.ndarray | None]:
    """(axis letter, alignment rotation or None) for a joint axis: ``x``, ``y``, ``z`` directly, any other
    unit vector through a constant rotation taking z onto it."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    for k, e in enumerate(np.eye(3)):
        if np.allclose(a, e, rtol=0, atol=1e-15):
            return "xyz"[k], None
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, a)
    s, c = np.linalg.norm(v), float(z @ a)
    if s < 1e-15:  # a = -z: half a turn about x
        R = np.diag([1.0, -1.0, -1.0])
    else:
        K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / s
        R = np.eye(3) + s * K + (1 - c) * (K @ K)
    A = np.eye(4)
    A[:3, :3] = R
    return "z", A
