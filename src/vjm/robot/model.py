"""A serial or tree robot's VJM model, evaluated in joint space.

:class:`RobotModel` holds a :class:`~vjm.robot.tree.Tree` (from a URDF or a DH table) and its
springs: one per joint (torsional, or axial for a prismatic joint; constant or a function of the
joint's value), optional 6x6 joint springs (a bearing's bending about the other axes) and link
springs (vjm's :class:`~vjm.model.links.LinkSpring`: a linkfea result, a beam, a 6x6 matrix).  With
none of them the robot is rigid: kinematics and gravity still work.

It is the ``"serial"`` kind of :class:`vjm.Model`: ``stiffness(q)`` and ``stiffness_map(Q)`` return
the :class:`~vjm.stiffness.linear.StiffnessResult` of a parallel machine (K, C in world axes at the
tool point), batched over configurations ``q`` (n, nq) instead of poses.  The chain from the base to a tool
frame is a :class:`vjm.kinematics.chain.Chain` (eq. 1) and, a serial chain having no passive joint, its
compliance is ``C = sum_s J_s C_s J_s^T`` (eq. 10 with ``J_q`` empty); ``K = C^-1``.  A direction
no spring deflects is rigid: C is then singular, K its pseudo-inverse and ``invertible`` False.
The self-weight equilibrium on the deflected geometry is :func:`vjm.stiffness.nonlinear.deflection_map`,
the one equilibrium solver, with the links' weights as body loads.
"""
from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import VjmError, VjmWarning
from ..kinematics.chain import forward, jacobian
from ..kinematics.poses import Kinematics
from ..kinematics.transforms import rotation_vector
from ..model.base import Model
from ..model.links import LinkSpring
from ..stiffness.linalg import psd_rank_inverse
from ..stiffness.linear import StiffnessResult
from .tree import ChainSprings, Tree, chain_values, path_chain

#: standard gravity, m/s^2, along -z of the base frame unless the model or the call says otherwise
GRAVITY = (0.0, 0.0, -9.80665)
#: configurations per block of :meth:`RobotModel.stiffness` (a block's arrays stay in cache)
BLOCK = 2048
#: tolerance of the self-weight equilibrium: Newton step of the tool pose below this x its size
SAG_TOL = 1e-11
#: plausible ranges, beyond which a value is in other units: gravity within this fraction of standard gravity
#: (or none at all), a joint stiffness of at least this (N mm/rad or N/mm: 1 N mm/rad turns a joint by a radian
#: under 1 N at 1 mm), a mass or payload of at most this (kg: 100 t), joint values beyond their limits by this
#: factor (of the larger limit)
GRAVITY_TOL = 0.05
MIN_STIFFNESS = 1.0
MAX_MASS = 1e5
LIMIT_FACTOR = 2.0


def check_gravity(g, where: str = "gravity") -> np.ndarray:
    """Gravity (3,) m/s^2: finite, and standard gravity within :data:`GRAVITY_TOL` (or zero: no weight)."""
    try:
        a = np.asarray(g, dtype=float)
    except (TypeError, ValueError):
        a = np.full(1, np.nan)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise VjmError(f"{where} must be 3 finite numbers (m/s^2, base frame), got {g!r}")
    top = float(np.max(np.abs(a)))
    size = top * float(np.linalg.norm(a / top)) if top > 0 else 0.0  # no overflow to inf at 1e300
    g0 = float(np.linalg.norm(GRAVITY))
    if size != 0.0 and abs(size / g0 - 1) > GRAVITY_TOL:
        unit = " (mm/s^2? gravity is in m/s^2)" if abs(size / g0 / 1000 - 1) < GRAVITY_TOL else ""
        raise VjmError(f"{where} {[float(x) for x in a]} has magnitude {size:.6g} m/s^2, not within "
                       f"{GRAVITY_TOL:.0%} of {g0:g}{unit}; give [0, 0, 0] for no weight")
    return a


