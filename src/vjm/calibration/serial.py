"""Absolute positions of a point on a robot, as an instrument sees them, with the calibration's parameters.

The measured point ``p`` of frame ``F`` at configuration ``q``, in the instrument frame of group ``g``::

    m = R_g (T_F(q; geometry, compliance) p + o_F) + t_g

- ``T_F``: the chain from the base to ``F`` with, per joint, an **origin error** (a small twist
  ``dx dy dz`` mm, ``ex ey ez`` rad, applied after the URDF origin: ``origin @ exp(error)``), a **joint
  offset** added to its value, and a **compliance correction** ``c`` (rad per N mm) to the model file's
  compliance ``c0`` (:mod:`vjm.calibration.nominal`), turning the gravity torque ``g_j(q)`` of the nominal model
  (its masses and payload, N mm) into a joint deflection ``-(c0 + c) g_j(q)`` (the link sags the way its weight
  pulls); with a fitted payload correction (kg) at the marker, its gravity torques add to the model's;
- the sag of the model's other springs (link springs, 6x6 joint springs) under its weight, a twist per row added
  to the point to first order (:class:`vjm.calibration.nominal.Nominal`);
- ``p``: the marker's offset on ``F`` (mm), ``R_g, t_g``: the instrument frame of the registration group
  (the nuisance parameters, fitted jointly and reported apart).

Parameters are named ``reg[<group>].tx..rz``, ``<frame>.px..pz``, ``<joint>.offset``, ``<joint>.dx..ez`` and
``<joint>.compliance`` and ``payload.mass``.  Jacobians are central differences with steps fitted to each kind (mm, rad,
compliance scaled to a joint deflection), so that they are accurate to about 1e-9 relative.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..effects import absolute
from ..effects.absolute import GEOMETRY
from ..kinematics.transforms import elementary
from ..robot.tree import _rigid_inverse
from .flex import beam_axes, beam_name, guide_axes, link_motion, link_springs, transforms

_REG = ("tx", "ty", "tz", "rx", "ry", "rz")
_STEP = {"mm": 1e-4, "rad": 1e-7, "kg": 1e-3}


def rotation_matrix(w) -> np.ndarray:
    """Rotation matrix of a rotation vector (3,) (Rodrigues)."""
    w = np.asarray(w, dtype=float)
    a = float(np.linalg.norm(w))
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if a < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(a) / a * K + (1 - np.cos(a)) / a**2 * (K @ K)


def _delta(d) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation_matrix(d[3:])
    T[:3, 3] = d[:3]
    return T


def kabsch(P: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rigid motion (R, t) minimising sum |R P_i + t - Q_i|^2 (points (n, 3))."""
    cp, cq = P.mean(axis=0), Q.mean(axis=0)
    H = (P - cp).T @ (Q - cq)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, cq - R @ cp


