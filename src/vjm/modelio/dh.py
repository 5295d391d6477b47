"""Denavit-Hartenberg tables (model YAML ``dh:``) as a :class:`~vjm.robot.tree.Tree`.

::

    dh:
      convention: standard        # | modified (Craig)
      base: {xyz: [0, 0, 0], rpy: [0, 0, 0]}   # optional, mm and rad
      tool: {xyz: [0, 0, 100], rpy: [0, 0, 0]} # optional: the tool frame in the last link's frame
      joints:
        - {name: a1, type: revolute, a: 175, alpha: -90*deg, d: 495, theta: 0, limits: [-185*deg, 185*deg],
           mass: 20, com: [0, 0, 100]}
        - {name: a2, type: revolute, a: 900, alpha: 0, d: 0, theta: -90*deg, beta: 0}

Standard: ``A_i = Rz(theta_i + q_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)``; modified (Craig):
``A_i = Rx(alpha_i) Ry(beta_i) Tx(a_i) Rz(theta_i + q_i) Tz(d_i)`` (alpha, a of the row are
those between the previous axis and this one).  ``beta`` is Hayati's parameter: for nearly
parallel consecutive axes DH's ``d`` is ill-conditioned, and the row writes ``beta`` (the
rotation about y) with ``d = 0`` instead.  A prismatic joint's value adds to ``d``.  Lengths in
mm, angles in rad; a value may be an expression (``-90*deg``, ``pi/2``).  ``mass`` (kg) and
``com`` (mm, in the frame of the joint's link, i.e. after ``A_i``) give the link's inertial.
"""
from __future__ import annotations

import numpy as np

from ..errors import VjmError
from ..kinematics.transforms import elementary
from ..robot.tree import Body, Frame, Tree, TreeJoint, origin_transform
from .description import evaluate

ROW_KEYS = ("name", "type", "a", "alpha", "d", "theta", "beta", "limits", "mass", "com")
#: the model file's key this format reads (:mod:`vjm.modelio.robotformats`), and how a message names it
KEYS = ("dh",)
DESCRIBES = "dh: (a table)"


def recognises(mapping) -> bool:
    """A model file holding a DH table (``dh:``)."""
    return isinstance(mapping, dict) and "dh" in mapping


def read(mapping: dict, base_dir: str) -> Tree:
    """The tree of a model file's ``dh:`` table, named after the file's ``name:``."""
    return tree_from_dh(mapping["dh"], str(mapping.get("name", "")))


def _val(v, where: str) -> float:
    if isinstance(v, bool):
        raise VjmError(f"{where} must be a number, got {v!r}")
    if isinstance(v, (int, float)):
        if not np.isfinite(v):
            raise VjmError(f"{where} must be finite, got {v!r}")
        return float(v)
    if isinstance(v, str):
        return evaluate(v, {}, where)
    raise VjmError(f"{where} must be a number or an expression, got {v!r}")


def _angles(r: dict, w: str, jt: str) -> None:
    """A row's angles (rad) beyond a turn (a revolute joint's limits beyond two: some wrists turn more than
    one) are in degrees: refused, with the expression that says so."""
    given = [(f"{w}.{k}", r[k], 2 * np.pi, "one turn") for k in ("alpha", "theta", "beta") if k in r]
    lim = r.get("limits")
    if jt == "revolute" and isinstance(lim, list):
        given += [(f"{w}.limits", v, 4 * np.pi, "two turns") for v in lim]
    for where, v, bound, turns in given:
        if abs(_val(v, where)) > bound + 1e-9:
            raise VjmError(f"{where}: {v!r} rad is beyond {turns}: degrees? write it as {v}*deg (angles are in rad)")


def _E(kind: str, a: float) -> np.ndarray:
    return elementary(kind, np.array([a]))[0]


def _frame(spec, where: str) -> np.ndarray:
    if spec is None:
        return np.eye(4)
    if not isinstance(spec, dict) or set(spec) - {"xyz", "rpy"}:
        raise VjmError(f"{where} must be a mapping {{xyz: [x, y, z] mm, rpy: [r, p, y] rad}}")
    vec = []
    for k in ("xyz", "rpy"):
        v = spec.get(k, [0, 0, 0])
        if not isinstance(v, list) or len(v) != 3:
            raise VjmError(f"{where}.{k} must be 3 numbers")
        vec.append([_val(x, f"{where}.{k}") for x in v])
    return origin_transform(*vec)