def check_payload(p, where: str = "payload"):
    """A :class:`Payload` (or None) of a mass in [0, :data:`MAX_MASS`] kg at a finite centre of mass."""
    if p is None:
        return p
    if not isinstance(p, Payload):
        raise VjmError(f"{where} must be a vjm.robot.model.Payload(frame, mass kg, com mm) or None, got {p!r}")
    m = p.mass
    if isinstance(m, bool) or not isinstance(m, (int, float, np.floating)) or not (0 <= m <= MAX_MASS):
        raise VjmError(f"{where}.mass must be a number in [0, {MAX_MASS:g}] kg, got {m!r}")
    c = np.asarray(p.com, dtype=float)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise VjmError(f"{where}.com must be 3 finite numbers (mm), got {p.com!r}")
    return p


def unit_slip(tree, q) -> tuple[int, str, bool] | None:
    """Joint values (n, nq) that look like other units: (joint, what is wrong, sure) for the first such
    joint, or None.  A rotational joint's value beyond 2 pi (one turn: degrees?), sure unless the joint is
    continuous (it may turn more); any joint's beyond its limits by :data:`LIMIT_FACTOR`."""
    a = np.atleast_2d(np.asarray(q, dtype=float))
    lo, hi = tree.limits
    types = [j.type for j in tree.joints if j.mimic is None]
    for j, name in enumerate(tree.q_names):
        rot = types[j] != "prismatic"
        top = float(np.max(np.abs(a[:, j]))) if len(a) else 0.0
        bound = max(abs(lo[j]), abs(hi[j]))
        if rot and top > 2 * np.pi + 1e-9:
            sure = bool(np.isfinite(bound))
            return j, f"{name} = {top:.4g} is beyond 2 pi rad (one turn): degrees where radians are meant?", sure
        if np.isfinite(bound) and bound > 0 and top > LIMIT_FACTOR * bound:
            return j, (f"{name} = {top:.4g} is beyond its limits [{lo[j]:g}, {hi[j]:g}] by a factor "
                       f"{top / bound:.3g}: {'degrees where radians' if rot else 'metres or microns where millimetres'} are "
                       f"meant?"), True
    return None


@dataclass(frozen=True, eq=False)
class JointSpring:
    """A joint's 1-dof spring: ``stiffness`` (N mm/rad, or N/mm for a prismatic joint), or a
    ``table`` (q, stiffness) interpolated linearly (held constant beyond its ends), or an
    ``expression`` of ``q`` (the joint's value, rad or mm) read by vjm's safe expression reader (one
    configuration at a time: over a large batch, a table is much faster)."""

    stiffness: float | None = None
    table: tuple | None = None
    expression: str | None = None

    def compliance(self, q: np.ndarray, where: str) -> np.ndarray:
        """Compliances (n,) at joint values q (n,); VjmError naming ``where`` if a stiffness is not > 0."""
        if self.stiffness is not None:
            k = np.full(q.shape, float(self.stiffness))
        elif self.table is not None:
            k = np.interp(q, self.table[0], self.table[1])
        else:
            from ..modelio.description import evaluate

            k = np.array([evaluate(str(self.expression), {"q": float(v)}, where) for v in q])
        bad = ~(k >= MIN_STIFFNESS)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise VjmError(f"{where}: stiffness {k[i]:g} at q = {q[i]:g}; it must be at least {MIN_STIFFNESS:g} "
                           f"(N mm/rad, N/mm for a prismatic joint)")
        return 1.0 / k


@dataclass(frozen=True, eq=False)
class PlacedSpring:
    """A link spring at frame ``at`` of the tree, moved by ``offset`` (4x4, mm) in that frame."""

    spring: LinkSpring
    at: str
    offset: np.ndarray = field(default_factory=lambda: np.eye(4))


@dataclass(frozen=True, eq=False)
class Payload:
    """A point mass (kg) at ``com`` (mm) in the frame ``frame``."""

    frame: str
    mass: float
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))


#: the fields a robot's model file holds verbatim (:meth:`RobotModel.replace` keeps its mapping in step)
VERBATIM = ("name", "gravity", "strict_limits", "home")


def _raw_after(raw: dict, changes: dict) -> dict | None:
    """A robot file's mapping after ``changes`` of a model's fields; None if one is not held verbatim."""
    out = dict(raw)
    for k, v in changes.items():
        if k == "path":
            continue
        if k not in VERBATIM:
            return None
        if v is None:
            out.pop(k, None)
        else:
            out[k] = [float(x) for x in v] if k in ("gravity", "home") else v
    return out