@dataclass(frozen=True)
class Layout:
    """The parameter vector: names, kinds (``reg``, ``marker``, ``geometry``, ``compliance``, ``backlash``), units
    (``mm``, ``rad``, ``c``) and, per name, what it acts on."""

    names: tuple
    kinds: tuple
    units: tuple

    @property
    def size(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        return self.names.index(name)

    def pick(self, keep) -> Layout:
        k = list(keep)
        return Layout(tuple(self.names[i] for i in k), tuple(self.kinds[i] for i in k),
                      tuple(self.units[i] for i in k))


def registration_parameters(groups) -> tuple[list, list, list]:
    """Names, kinds and units of every group's instrument frame (``reg[g].tx .. rz``): the first
    parameters of a layout, the robot's and the parallel machine's."""
    names, kinds, units = [], [], []
    for g in groups:
        for k in _REG:
            names.append(f"reg[{g}].{k}")
            kinds.append("reg")
            units.append("mm" if k[0] == "t" else "rad")
    return names, kinds, units


def site(model, frame: str) -> absolute.Site:
    """What a robot's effects repeat over on the path to ``frame`` (:class:`vjm.effects.absolute.Site`): every
    joint, the free ones (not mimics), the free revolute ones (``bearing``), their ordered pairs, the links
    bending as beams, the prismatic guides (``guide``, one per driving joint), the model's link springs
    (``spring``), once."""
    path = [model.tree.joints[i] for i in model.tree.path(model.tree.frame(frame).joint)]
    free = [j.name for j in path if j.mimic is None]
    return absolute.Site("serial", {
        "joint": tuple({"joint": j.name} for j in path),
        "free": tuple({"joint": n} for n in free),
        "bearing": tuple({"joint": j.name} for j in path if j.mimic is None and j.kind[0] == "r"),
        "pair": tuple({"joint": a, "other": b} for a in free for b in free if a != b),
        "beam": tuple({"link": beam_name(model, a)[:-len(".bending")]} for a, *_ in beam_axes(model, frame)),
        "guide": tuple({"joint": name} for name, *_ in guide_axes(model, frame)),
        "spring": tuple({"link": name} for name, *_ in link_springs(model, frame)),
        "once": ({},)})


def full_layout(model, frame: str, groups, effects=()) -> Layout:
    """Every parameter of the measurement model of a point on ``frame``: the registration of each group
    first, the marker offset, then the parameters of each effect (:mod:`vjm.effects.absolute`) in the
    order of their rank -- those listed always (offsets and origin errors per joint of the path, the
    compliances, the backlashes) and those of the ``effects`` tried (with coupling each joint's value
    coupled to each other's, ``a.coupling[b]``: a turns by that times b's value, ...)."""
    tried = [e for e in absolute.of_kind("serial") if not e.on_demand or e.name in effects]
    return layout_of(groups, [f"{frame}.{k}" for k in ("px", "py", "pz")], site(model, frame), tried)


def layout_of(groups, markers, at: absolute.Site, effects) -> Layout:
    """The parameters of a measurement model, in their order: each group's registration, the ``markers``'
    offsets (mm), then each of ``effects``' parameters over the site ``at`` (a robot's or a machine's)."""
    names, kinds, units = registration_parameters(groups)
    names += list(markers)
    kinds += ["marker"] * len(markers)
    units += ["mm"] * len(markers)
    for e in effects:
        for n, _, step in e.parameters(at):
            names.append(n)
            kinds.append(e.name)
            units.append(step)
    return Layout(tuple(names), tuple(kinds), tuple(units))


@dataclass(frozen=True, eq=False)
class Problem:
    """What the prediction needs besides the parameters: the model, the measured frame, the rows'
    configurations (n, nq), their group index (n,), the groups' base registration (R0, t0) and the
    marker's base offset p0, and the nominal gravity torques (n, nq) N mm (the model's masses and payload)."""

    model: Any
    frame: str
    q: np.ndarray
    gidx: np.ndarray
    groups: tuple
    R0: tuple
    t0: tuple
    p0: np.ndarray
    torques: np.ndarray
    #: the gravity torques (n, nq) N mm of 1 kg at the marker (the ``payload.mass`` parameter's), or None
    unit_torques: np.ndarray | None = None
    #: the robot's gravity torques (3, n, nq) N mm for a unit gravity along each base axis (the base tilt's), or None
    gravity_basis: np.ndarray | None = None
    #: the loads of the lateral compliances, link bending and temperature (:class:`vjm.calibration.flex.Flex`), or None
    flex: Any = None
    #: what the model file states per row, the fit's corrections added to it: its joint compliances and the sag of
    #: its other springs (:class:`vjm.calibration.nominal.Nominal`); None: a rigid model (older callers)
    nominal: Any = None


@dataclass(frozen=True, eq=False)
class Points:
    """Several measured frames on the same rows (a marker on each hand): one :class:`Problem` per frame,
    their predictions stacked frame after frame ((k n, 3)); what the rows share (the model, q, groups,
    torques, loads) is read from the first."""

    parts: tuple

    def __getattr__(self, name: str):
        if name == "parts":
            raise AttributeError(name)
        return getattr(self.parts[0], name)


def merged_layout(model, frames, groups, effects=()) -> Layout:
    """The parameters of several measured frames: each frame's :func:`full_layout`, a parameter shared by
    their paths (the registration, a common joint's) once, ordered by kind."""
    seen: dict = {}
    for f in frames:
        lay = full_layout(model, f, groups, effects)
        for n, k, u in zip(lay.names, lay.kinds, lay.units):
            seen.setdefault(n, (k, u))
    names = sorted(seen, key=lambda n: absolute.rank(seen[n][0]))   # stable: each kind keeps its order
    return Layout(tuple(names), tuple(seen[n][0] for n in names), tuple(seen[n][1] for n in names))


def chain_frames(model, q: np.ndarray, frame: str, values: dict, dq: np.ndarray | None = None,
                 flex=None) -> np.ndarray:
    """Frames (n, 4, 4) of ``frame`` with origin errors and offsets ``values`` ({"<joint>.<kind>": value},
    missing ones 0), extra joint values ``dq`` (n, nq) (the compliance's deflections) and the flex effects
    of ``values`` on the loads ``flex`` (:func:`vjm.calibration.flex.transforms`)."""
    pre, post, tool = transforms(flex, model, frame, values)
    tree = model.tree
    qn = list(tree.q_names)
    n = len(q)
    T = np.broadcast_to(np.eye(4), (n, 4, 4))
    for ji in tree.path(tree.frame(frame).joint):
        j = tree.joints[ji]
        d = np.array([values.get(f"{j.name}.{k}", 0.0) for k in GEOMETRY])
        C = j.placement @ _delta(d[1:]) if np.any(d[1:]) else j.placement
        if j.align is not None:
            C = C @ j.align
        if j.mimic is None:
            v = q[:, qn.index(j.name)] + (0.0 if dq is None else dq[:, qn.index(j.name)])
        else:
            master, mult, off = j.mimic
            k = qn.index(master)
            v = mult * (q[:, k] + (0.0 if dq is None else dq[:, k])) + off
        T = ((T @ pre[ji]) @ C if ji in pre else T @ C) @ elementary(j.kind, v + d[0])
        if j.align is not None:
            T = T @ _rigid_inverse(j.align)
        if ji in post:
            T = T @ post[ji]
    return (T if tool is None else T @ tool) @ tree.frame(frame).placement


def predict(prob: Problem, layout: Layout, x: np.ndarray, fixed: dict | None = None) -> np.ndarray:
    """The measured points (n, 3) mm in the instrument frames, for parameters ``x`` of ``layout`` (and
    the values ``fixed`` of parameters not in it); of :class:`Points`, (k n, 3) frame after frame."""
    if isinstance(prob, Points):
        return np.concatenate([predict(p, layout, x, fixed) for p in prob.parts])
    vals = dict(fixed or {})
    vals.update(zip(layout.names, x))
    T = chain_frames(prob.model, prob.q, prob.frame, vals, deflections(prob, vals), prob.flex)
    p = prob.p0 + np.array([vals.get(f"{prob.frame}.p{k}", 0.0) for k in "xyz"])
    pb = np.einsum("nij,j->ni", T[:, :3, :3], p) + T[:, :3, 3]
    w = _sag(prob, vals)
    if w is not None:
        pb = pb + w[:, :3] + np.cross(w[:, 3:], prob.nominal.R @ p)
    out = np.empty_like(pb)
    for gi, g in enumerate(prob.groups):
        rows = prob.gidx == gi
        t = np.array([vals.get(f"reg[{g}].t{k}", 0.0) for k in "xyz"])
        w = np.array([vals.get(f"reg[{g}].r{k}", 0.0) for k in "xyz"])
        R = rotation_matrix(w) @ prob.R0[gi]
        out[rows] = pb[rows] @ R.T + prob.t0[gi] + t
    return out


def _sag(prob: Problem, vals: dict) -> np.ndarray | None:
    """The twist (n, 6) of the model's springs other than the joints' (link springs ...) at the measured frame,
    with the fitted payload's share, or None (:class:`vjm.calibration.nominal.Nominal`): added to the point to
    first order, ``t + w x R p`` with the frame's nominal rotation R, so that it is linear in the marker ``p``."""
    nom = prob.nominal
    return None if nom is None else nom.twist(vals.get("payload.mass", 0.0) if prob.unit_torques is not None else 0.0)


def tilted_gravity(prob: Problem, vals: dict, d: int | None = None) -> np.ndarray:
    """The gravity (3,) in the base frame turned by the base tilt of ``vals`` (about the base x and y axes),
    or its derivative by ``base.tilt_rx`` (d=0) or ``base.tilt_ry`` (d=1)."""
    w = np.array([vals.get("base.tilt_rx", 0.0), vals.get("base.tilt_ry", 0.0), 0.0])
    g = np.asarray(prob.model.gravity, dtype=float)
    if d is None:
        return rotation_matrix(w) @ g
    e = np.zeros(3)
    e[d] = _STEP["rad"]
    return (rotation_matrix(w + e) - rotation_matrix(w - e)) @ g / (2 * e[d])


def total_torques(prob: Problem, vals: dict) -> np.ndarray:
    """The gravity torques (n, nq) N mm: the model's masses (under the tilted gravity if the base is tilted),
    and the fitted payload at the marker."""
    tau = prob.torques
    if prob.gravity_basis is not None and (vals.get("base.tilt_rx", 0.0) or vals.get("base.tilt_ry", 0.0)):
        tau = np.einsum("knj,k->nj", prob.gravity_basis, tilted_gravity(prob, vals))
    m = vals.get("payload.mass", 0.0)
    return tau if not m or prob.unit_torques is None else tau + m * prob.unit_torques


def deflections(prob: Problem, vals: dict) -> np.ndarray:
    """The joints' deflections (n, nq) ``-(c0 + c) g(q) - b sign(g(q))`` under the model's compliances ``c0``,
    the fitted corrections ``c`` and the backlashes ``b`` of ``vals`` (a clearance taken up on the side the
    gravity torque pushes to)."""
    tau = total_torques(prob, vals)
    dq = np.zeros_like(prob.q)
    c0 = None if prob.nominal is None else prob.nominal.compliance
    for i, name in enumerate(prob.model.tree.q_names):
        c = vals.get(f"{name}.compliance", 0.0)
        if c0 is not None and c0[:, i].any():
            c = c + c0[:, i]
        b = vals.get(f"{name}.backlash", 0.0)
        cq = vals.get(f"{name}.varying", 0.0)
        if np.any(c):
            dq[:, i] -= c * tau[:, i]
        if cq:
            dq[:, i] -= cq * prob.q[:, i] * tau[:, i]
        if b:
            dq[:, i] -= b * np.sign(tau[:, i])
    qn = list(prob.model.tree.q_names)
    for key, k in vals.items():
        if k and ".coupling[" in key:
            a, b = key[:-1].split(".coupling[")
            dq[:, qn.index(a)] += k * prob.q[:, qn.index(b)]
    for e in _generic():
        more = e.joint_motion(prob.model, prob.q, vals)
        if more is not None:
            dq = dq + more
    return dq


def _generic() -> list:
    """The robot's effects whose predictions this model does not write itself (:attr:`PoseEffect.joint_motion`)."""
    return [e for e in absolute.POSES.values() if "serial" in e.model_kinds and not e.hand_written]


def load_scale(prob: Problem, name: str, unit: str) -> float:
    """The largest deflection (rad) per unit of a load-driven parameter (compliances, flex effects): its
    torque, moment, beam rotation or temperature offset over the rows."""
    qn = list(prob.model.tree.q_names)
    joint = name.rsplit(".", 1)[0]
    if unit == "c":
        v = prob.torques[:, qn.index(joint)]
    elif unit == "var":
        v = prob.torques[:, qn.index(joint)] * prob.q[:, qn.index(joint)]
    elif unit == "lat":
        v = np.linalg.norm(prob.flex.lateral[:, prob.model.tree.joint_index(joint)], axis=1)
    elif unit == "bend":
        v = np.linalg.norm(next(b.theta for b in prob.flex.beams if b.name == name), axis=1)
    elif unit == "guide":
        g = next(g for g in prob.flex.guides if g.name == joint)
        v = np.concatenate([np.linalg.norm(prob.flex.lateral[:, i], axis=1) for i in g.joints])
    elif unit == "scale":   # a link's nominal deflection: its rotation, or its translation over 1 m
        k = next(k for k in prob.flex.links if k.name == joint)
        v = np.linalg.norm(k.r, axis=1) + np.linalg.norm(k.t, axis=1) / 1000.0
    else:   # "K": a relative length change of 1e-7
        v = prob.flex.dT
    return float(np.max(np.abs(v), initial=0.0))


def steps(prob: Problem, layout: Layout) -> np.ndarray:
    """Central-difference steps: 1e-4 mm, 1e-7 rad, and a load-driven parameter's step deflecting by 1e-7 rad."""
    out = np.empty(layout.size)
    for i, (name, u) in enumerate(zip(layout.names, layout.units)):
        if u in _STEP:
            out[i] = _STEP[u]
        else:
            load = load_scale(prob, name, u)
            out[i] = 1e-7 / load if load > 0 else 1e-12
    return out


def jacobian(prob: Problem, layout: Layout, x: np.ndarray, fixed: dict | None = None) -> np.ndarray:
    """d predict / d x, (3n, size) (rows: point 0 x y z, point 1 ...)."""
    h = steps(prob, layout)
    J = np.empty((predict(prob, layout, x, fixed).size, layout.size))
    for i in range(layout.size):
        e = np.zeros(layout.size)
        e[i] = h[i]
        J[:, i] = (predict(prob, layout, x + e, fixed) - predict(prob, layout, x - e, fixed)).ravel() / (2 * h[i])
    return J


def _axis_column(kind: str, A: np.ndarray, pb: np.ndarray) -> np.ndarray:
    """d pb / d (joint value) for a joint of ``kind`` whose axis frame is A (n, 4, 4)."""
    a = A[:, :3, "xyz".index(kind[1])]
    return np.cross(a, pb - A[:, :3, 3]) if kind[0] == "r" else a


def _origin_columns(G: np.ndarray, d: np.ndarray, pb: np.ndarray) -> np.ndarray:
    """d pb / d (dx..ez) (6, n, 3) of an origin error d applied after the frames G (n, 4, 4): pb is
    ``G Delta(d) s`` with s fixed, differentiated by central differences of the constant Delta only."""
    Di = _rigid_inverse(_delta(d))
    local = np.einsum("nji,nj->ni", G[:, :3, :3], pb - G[:, :3, 3])   # G^-1 pb: the frames are rigid motions
    s = local @ Di[:3, :3].T + Di[:3, 3]
    out = np.empty((6, len(pb), 3))
    for k in range(6):
        h = _STEP["mm" if k < 3 else "rad"]
        e = np.zeros(6)
        e[k] = h
        Dp, Dm = _delta(d + e), _delta(d - e)
        dl = (s @ (Dp[:3, :3] - Dm[:3, :3]).T + (Dp[:3, 3] - Dm[:3, 3])) / (2 * h)
        out[k] = np.einsum("nij,nj->ni", G[:, :3, :3], dl)
    return out


def _base_columns(prob: Problem, vals: dict) -> tuple[np.ndarray, dict]:
    """The marker point pb (n, 3) in the base frame and {parameter name: d pb / d parameter (n, 3)} of the
    robot's parameters and the marker offset."""
    tree = prob.model.tree
    qn = list(tree.q_names)
    q = prob.q
    tau = total_torques(prob, vals)
    dq = deflections(prob, vals)
    pre, post, tool = transforms(prob.flex, prob.model, prob.frame, vals)
    T = np.broadcast_to(np.eye(4), (len(q), 4, 4))
    saved = []
    for ji in tree.path(tree.frame(prob.frame).joint):
        j = tree.joints[ji]
        d = np.array([vals.get(f"{j.name}.{k}", 0.0) for k in GEOMETRY])
        F = T
        if ji in pre:
            T = T @ pre[ji]
        G = T @ j.placement
        A = G @ _delta(d[1:])
        if j.align is not None:
            A = A @ j.align
        if j.mimic is None:
            k, mult, off = qn.index(j.name), 1.0, 0.0
        else:
            k, mult, off = qn.index(j.mimic[0]), float(j.mimic[1]), float(j.mimic[2])
        T = A @ elementary(j.kind, mult * (q[:, k] + dq[:, k]) + off + d[0])
        if j.align is not None:
            T = T @ _rigid_inverse(j.align)
        if ji in post:
            T = T @ post[ji]
        saved.append((ji, j, F, G, A, T, d, k, mult))
    last = T
    T = (T if tool is None else T @ tool) @ tree.frame(prob.frame).placement
    p = prob.p0 + np.array([vals.get(f"{prob.frame}.p{c}", 0.0) for c in "xyz"])
    pb = np.einsum("nij,j->ni", T[:, :3, :3], p) + T[:, :3, 3]
    cols = {f"{prob.frame}.p{c}": T[:, :3, i] for i, c in enumerate("xyz")}
    for ji, j, F, G, A, Tj, d, k, mult in saved:
        ax = _axis_column(j.kind, A, pb)
        cols[f"{j.name}.offset"] = ax
        _torque_columns(prob, vals, cols, qn, k, mult * ax, tau)
        for kk, col in zip(GEOMETRY[1:], _origin_columns(G, d[1:], pb)):
            cols[f"{j.name}.{kk}"] = col
        if prob.flex is not None:
            _flex_columns(prob, vals, cols, (ji, j, F, G, Tj), pb)
    if prob.flex is not None and prob.flex.dT is not None:
        c = cols.get("thermal.alpha", 0.0)
        cols["thermal.alpha"] = c + prob.flex.dT[:, None] * (last[:, :3, :3] @ tree.frame(prob.frame).placement[:3, 3])
    w = _sag(prob, vals)
    if w is not None:   # the sag of the other springs, linear in the marker only (see predict)
        R = prob.nominal.R
        pb = pb + w[:, :3] + np.cross(w[:, 3:], R @ p)
        for i, c in enumerate("xyz"):
            cols[f"{prob.frame}.p{c}"] = cols[f"{prob.frame}.p{c}"] + np.cross(w[:, 3:], R[:, :, i])
        u = prob.nominal.unit_sag
        if u is not None and prob.unit_torques is not None:
            cols["payload.mass"] = cols.get("payload.mass", 0.0) + u[:, :3] + np.cross(u[:, 3:], R @ p)
    return pb, cols


def _torque_columns(prob: Problem, vals: dict, cols: dict, qn: list, k: int, ax: np.ndarray, tau: np.ndarray) -> None:
    """The columns of the parameters acting through joint k's value (its axis column ``ax`` times the
    multiplier of a mimic): compliance, varying compliance, backlash, couplings, tilt, payload."""
    q = prob.q
    comp = f"{qn[k]}.compliance"
    cols[comp] = cols.get(comp, 0.0) + ax * (-tau[:, k:k + 1])
    var = f"{qn[k]}.varying"
    cols[var] = cols.get(var, 0.0) + ax * (-tau[:, k:k + 1] * q[:, k:k + 1])
    back = f"{qn[k]}.backlash"
    cols[back] = cols.get(back, 0.0) + ax * (-np.sign(tau[:, k:k + 1]))
    for b in qn:
        if b != qn[k]:
            name = f"{qn[k]}.coupling[{b}]"
            cols[name] = cols.get(name, 0.0) + ax * q[:, qn.index(b), None]
    ceff = vals.get(comp, 0.0) + vals.get(var, 0.0) * q[:, k]
    if prob.nominal is not None:
        ceff = ceff + prob.nominal.compliance[:, k]
    if prob.gravity_basis is not None:
        for axis, name in enumerate(("base.tilt_rx", "base.tilt_ry")):
            dtau = np.einsum("kn,k->n", prob.gravity_basis[:, :, k], tilted_gravity(prob, vals, axis))
            cols[name] = cols.get(name, 0.0) + ax * (-ceff * dtau)[:, None]
    if prob.unit_torques is not None:
        cu = -ceff * prob.unit_torques[:, k]
        cols["payload.mass"] = cols.get("payload.mass", 0.0) + ax * cu[:, None]


def _flex_columns(prob: Problem, vals: dict, cols: dict, at: tuple, pb: np.ndarray) -> None:
    """The columns of joint ``ji``'s lateral compliance, the beam it carries and its share of the thermal
    scale, from the frames ``F`` (before its placement's flex motion), ``G`` (after its placement) and
    ``Tj`` (after its motion)."""
    ji, j, F, G, Tj = at
    flex = prob.flex
    base = _before_links(prob, vals, ji, Tj)
    lat = np.einsum("nij,nj->ni", base[:, :3, :3], flex.lateral[:, ji])
    cols[f"{j.name}.lateral"] = np.cross(lat, pb - base[:, :3, 3])
    if flex.guides or flex.links:
        _guide_link_columns(prob, vals, cols, ji, base, pb)
    for bm in flex.beams:
        if bm.joint == ji:
            c = vals.get(bm.name, 0.0)
            y = np.einsum("nji,nj->ni", Tj[:, :3, :3], pb - Tj[:, :3, 3])
            loc = np.cross(bm.theta, y - bm.tip - c * bm.u) + bm.u
            cols[bm.name] = np.einsum("nij,nj->ni", Tj[:, :3, :3], loc)
    if flex.dT is not None:
        # the placement's translation, scaled, moves what follows rigidly: in the frame just before it
        Gr = G[:, :3, :3] @ j.placement[:3, :3].T
        cols["thermal.alpha"] = cols.get("thermal.alpha", 0.0) + flex.dT[:, None] * (Gr @ j.placement[:3, 3])


def _before_links(prob: Problem, vals: dict, ji: int, Tj: np.ndarray) -> np.ndarray:
    """Joint ``ji``'s frame after its motion and its bearing's or guide's tilt, before its link springs'
    deflections (``Tj`` after all of them, :func:`vjm.calibration.flex.transforms`)."""
    base = Tj
    for k in reversed([k for k in prob.flex.links if k.joint == ji]):
        v = vals.get(f"{k.name}.link_scale", 0.0)
        if v:
            base = base @ _inverse_batch(link_motion(k, v))
    return base


def _guide_link_columns(prob: Problem, vals: dict, cols: dict, ji: int, base: np.ndarray, pb: np.ndarray) -> None:
    """The columns of a prismatic guide's tilt compliances at joint ``ji`` and of the link springs it carries,
    from its frame before the link springs (``base``): each spring's ``S D S^-1`` follows in turn; each
    column is exact (a rotation about a fixed axis differentiates to that axis times itself)."""
    mine = [k for k in prob.flex.links if k.joint == ji]
    for g in prob.flex.guides:
        if ji in g.joints:
            w_ = np.einsum("nij,nj->ni", base[:, :3, :3], prob.flex.lateral[:, ji])
            exit_ = base[:, :3, 3] - np.einsum("nij,nj->ni", base[:, :3, :3], g.slide[:, g.joints.index(ji)])
            for kind, centre in (("guide_tilt", base[:, :3, 3]), ("column_tilt", exit_)):
                lat = np.cross(w_, pb - centre)
                for end, w in (("lower", 1.0 - g.s), ("upper", g.s)):
                    name = f"{g.name}.{kind}_{end}"
                    cols[name] = cols.get(name, 0.0) + lat * w[:, None]
    for k in mine:
        v = vals.get(f"{k.name}.link_scale", 0.0)
        M = link_motion(k, v)
        D = k.S_inv @ M @ k.S   # the spring frame's small motion
        F = base @ k.S @ D      # the spring frame after its deflection
        z = np.einsum("nji,nj->ni", F[:, :3, :3], pb - F[:, :3, 3])
        loc = np.cross(k.r, z) + np.einsum("nji,nj->ni", D[:, :3, :3], k.t)   # r x z + R^T t
        cols[f"{k.name}.link_scale"] = np.einsum("nij,nj->ni", F[:, :3, :3], loc)
        base = base @ M


def _inverse_batch(T: np.ndarray) -> np.ndarray:
    """Inverses (n, 4, 4) of rigid motions (n, 4, 4)."""
    out = np.broadcast_to(np.eye(4), T.shape).copy()
    Rt = np.swapaxes(T[:, :3, :3], 1, 2)
    out[:, :3, :3] = Rt
    out[:, :3, 3] = -np.einsum("nij,nj->ni", Rt, T[:, :3, 3])
    return out


def jacobian_fast(prob: Problem, layout: Layout, x: np.ndarray, fixed: dict | None = None) -> np.ndarray:
    """:func:`jacobian` from one pass along the chain: joint axes for offsets and compliances, the frame
    columns for the marker, and differences of the small constant transforms only for the origin errors
    and the registration rotations (the same values to about 1e-9, some twenty times faster)."""
    if isinstance(prob, Points):
        return np.concatenate([jacobian_fast(p, layout, x, fixed) for p in prob.parts])
    vals = dict(fixed or {})
    vals.update(zip(layout.names, x))
    pb, cols = _base_columns(prob, vals)
    J = instrument_jacobian(pb, cols, layout, vals, prob.groups, prob.gidx, prob.R0)
    own = {e.name for e in _generic()}
    other = [i for i, k in enumerate(layout.kinds) if k in own]
    if other:   # an effect without columns of its own: central differences of the prediction
        h = steps(prob, layout)
        for i in other:
            e = np.zeros(layout.size)
            e[i] = h[i]
            J[:, i] = (predict(prob, layout, x + e, fixed) - predict(prob, layout, x - e, fixed)).ravel() / (2 * h[i])
    return J


def instrument_jacobian(pb: np.ndarray, cols: dict, layout: Layout, vals: dict, groups, gidx, R0) -> np.ndarray:
    """d (measured points) / d (parameters of ``layout``), (3n, size), from the points ``pb`` (n, 3) in the
    base frame and their columns ``cols`` (name: (n, 3) or (3,) base-frame motion per unit of the parameter):
    each group's instrument rotation applied to them, the registration's own columns added (translations,
    and rotations by central differences of ``_STEP["rad"]``).  The robot's and the parallel machine's
    measurement models share it."""
    J = np.zeros((len(pb), 3, layout.size))
    h = _STEP["rad"]
    for gi, g in enumerate(groups):
        rows = gidx == gi
        w = np.array([vals.get(f"reg[{g}].r{c}", 0.0) for c in "xyz"])
        R = rotation_matrix(w) @ R0[gi]
        for i, name in enumerate(layout.names):
            if name.startswith(f"reg[{g}].t"):
                J[rows, "xyz".index(name[-1]), i] = 1.0
            elif name.startswith(f"reg[{g}].r"):
                e = np.zeros(3)
                e["xyz".index(name[-1])] = h
                dR = (rotation_matrix(w + e) - rotation_matrix(w - e)) @ R0[gi] / (2 * h)
                J[rows, :, i] = pb[rows] @ dR.T
            elif name in cols:
                J[rows, :, i] = np.broadcast_to(cols[name], pb.shape)[rows] @ R.T
    return J.reshape(-1, layout.size)
