"""Elastic and thermal effects of a robot beyond its joints' torsion, for absolute-pose calibration.

Each is a per-row small rigid motion inserted in the chain of :func:`vjm.calibration.serial.chain_frames`,
driven by the nominal model's self-weight (or the temperature) and scaled by one fitted parameter:

- **lateral joint compliance** ``<joint>.lateral`` (rad per N mm): the joint's bearing tilts under the
  moment its subtree's weight puts on it, about the two axes normal to the joint's axis (an isotropic
  bearing), the rotation ``-c M_perp`` applied in the joint's frame after its motion.  ``M`` is the support
  moment (the parent's on the child, about the joint's origin; its component along the axis is the
  joint's gravity torque);
- **link bending** ``<link>.bending`` (1 / (N mm^2), that is 1/EI): a link whose joint-to-joint
  placement is long (its largest component at least half the longest of the path: a UR's upper arm and
  forearm) is an Euler-Bernoulli cantilever of length ``L`` along that component's axis ``e``, clamped at
  its joint, loaded at its tip by the weight of what it carries (force ``F`` and moment ``M`` about the
  tip).  Per unit ``1/EI`` the tip turns by ``L M_perp + L^2/2 e x F`` and moves by
  ``L^2/2 M_perp x e + L^3/3 (e x F) x e`` (torsion about ``e`` is left out); the next joint's placement
  follows the tip;
- **compliance depending on the joint's value** ``<joint>.varying`` (rad per N mm per rad): the joint's
  torsional compliance ``c + c' q`` (first order of any dependence), the deflection ``-c' q g(q)`` added;
- **length scale with temperature** ``thermal.alpha`` (1/K): every joint placement's translation and the
  measured frame's scaled by ``1 + alpha (T - 20 C)`` with the row's temperature ``T`` (a ``meta_temperature``
  column);
- **a prismatic guide's tilt** ``<joint>.guide_tilt_lower`` and ``<joint>.guide_tilt_upper`` (rad per N mm):
  the carriage of a prismatic joint (a linear axis, a gantry, a track, a telescopic column) tilts under the
  moment it carries, the rotation ``-c(q) M_perp`` after the joint's motion as for a lateral compliance (an
  isotropic guide: one compliance about both axes normal to the guide).  The compliance grows as the guide
  extends and its overlaps shrink: ``c(q) = c_lower (1 - s) + c_upper s`` with ``s = (q - lower) / (upper -
  lower)`` the fraction of the joint's travel (its limits), that is ``a + b q`` written by its values at the
  travel's ends -- the first order of any dependence (``a + b / overlap`` needs the overlap at full
  retraction, which no model file states), linear in its parameters, and physical over the whole travel
  exactly when both ends are >= 0.  A mimic joint (one drive moving several segments) shares its master's
  two compliances, each segment tilting under its own moment;
- **a telescopic stage's tilt** ``<joint>.column_tilt_lower`` and ``<joint>.column_tilt_upper``: the same
  compliance, the stage turning about where it leaves its fixed guide (the joint's frame before its motion,
  the exit of the guide) rather than about its carriage: a column's stage held in its guide at the guide's
  top tilts about that top, and the point of rotation stays while the stage slides;
- **a link spring's scale** ``<link>.link_scale`` (1): the model's link spring (a beam, a linkfea result:
  its 6x6 compliance ``C`` in the spring frame) deflects by ``C w`` under the wrench ``w`` it carries (the
  weight of everything beyond it, about the spring's origin, in its frame); the parameter multiplies that
  nominal deflection, which moves what follows the spring rigidly.  With the nominal deflection in the
  baseline (scale 1) the fitted parameter is the correction ``s - 1`` on top of it and the link is
  ``s = nominal + correction`` times as compliant as its CAD predicts (:func:`link_scale_text`).

The loads are the nominal model's (its masses under its gravity) at the commanded configurations: the
effects are small, their products with the calibration's corrections second order.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..kinematics.transforms import elementary

T_REF = 20.0   # C, the reference temperature of dimensional metrology (ISO 1)
TEMPERATURE = "meta_temperature"


@dataclass(frozen=True, eq=False)
class Beam:
    """A link bending as a cantilever: the joint ``joint`` carrying it (tree index), the next joint
    ``child`` on the path, the tip (3,) mm in ``joint``'s frame, and per unit 1/EI the tip's rotation
    ``theta`` (n, 3) rad and displacement ``u`` (n, 3) mm, in ``joint``'s frame."""

    name: str
    joint: int
    child: int
    tip: np.ndarray
    theta: np.ndarray
    u: np.ndarray