def tree_from_dh(spec, name: str = "", where: str = "dh") -> Tree:
    """The tree of a ``dh:`` mapping (see the module docstring)."""
    if not isinstance(spec, dict) or "joints" not in spec:
        raise VjmError(f"{where} must be a mapping with joints: (a list of DH rows)")
    extra = set(spec) - {"convention", "base", "tool", "joints"}
    if extra:
        raise VjmError(f"{where}: unknown keys {sorted(extra)}; known: convention, base, tool, joints")
    conv = spec.get("convention", "standard")
    if conv not in ("standard", "modified"):
        raise VjmError(f"{where}.convention must be standard or modified (Craig), got {conv!r}")
    rows = spec["joints"]
    if not isinstance(rows, list) or not rows:
        raise VjmError(f"{where}.joints must be a non-empty list of DH rows")
    joints, bodies, posts = [], [], []
    pre = _frame(spec.get("base"), f"{where}.base")  # constant part before the next joint factor
    for i, r in enumerate(rows):
        w = f"{where}.joints[{i}]"
        if not isinstance(r, dict):
            raise VjmError(f"{w} must be a mapping (name, type, a, alpha, d, theta ...)")
        bad = set(r) - set(ROW_KEYS)
        if bad:
            raise VjmError(f"{w}: unknown keys {sorted(bad)}; known: {', '.join(ROW_KEYS)}")
        jt = r.get("type", "revolute")
        if jt not in ("revolute", "prismatic"):
            raise VjmError(f"{w}.type must be revolute or prismatic, got {jt!r}")
        a, alpha, d, theta, beta = (_val(r.get(k, 0.0), f"{w}.{k}") for k in ("a", "alpha", "d", "theta", "beta"))
        _angles(r, w, jt)
        if beta != 0.0 and d != 0.0:
            raise VjmError(f"{w}: Hayati's beta replaces d (nearly parallel axes): give d: 0 with beta")
        lo, hi = -np.inf, np.inf
        if "limits" in r:
            lim = r["limits"]
            if not isinstance(lim, list) or len(lim) != 2:
                raise VjmError(f"{w}.limits must be [lower, upper]")
            lo, hi = (_val(x, f"{w}.limits") for x in lim)
            if not lo < hi:
                raise VjmError(f"{w}.limits: lower {lo:g} must be below upper {hi:g}")
        if conv == "modified":
            pre = pre @ _E("rx", alpha) @ _E("ry", beta) @ _E("tx", a)
        kind = "rz" if jt == "revolute" else "tz"
        if jt == "revolute":
            place, post = pre @ _E("rz", theta), _E("tz", d)
        else:
            place, post = pre @ _E("rz", theta) @ _E("tz", d), np.eye(4)
        if conv == "standard":
            post = post @ _E("tx", a) @ _E("rx", alpha) @ _E("ry", beta)
        jname = str(r.get("name", f"joint{i + 1}"))
        joints.append(TreeJoint(jname, i - 1, place, kind, jt, lo, hi, child=f"link{i + 1}"))
        # the link frame (after A_i) in this joint's frame is ``post``; the next joint starts from it
        pre = post
        posts.append(post)
        if "mass" in r or "com" in r:
            bodies.append(_body(r, w, jname, i, post))
    tool = pre @ _frame(spec.get("tool"), f"{where}.tool")
    names = [j.name for j in joints]
    if len(set(names)) != len(names):
        raise VjmError(f"{where}: joint names must be unique, got {names}")
    # the DH frame after A_i is named after its joint's link: link1 ... linkN
    frames = (Frame("tool", len(joints) - 1, tool),) + tuple(
        Frame(f"link{i + 1}", i, T) for i, T in enumerate(posts))
    return Tree(name or "dh", tuple(joints), frames, tuple(bodies), ("tool",), where,
                frozenset(b.joint for b in bodies))


def _body(r: dict, w: str, jname: str, i: int, post: np.ndarray) -> Body:
    if "mass" not in r:
        raise VjmError(f"{w}: a com without a mass")
    if "com" not in r:
        raise VjmError(f"{w}: a mass of {r['mass']!r} kg without a centre of mass (com: [x, y, z] mm)")
    m = _val(r["mass"], f"{w}.mass")
    if m < 0:
        raise VjmError(f"{w}.mass must be >= 0 (kg), got {m:g}")
    c = r["com"]
    if not isinstance(c, list) or len(c) != 3:
        raise VjmError(f"{w}.com must be [x, y, z] (mm, in the link frame)")
    cl = np.array([_val(x, f"{w}.com") for x in c])
    return Body(jname, i, m, post[:3, :3] @ cl + post[:3, 3])