@dataclass(frozen=True, eq=False)
class RobotModel(Model):
    """Immutable VJM model of a serial or tree robot: the ``"serial"`` kind of :class:`vjm.Model` (see the
    module docstring).

    Attributes
    ----------
    tree : the kinematic tree (mm, kg)
    joint_springs : joint name -> :class:`JointSpring` (joints without one are rigid)
    joint6 : joint name -> 6x6 :class:`~vjm.model.links.LinkSpring` after the joint (its bearing)
    links : spring name -> :class:`PlacedSpring`
    payload : a :class:`Payload` or None
    gravity : (3,) m/s^2 in the base frame
    name, path : free text; the model file read (or None)
    raw : the model file's mapping (written back by :meth:`save`)
    strict_limits : a q outside a joint's limits is an error, not a warning
    home : the working configuration (nq,) the file names, or None (``vjm path``'s default seed)
    payload_limit : the largest payload (kg, the rated load) the file states, or None: a calibrated mass's bound
    """

    tree: Tree
    joint_springs: dict = field(default_factory=dict)
    joint6: dict = field(default_factory=dict)
    links: dict = field(default_factory=dict)
    payload: Payload | None = None
    gravity: tuple = GRAVITY
    name: str = ""
    path: str | None = None
    raw: dict | None = None
    strict_limits: bool = False
    home: tuple | None = None
    payload_limit: float | None = None

    def __post_init__(self):
        names = {j.name for j in self.tree.joints}
        for key, d in (("joints", self.joint_springs), ("joints", self.joint6)):
            for j in d:
                if j not in names:
                    raise VjmError(f"{key}.{j}: the robot has no joint {j!r}; its joints: "
                                   f"{', '.join(x.name for x in self.tree.joints)}")
        for k, s in self.links.items():
            if k in names:
                raise VjmError(f"links.{k}: a link spring may not share its name with a joint")
            f = self.tree.frame(s.at)
            if f.joint < 0:
                raise VjmError(f"links.{k}: frame {s.at!r} is fixed to the base; a link spring sits on a moving link")
        if check_payload(self.payload) is not None:
            self.tree.frame(self.payload.frame)
        check_gravity(self.gravity)
        if self.home is not None:
            if len(self.home) != self.nq or not np.all(np.isfinite(np.asarray(self.home, dtype=float))):
                raise VjmError(f"home must be {self.nq} joint values ({', '.join(self.q_names)}; finite numbers), "
                               f"got {self.home!r}")
            self.check_seed(self.home, "home")

    kind = "serial"
    architecture = "robot"
    dof = 6

    @property
    def q_names(self) -> tuple[str, ...]:
        return self.tree.q_names

    @property
    def nq(self) -> int:
        return self.tree.nq

    @property
    def tools(self) -> tuple[str, ...]:
        return self.tree.tools

    @cached_property
    def _springs(self) -> ChainSprings:
        placed = []
        for k, s in self.links.items():
            f = self.tree.frame(s.at)
            placed.append((k, f.joint, f.placement @ s.offset))
        return ChainSprings(frozenset(self.joint_springs), frozenset(self.joint6), tuple(placed))

    @cached_property
    def _chains(self) -> dict:
        return {}

    def chain(self, frame: str):
        """The chain (and its marks) from the base to a named frame (:func:`vjm.robot.tree.path_chain`)."""
        hit = self._chains.get(frame)
        if hit is None:
            f = self.tree.frame(frame)
            hit = self._chains[frame] = path_chain(self.tree, f.joint, f.placement, self._springs, frame)
        return hit

    def _tool(self, tool: str | None) -> str:
        if tool is None:
            return self.tools[0]
        if tool not in self.tools and tool not in {f.name for f in self.tree.frames}:
            raise VjmError(f"no tool frame {tool!r}; tools: {', '.join(self.tools)}")
        return tool

    def check_q(self, q) -> tuple[np.ndarray, bool]:
        """Configurations (n, nq) and whether one was given (not a batch); VjmError if the length is
        wrong; a configuration outside a joint's limits warns (VjmError with ``strict_limits``)."""
        a = np.asarray(q, dtype=float)
        single = a.ndim == 1
        a = np.atleast_2d(a)
        if a.ndim != 2 or a.shape[1] != self.nq:
            raise VjmError(f"{self._where}q must have {self.nq} values ({', '.join(self.q_names)}), got shape "
                           f"{np.shape(q)}")
        if not np.all(np.isfinite(a)):
            raise VjmError("q must be finite numbers (rad, mm for prismatic joints)")
        lo, hi = self.tree.limits
        out = (a < lo - 1e-12) | (a > hi + 1e-12)
        if np.any(out):
            i, j = np.argwhere(out)[0]
            msg = (f"{self._where}q[{j}] = {a[i, j]:g} of joint {self.q_names[j]!r} is outside its limits "
                   f"[{lo[j]:g}, {hi[j]:g}] ({int(out.any(axis=1).sum())} of {len(a)} configurations)")
            if self.strict_limits:
                raise VjmError(msg)
            warnings.warn(msg, VjmWarning, stacklevel=3)
        return a, single

    def check_seed(self, q, what: str = "seed") -> np.ndarray:
        """:meth:`check_q` of a configuration the user gives (a seed, ``home``), and VjmError if its values look
        like degrees or metres (:func:`unit_slip`; a continuous joint beyond a turn warns)."""
        a = np.atleast_2d(np.asarray(q, dtype=float))
        if a.ndim == 2 and a.shape[1] == self.nq and np.all(np.isfinite(a)):
            slip = unit_slip(self.tree, a)
            if slip is not None:
                msg = f"{self._where}{what}: {slip[1]}"
                if slip[2]:
                    raise VjmError(msg)
                warnings.warn(msg + "; a continuous joint may turn more: then ignore this", VjmWarning, stacklevel=3)
        return self.check_q(q)[0]

    @property
    def _where(self) -> str:
        return f"{self.path}: " if self.path else ""

    def compliances(self, kin: Kinematics) -> list[dict]:
        """Per chain of ``kin``, {spring name: compliance (k, k) or (n, k, k)} (rigid springs omitted)."""
        out = []
        for ch in kin.chains:
            d = {}
            for s in ch.springs:
                if s.name in self.joint_springs:
                    j = self.q_names.index(s.name) if s.name in self.q_names else None
                    qj = kin.q[:, j] if j is not None else self._mimic_value(s.name, kin.q)
                    d[s.name] = self.joint_springs[s.name].compliance(qj, f"joints.{s.name}.stiffness")[:, None, None]
                elif s.name.endswith(".spring6") and s.name[:-8] in self.joint6:
                    d[s.name] = self.joint6[s.name[:-8]].compliance
                elif s.name in self.links and self.links[s.name].spring.compliance is not None:
                    d[s.name] = self.links[s.name].spring.compliance
            out.append(d)
        return out

    def _mimic_value(self, name: str, q: np.ndarray) -> np.ndarray:
        j = self.tree.joints[self.tree.joint_index(name)]
        master, mult, off = j.mimic
        return mult * q[:, self.q_names.index(master)] + off

    def kinematics(self, q, tool: str | None = None) -> Kinematics:
        """The chain to ``tool`` at configurations q (n, nq), as the stiffness and equilibrium solvers take it."""
        if isinstance(q, Kinematics):
            return q
        a, _ = self.check_q(q)
        ch, _ = self.chain(self._tool(tool))
        v = chain_values(ch, self.tree, a)
        return Kinematics(("robot", id(self), ch.name), (ch,), forward(ch, v), a, (v,))

    # -- kinematics and gravity (checked against pinocchio in the tests) ---
    def forward(self, q, frame: str | None = None) -> np.ndarray:
        """Frames (n, 4, 4) (or (4, 4)) of a named frame (default: the first tool), mm, at configurations q."""
        kin = self.kinematics(q, frame)
        return kin.frames[0] if np.ndim(q) == 1 else kin.frames

    def jacobian(self, q, frame: str | None = None) -> np.ndarray:
        """Frame Jacobian (n, 6, nq) (or (6, nq)): twist (dx, dy, dz, rx, ry, rz), world axes at the frame's
        origin, per unit of each joint (mm/rad, rad/rad; mm/mm, rad/mm for prismatic joints)."""
        a, single = self.check_q(q)
        ch, _ = self.chain(self._tool(frame))
        J = jacobian(ch, chain_values(ch, self.tree, a))[1]
        out = np.zeros((len(a), 6, self.nq))
        for k, (vn, role) in enumerate(zip(ch.var_names, ch.roles)):
            if role == "actuated":
                out[:, :, self.q_names.index(vn)] += J[:, :, k]
        return out[0] if single else out

    def gravity_torques(self, q, gravity=None) -> np.ndarray:
        """Generalized gravity (n, nq) (or (nq,)): the joint torques (N mm) and forces (N) that hold the
        robot still at q, ``g(q) = -sum_b J_b^T m_b g`` over the bodies' centres of mass (pinocchio's
        ``computeGeneralizedGravity``, in N mm)."""
        a, single = self.check_q(q)
        gv = np.asarray(self.gravity if gravity is None else gravity, dtype=float)
        out = np.zeros((len(a), self.nq))
        for b in self.tree.bodies:
            if b.joint < 0 or b.mass == 0:
                continue
            T = np.eye(4)
            T[:3, 3] = b.com
            ch, _ = path_chain(self.tree, b.joint, T, ChainSprings(), f"com:{b.name}")
            J = jacobian(ch, chain_values(ch, self.tree, a))[1]
            for k, (vn, role) in enumerate(zip(ch.var_names, ch.roles)):
                if role == "actuated":
                    out[:, self.q_names.index(vn)] -= b.mass * np.einsum("ni,i->n", J[:, :3, k], gv)
        return out[0] if single else out

    # -- stiffness --------------------------------------------------------
    def stiffness(self, q, tool: str | None = None) -> StiffnessResult:
        """Stiffness at the tool (world axes, at the tool point) for configurations q: (nq,) gives a
        result without leading axis, (n, nq) a batch (every array with a leading axis n).

        Computed in blocks of ``BLOCK`` configurations with the configuration axis last (the
        chain's closed-form Jacobian, ``C = sum_s J_s C_s J_s^T`` and its inverse stay in cache)."""
        a, single = self.check_q(q)
        name = self._tool(tool)
        if self.tree.frame(name).joint < 0:
            raise VjmError(f"{self._where}{name!r} is fixed to the robot's base: no joint moves it, so it has no "
                           f"stiffness (K = 0); tools: {', '.join(self.tools)}")
        ch, _ = self.chain(name)
        n = len(a)
        out = (np.empty((n, 3)), np.empty((n, 6, 6)), np.empty((n, 6, 6)), np.empty(n), np.empty(n),
               np.empty(n, dtype=int), np.empty(n, dtype=bool), np.empty((n, 3)))
        for a0 in range(0, n, BLOCK):
            self._stiffness_block(ch, a[a0:a0 + BLOCK], out, a0)
        pts, K, C, kt, kr, rank, inv, rot = out
        res = StiffnessResult(pts, K, C, kt, kr, rank, inv, np.zeros((n, 1), dtype=int), rot)
        return res.pose(0) if single else res

    def _stiffness_block(self, ch, qb: np.ndarray, out, a0: int) -> None:
        """Configurations ``a0 : a0 + len(qb)`` of :meth:`stiffness`, written into ``out``: C and K from the
        compiled kernel (:mod:`vjm.robot.kernel`); a configuration whose C it cannot invert (a direction no
        spring deflects) is redone by the rank-revealing :func:`vjm.stiffness.linalg.psd_rank_inverse`."""
        from .kernel import stiffness_kernel

        b0 = a0 + len(qb)
        n = len(qb)
        vt, s1, c1, s6, c6 = self.spring_arrays(ch, qb)
        pts, K, C, kt, kr, rk, iv, rot = out
        ok = np.empty(n, dtype=bool)
        R = np.empty((n, 3, 3))
        stiffness_kernel(*self._encoded(ch), vt, s1, c1, s6, c6, 1e-10,  # type: ignore[call-arg]
                         C[a0:b0], K[a0:b0], ok, pts[a0:b0], R, kt[a0:b0], kr[a0:b0])
        rk[a0:b0], iv[a0:b0] = 6, True
        bad = np.flatnonzero(~ok)
        if bad.size:
            Kb, rb, ib = psd_rank_inverse(C[a0 + bad])
            K[a0 + bad], rk[a0 + bad], iv[a0 + bad] = Kb, rb, ib
        rot[a0:b0] = rotation_vector(R)

    def spring_arrays(self, ch, qb: np.ndarray) -> tuple:
        """The chain's values vt (n_vars, n) at configurations qb (n, nq) and its springs as the compiled
        kernels take them: 1-dof variables s1 (m1,), compliances c1 (m1, n); 6-dof s6 (m6, 6), c6 (m6, 6, 6)."""
        n = len(qb)
        vt = np.ascontiguousarray(chain_values(ch, self.tree, qb).T)
        kin = Kinematics(("robot", ch.name), (ch,), np.empty((n, 4, 4)), qb, (vt.T,))
        comp = self.compliances(kin)[0]
        one = [(s.vars[0], np.broadcast_to(np.reshape(comp[s.name], (-1,)), (n,)))
               for s in ch.springs if s.name in comp and len(s.vars) == 1]
        six = [(s.vars, comp[s.name]) for s in ch.springs if s.name in comp and len(s.vars) == 6]
        s1 = np.array([v for v, _ in one], dtype=np.int64)
        c1 = np.array([c for _, c in one], dtype=float).reshape(len(one), n)
        s6 = np.array([v for v, _ in six], dtype=np.int64).reshape(len(six), 6)
        c6 = np.array([c for _, c in six], dtype=float).reshape(len(six), 6, 6)
        return vt, s1, c1, s6, c6

    def _encoded(self, ch):
        """The chain's arrays for the kernel (:func:`vjm.robot.kernel.encode`), built once."""
        key = ("encoded", ch.name)
        hit = self._chains.get(key)
        if hit is None:
            from .kernel import encode

            hit = self._chains[key] = encode(ch)
        return hit

    def stiffness_map(self, Q, tool: str | None = None) -> StiffnessResult:
        """:meth:`stiffness` at every configuration of Q (n, nq) (one (nq,) is a batch of one): every array of
        the result has a leading axis n, as a parallel machine's ``stiffness_map`` over poses."""
        return self.stiffness(np.atleast_2d(np.asarray(Q, dtype=float)), tool)

    def stiffness_tools(self, q) -> dict:
        """{tool frame: :meth:`stiffness`} for every tool frame of the tree."""
        return {t: self.stiffness(q, t) for t in self.tools}

    def deflection(self, q, wrench, tool: str | None = None) -> np.ndarray:
        """Linear deflection twist ``C w`` (n, 6) (or (6,)) of the tool under wrench(es) at the tool point
        (Fx..Mz, N and N mm, world axes)."""
        r = self.stiffness(np.atleast_2d(np.asarray(q, dtype=float)), tool)
        try:
            W = np.broadcast_to(np.asarray(wrench, dtype=float), (r.C.shape[0], 6))
        except (TypeError, ValueError):
            raise VjmError(f"deflection: the wrench must be 6 numbers (N, N mm) or one row per configuration, got "
                           f"shape {np.shape(wrench)}") from None
        if not np.all(np.isfinite(W)):
            raise VjmError(f"deflection: the wrench must be finite numbers (N, N mm), got {np.asarray(wrench)!r}")
        t = np.einsum("nij,nj->ni", r.C, W)
        return t[0] if np.ndim(q) == 1 else t

    def self_weight(self, q, tool: str | None = None, gravity=None, payload: Payload | None = None,
                    wrench=None, tol: float = SAG_TOL, max_iter: int = 60, return_info: bool = False,
                    strict: bool = True):
        """The tool's deflection (n, 6) (or (6,)) under the robot's own weight (and a payload and a tool
        wrench), from the equilibrium on the deflected geometry (see :mod:`vjm.robot.weight`): a
        :class:`~vjm.robot.sag.Sag`, which reads as that array and names the tool, the joints and the units."""
        from .sag import Sag
        from .weight import self_weight

        _loads(gravity, payload)
        out = self_weight(self, q, tool, gravity, payload, wrench, tol, max_iter, return_info, strict)
        t, info = out if return_info else (out, None)
        sag = Sag(np.asarray(t), self._tool(tool), np.asarray(q, dtype=float), tuple(self.q_names))
        return (sag, info) if return_info else sag

    def joint_map(self, q0, joints, ranges, n=41, tool: str | None = None, self_weight: bool = False):
        """k_tran, k_rot, K (and the sag) over two joints, the others at ``q0``; ``n`` values per joint (or one
        count per joint) (:func:`vjm.maps.robot_joint.joint_map`)."""
        from ..maps.robot_joint import joint_map

        return joint_map(self, q0, joints, ranges, n, tool, self_weight)

    def inverse(self, poses, seed, tool: str | None = None, tol: float = 1e-8):
        """Joint values reaching tool poses (n, 4, 4) in the configuration of ``seed`` (:mod:`vjm.robot.ik`):
        an :class:`~vjm.robot.ik.IKResult` with ``q``, ``reached``, ``singular``, ``residual``."""
        from .ik import solve

        T = np.asarray(poses, dtype=float)
        if T.shape[-2:] != (4, 4) or T.ndim not in (2, 3):
            raise VjmError(f"inverse: poses must be tool frames (4, 4) or (n, 4, 4) (mm), got shape {T.shape}; for "
                           f"points (n, 3) use compensate or cartesian_map (orientation free or given)")
        return solve(self, T.reshape(-1, 4, 4), self.check_seed(seed)[0], tool, tol)

    def compensate(self, targets, seed, tool: str | None = None, gravity=None, payload: Payload | None = None,
                   tol: float = 1e-6, orientation=None):
        """The joint values to command so that the tool, deflected under self-weight (and a payload), reaches
        target poses (n, 4, 4) or points (n, 3) mm (orientation free, or ``orientation``) within ``tol`` mm, in
        the configuration of ``seed``: a :class:`~vjm.compensation.Compensation` (:mod:`vjm.robot.compensate`)."""
        from .compensate import compensate

        _loads(gravity, payload)
        self.check_seed(seed)
        return compensate(self, targets, seed, tool, gravity, payload, tol, orientation)

    def cartesian_map(self, points, seed, orientation=None, tool: str | None = None, self_weight: bool = False):
        """k_tran, k_rot (and the sag) at tool points (n, 3) mm with one orientation (rotation vector), through
        the IK in the configuration of ``seed``, carried from point to point (:func:`vjm.robot.ik.solve_path`).

        Returns ``(IKResult, StiffnessResult or None, sag or None)``: the stiffness and sag of the reached
        points only (``ik.reached`` says which); unreachable and singular points are flagged in ``ik``."""
        from .ik import pose_targets, solve_path

        ik = solve_path(self, pose_targets(points, orientation), self.check_seed(seed)[0], tool)
        ok = ik.reached
        if not np.any(ok):
            return ik, None, None
        r = self.stiffness(ik.q[ok], tool)
        return ik, r, (self.self_weight(ik.q[ok], tool) if self_weight else None)

    def __repr__(self) -> str:
        """A few lines: name, file, joints, tools, springs, payload, gravity."""
        from ..maps.views import robot_text

        return robot_text(self)

    def _repr_html_(self) -> str:
        """The same facts as :meth:`__repr__`, as a table."""
        from ..maps.views import robot_rows, rows_table

        return "<p><b>vjm RobotModel</b></p>" + rows_table(robot_rows(self))

    def replace(self, **changes) -> "RobotModel":
        """A copy with some fields changed (``joint_springs=``, ``links=``, ``payload=``, ``gravity=``,
        ``strict_limits=``, ``home=`` ...), validated again.

        The model file's mapping (what :meth:`save` writes) follows the fields it holds verbatim (``name``,
        ``gravity``, ``strict_limits``, ``home``); a change of the tree or the springs leaves a model that
        :meth:`save` refuses (its file would not say what it holds)."""
        unknown = sorted(set(changes) - {f.name for f in dataclasses.fields(self)})
        if unknown:
            raise VjmError(f"replace: a robot model has no field {unknown[0]!r}; its fields: "
                           f"{', '.join(f.name for f in dataclasses.fields(self))}")
        given = "raw" in changes
        raw = changes.pop("raw", self.raw)
        if raw is not None and not given:
            raw = _raw_after(raw, changes)
        return dataclasses.replace(self, raw=raw, **changes)

    def save(self, path) -> None:
        """Write this model's file (its mapping as read; a URDF path is kept absolute)."""
        from ..modelio.robotwrite import save_robot

        save_robot(self, path)


def _loads(gravity, payload) -> None:
    """A call's gravity and payload (None: the model's), checked as the model's are."""
    if gravity is not None:
        check_gravity(gravity)
    check_payload(payload)