@dataclass(frozen=True, eq=False)
class Guide:
    """A prismatic guide: the parameters' prefix ``name`` (the driving joint), the tree joints it moves
    (``joints``: the driving one and its mimics on the path), the rows' fraction of its travel ``s`` (n,) and
    each joint's slide along its axis ``slide`` (n, len(joints), 3) mm in its own frame (where a telescopic
    stage's point of rotation, the guide's exit, sits behind the carriage)."""

    name: str
    joints: tuple
    s: np.ndarray
    slide: np.ndarray


@dataclass(frozen=True, eq=False)
class LinkLoad:
    """A link spring's nominal deflection: its ``name``, the tree joint carrying it, its frame ``S`` (4, 4) in
    that joint's frame (after the joint's motion), and per row the translation ``t`` (n, 3) mm and rotation
    ``r`` (n, 3) rad of ``C w`` in the spring frame."""

    name: str
    joint: int
    S: np.ndarray
    t: np.ndarray
    r: np.ndarray

    @property
    def S_inv(self) -> np.ndarray:
        """The spring frame's inverse (a rigid motion)."""
        Si = np.eye(4)
        Si[:3, :3] = self.S[:3, :3].T
        Si[:3, 3] = -self.S[:3, :3].T @ self.S[:3, 3]
        return Si


@dataclass(frozen=True, eq=False)
class Flex:
    """The loads of the flex effects at the rows' configurations: per tree joint the lateral deflection per
    unit compliance ``lateral`` (n, nj, 3) rad per (rad/(N mm)) in the joint's frame (``-M_perp``), the
    ``beams``, the rows' temperature offsets ``dT`` (n,) K from :data:`T_REF` (None without a
    temperature column), the prismatic ``guides`` and the link springs' nominal deflections ``links``."""

    lateral: np.ndarray
    beams: tuple
    dT: np.ndarray | None = None
    guides: tuple = ()
    links: tuple = ()

    def rows(self, mask: np.ndarray) -> Flex:
        """The loads of the rows ``mask`` selects."""
        return Flex(self.lateral[mask], tuple(replace(b, theta=b.theta[mask], u=b.u[mask]) for b in self.beams),
                    None if self.dT is None else self.dT[mask], tuple(replace(g, s=g.s[mask], slide=g.slide[mask]) for g in self.guides),
                    tuple(replace(k, t=k.t[mask], r=k.r[mask]) for k in self.links))


def rotations(w: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of rotation vectors (n, 3) (Rodrigues)."""
    a = np.linalg.norm(w, axis=1)
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = w[:, 2], -w[:, 1], w[:, 0]
    small = a < 1e-8
    s = np.where(small, 1.0 - a**2 / 6, np.sin(a) / np.where(small, 1.0, a))
    c = np.where(small, 0.5 - a**2 / 24, (1 - np.cos(a)) / np.where(small, 1.0, a) ** 2)
    return np.eye(3) + s[:, None, None] * K + c[:, None, None] * (K @ K)


def joint_value(j, q: np.ndarray, qn: list) -> np.ndarray:
    """A tree joint's value at q (n, nq): its own coordinate, or its mimic's."""
    if j.mimic is None:
        return q[:, qn.index(j.name)]
    master, mult, off = j.mimic
    return mult * q[:, qn.index(master)] + off


def world_frames(model, q: np.ndarray) -> np.ndarray:
    """Every joint's frame after its motion (n, nj, 4, 4), nominal model, base frame."""
    tree = model.tree
    qn = list(tree.q_names)
    W = np.empty((len(q), len(tree.joints), 4, 4))
    for i, j in enumerate(tree.joints):
        P = np.eye(4) if j.parent < 0 else W[:, j.parent]
        C = j.placement if j.align is None else j.placement @ j.align
        T = (P @ C) @ elementary(j.kind, joint_value(j, q, qn))
        W[:, i] = T if j.align is None else T @ np.linalg.inv(j.align)
    return W


def support_wrenches(model, q: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The support force (n, nj, 3) N and moment about the joint's origin (n, nj, 3) N mm, base axes, that
    each joint passes to its subtree under the nominal model's gravity (the negated weight of the subtree;
    a joint's gravity torque is the moment's component along its axis)."""
    tree = model.tree
    g = np.asarray(model.gravity, dtype=float)
    F = np.zeros((len(q), len(tree.joints), 3))
    M = np.zeros_like(F)
    for b in tree.bodies:
        if b.joint < 0 or b.mass == 0:
            continue
        c = np.einsum("nij,j->ni", W[:, b.joint, :3, :3], np.asarray(b.com, dtype=float)) + W[:, b.joint, :3, 3]
        w = b.mass * g
        for j in tree.path(b.joint):
            F[:, j] -= w
            M[:, j] -= np.cross(c - W[:, j, :3, 3], w)
    return F, M


def beam_axes(model, frame: str) -> list:
    """The links of the path to ``frame`` bending as beams: (joint, child joint, axis index, length mm) of
    consecutive joints whose placement's largest component is at least half the path's longest."""
    tree = model.tree
    path = tree.path(tree.frame(frame).joint)
    pairs = [(a, b, tree.joints[b].placement[:3, 3]) for a, b in zip(path[:-1], path[1:])]
    top = max((float(np.max(np.abs(p))) for _, _, p in pairs), default=0.0)
    out = []
    for a, b, p in pairs:
        k = int(np.argmax(np.abs(p)))
        if top > 0 and abs(p[k]) >= 0.5 * top:
            out.append((a, b, k, float(p[k])))
    return out


def beam_name(model, joint: int) -> str:
    j = model.tree.joints[joint]
    return f"{j.child or j.name}.bending"


def _beam(model, a: int, b: int, k: int, L: float, W, F, M) -> Beam:
    R = W[:, a, :3, :3]
    e = np.zeros(3)
    e[k] = np.sign(L)
    tip = e * abs(L)
    tip_w = np.einsum("nij,j->ni", R, tip) + W[:, a, :3, 3]
    # the loads on the beam at its tip: the child's weight, the negated support wrench, about the tip
    Ft = -np.einsum("nji,nj->ni", R, F[:, b])
    Mt = -np.einsum("nji,nj->ni", R, M[:, b] + np.cross(W[:, b, :3, 3] - tip_w, F[:, b]))
    Mp = Mt - np.outer(Mt @ e, e)
    Lb = abs(L)
    exF = np.cross(e, Ft)
    theta = Lb * Mp + Lb**2 / 2 * exF
    u = Lb**2 / 2 * np.cross(Mp, e) + Lb**3 / 3 * np.cross(exF, e)
    return Beam(beam_name(model, a), a, b, tip, theta, u)


def guide_axes(model, frame: str) -> list:
    """The prismatic guides of the path to ``frame``: (driving joint's name, its travel (lower, upper), the
    tree joints it moves on the path), one per driving joint (a mimic segment is its master's), those with a
    finite travel only (the compliance is stated at its ends)."""
    tree = model.tree
    out: dict = {}
    for i in tree.path(tree.frame(frame).joint):
        j = tree.joints[i]
        if j.kind[0] != "t":
            continue
        master = j.name if j.mimic is None else j.mimic[0]
        m = tree.joints[tree.joint_index(master)]
        if m.kind[0] == "t" and np.isfinite(m.lower) and np.isfinite(m.upper) and m.upper > m.lower:
            out.setdefault(master, ((float(m.lower), float(m.upper)), []))[1].append(i)
    return [(k, lim, tuple(js)) for k, (lim, js) in out.items()]


def link_springs(model, frame: str) -> list:
    """The model's link springs on the path to ``frame`` that deflect: (name, tree joint carrying it, its
    frame (4, 4) in that joint's frame, its 6x6 compliance)."""
    tree = model.tree
    path = set(tree.path(tree.frame(frame).joint))
    out = []
    for name, ps in model.links.items():
        C = ps.spring.compliance
        f = tree.frame(ps.at)
        if C is not None and f.joint in path:
            out.append((name, f.joint, f.placement @ ps.offset, np.asarray(C, dtype=float)))
    return out


def _link_load(model, name: str, ji: int, S: np.ndarray, C: np.ndarray, W: np.ndarray) -> LinkLoad:
    """The spring's deflection ``C w`` under the weight ``w`` of what it carries: the bodies beyond its joint
    (its own link's body sits before it, as in :func:`vjm.robot.tree.path_chain`), about its origin."""
    tree = model.tree
    g = np.asarray(model.gravity, dtype=float)
    Sw = W[:, ji] @ S
    F = np.zeros((len(W), 3))
    M = np.zeros_like(F)
    for b in tree.bodies:
        if b.joint < 0 or b.mass == 0 or b.joint == ji or ji not in tree.path(b.joint):
            continue
        c = np.einsum("nij,j->ni", W[:, b.joint, :3, :3], np.asarray(b.com, dtype=float)) + W[:, b.joint, :3, 3]
        F += b.mass * g
        M += np.cross(c - Sw[:, :3, 3], b.mass * g)
    w = np.concatenate([np.einsum("nji,nj->ni", Sw[:, :3, :3], F), np.einsum("nji,nj->ni", Sw[:, :3, :3], M)], axis=1)
    d = w @ C.T
    return LinkLoad(name, ji, S, d[:, :3], d[:, 3:])


def flex_loads(model, q: np.ndarray, frame: str, temperature=None) -> Flex:
    """The :class:`Flex` loads of the path to ``frame`` at q (n, nq); ``temperature`` (n,) C or None."""
    W = world_frames(model, q)
    F, M = support_wrenches(model, q, W)
    Ml = np.einsum("nkji,nkj->nki", W[:, :, :3, :3], M)   # in each joint's frame
    lateral = np.zeros_like(Ml)
    for i, j in enumerate(model.tree.joints):
        a = _axis(j)
        lateral[:, i] = -(Ml[:, i] - np.outer(Ml[:, i] @ a, a))
    beams = tuple(_beam(model, a, b, k, L, W, F, M) for a, b, k, L in beam_axes(model, frame))
    dT = None if temperature is None else np.asarray(temperature, dtype=float) - T_REF
    qn = list(model.tree.q_names)
    joints = model.tree.joints
    guides = tuple(Guide(name, js, (q[:, qn.index(name)] - lo) / (hi - lo),
                         np.stack([np.outer(joint_value(joints[i], q, qn), _axis(joints[i])) for i in js], axis=1))
                   for name, (lo, hi), js in guide_axes(model, frame))
    links = tuple(_link_load(model, name, ji, S, C, W) for name, ji, S, C in link_springs(model, frame))
    return Flex(lateral, beams, dT, guides, links)


#: the guide tilts' parameter prefixes: about the carriage, and about the guide's exit (a telescopic stage)
GUIDE_TILTS = ("guide_tilt", "column_tilt")


def guide_compliance(g: Guide, vals: dict, kind: str = "guide_tilt") -> np.ndarray:
    """The guide's tilt compliance (n,) rad/(N mm) at the rows: its ends' values interpolated along the travel."""
    lo, hi = vals.get(f"{g.name}.{kind}_lower", 0.0), vals.get(f"{g.name}.{kind}_upper", 0.0)
    return lo * (1.0 - g.s) + hi * g.s


def link_motion(k: LinkLoad, v: float) -> np.ndarray:
    """The rigid motion (n, 4, 4) in the carrying joint's frame of the link spring ``k`` deflected ``v`` times its
    nominal deflection: ``S D S^-1``, D the spring frame's small motion (translation, then rotation)."""
    D = np.broadcast_to(np.eye(4), (len(k.t), 4, 4)).copy()
    D[:, :3, :3] = rotations(v * k.r)
    D[:, :3, 3] = v * k.t
    return k.S @ D @ k.S_inv


def link_scale_text(link: str, total: float, std: float) -> str:
    """The report's line of a fitted link scale: how compliant the link is against its CAD (the model's link
    spring), ``total`` the scale (nominal 1 plus the fitted correction) and ``std`` its standard deviation."""
    digits = max(0, -int(np.floor(np.log10(std)))) if std > 0 and np.isfinite(std) else 2   # std's first digit
    words = link.replace("_", " ")
    return f"the {words} is {total:.{digits}f} +- {std:.{digits}f} times as compliant as its CAD predicts"


def _axis(j) -> np.ndarray:
    """The joint's axis in its own frame (after the alignment's inverse)."""
    a = np.zeros(3)
    a["xyz".index(j.kind[1])] = 1.0
    return a if j.align is None else j.align[:3, :3] @ a


def transforms(flex: Flex | None, model, frame: str, vals: dict) -> tuple[dict, dict, np.ndarray | None]:
    """The flex effects of ``vals`` as per-row transforms: ({joint: (n, 4, 4) before its placement},
    {joint: (n, 4, 4) after its motion}, the measured frame's (n, 4, 4) before its placement or None)."""
    pre: dict = {}
    post: dict = {}
    if flex is None:
        return pre, post, None
    tree = model.tree
    for i in tree.path(tree.frame(frame).joint):
        c = vals.get(f"{tree.joints[i].name}.lateral", 0.0)
        if c:
            T = np.broadcast_to(np.eye(4), (len(flex.lateral), 4, 4)).copy()
            T[:, :3, :3] = rotations(c * flex.lateral[:, i])
            post[i] = T
    for g, kind in ((g, k) for g in flex.guides for k in GUIDE_TILTS):
        c = guide_compliance(g, vals, kind)
        if np.any(c):
            for n, i in enumerate(g.joints):
                T = np.broadcast_to(np.eye(4), (len(c), 4, 4)).copy()
                T[:, :3, :3] = rotations(c[:, None] * flex.lateral[:, i])
                if kind == "column_tilt":   # about the exit, the slide d behind the carriage: (R - I) d
                    d = g.slide[:, n]
                    T[:, :3, 3] = np.einsum("nij,nj->ni", T[:, :3, :3], d) - d
                post[i] = post[i] @ T if i in post else T
    for k in flex.links:   # after the joint's motion and its bearing's tilt, as the chain's link springs
        v = vals.get(f"{k.name}.link_scale", 0.0)
        if v:
            post[k.joint] = post[k.joint] @ link_motion(k, v) if k.joint in post else link_motion(k, v)
    for bm in flex.beams:
        c = vals.get(bm.name, 0.0)
        if c:
            T = np.broadcast_to(np.eye(4), (len(bm.theta), 4, 4)).copy()
            R = rotations(c * bm.theta)
            T[:, :3, :3] = R
            T[:, :3, 3] = c * bm.u + bm.tip - R @ bm.tip
            pre[bm.child] = T
    alpha = vals.get("thermal.alpha", 0.0)
    tool = None
    if alpha and flex.dT is not None:
        s = alpha * flex.dT
        for i in tree.path(tree.frame(frame).joint):
            T = np.broadcast_to(np.eye(4), (len(s), 4, 4)).copy()
            T[:, :3, 3] = np.outer(s, tree.joints[i].placement[:3, 3])
            pre[i] = pre[i] @ T if i in pre else T
        tool = np.broadcast_to(np.eye(4), (len(s), 4, 4)).copy()
        tool[:, :3, 3] = np.outer(s, tree.frame(frame).placement[:3, 3])
    return pre, post, tool
