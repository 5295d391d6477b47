"""Denavit-Hartenberg tables (model YAML ``dh:``) as a :class:`~vjm.robot.tree.Tree`.

::

    dh:
      convention: standard        # | modified (Craig)
      base: {xyz: [0, 0, 0], rpy: [0, 0, 0]}   # optional, mm and rad
      tool: {xyz: [0, 0, 100], rpy: [0, 0, 0]} # optional: the tool frame in the last link's frame
      frames:                     # optional: more named frames fixed to a frame of the table (a marker)
        tool_marker: {at: tool, xyz: [0, 0, 20], rpy: [0, 0, 0]}
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

The frames of a table are ``tool``, ``link1`` ... ``linkN`` (the frame after ``A_i``) and those of ``frames:``.
:func:`match_table` writes a table of the same rows reproducing another tree's kinematics (a calibrated one).
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
    extra = set(spec) - {"convention", "base", "tool", "joints", "frames"}
    if extra:
        raise VjmError(f"{where}: unknown keys {sorted(extra)}; known: convention, base, tool, joints, frames")
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
    frames += _named_frames(spec.get("frames"), frames, f"{where}.frames")
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


def _named_frames(spec, frames: tuple, where: str) -> tuple:
    """The ``frames:`` of a table: each {at: a frame of the table, xyz mm, rpy rad}, fixed to that frame."""
    if spec is None:
        return ()
    if not isinstance(spec, dict):
        raise VjmError(f"{where} must be a mapping name -> {{at: frame, xyz: [x, y, z], rpy: [r, p, y]}}")
    known = {f.name: f for f in frames}
    out = []
    for name, f in spec.items():
        w = f"{where}.{name}"
        if not isinstance(f, dict) or "at" not in f:
            raise VjmError(f"{w} must be a mapping with at: (tool or a linkN) and optional xyz, rpy")
        if name in known:
            raise VjmError(f"{w}: the table already has a frame {name!r}")
        at = known.get(str(f["at"]))
        if at is None:
            raise VjmError(f"{w}.at: no frame {f['at']!r}; frames: {', '.join(known)}")
        T = at.placement @ _frame({k: v for k, v in f.items() if k != "at"}, w)
        known[str(name)] = Frame(str(name), at.joint, T)
        out.append(known[str(name)])
    return tuple(out)


#: a row's parameters as :func:`match_table` fits them, in the order of the standard convention's product
_PARAMS = ("theta", "d", "a", "alpha", "beta")


def _row_constant(conv: str, kind: str, v) -> tuple[np.ndarray, bool]:
    """A row (theta, d, a, alpha, beta) as ``A_i = C M(q)`` (standard: the joint's motion first, then the constant)
    or ``A_i = C M(q)`` with the constant first (modified): (C 4x4, whether the motion comes first).  The joint's
    motion (about or along z) commutes with Rz(theta) and Tz(d)."""
    th, d, a, al, be = (float(x) for x in v)
    if conv == "standard":
        return _E("rz", th) @ _E("tz", d) @ _E("tx", a) @ _E("rx", al) @ _E("ry", be), True
    return _E("rx", al) @ _E("ry", be) @ _E("tx", a) @ _E("rz", th) @ _E("tz", d), False


def _table_tool(conv: str, kinds: list, base: np.ndarray, rows: np.ndarray, tool: np.ndarray,
                Q: np.ndarray) -> np.ndarray:
    """The tool frames (n, 4, 4) of a table (rows (nq, 5)) at configurations Q (n, nq)."""
    T = np.broadcast_to(base, (len(Q), 4, 4))
    for i, kind in enumerate(kinds):
        C, motion_first = _row_constant(conv, kind, rows[i])
        M = elementary("rz" if kind == "revolute" else "tz", Q[:, i])
        T = T @ (M @ C if motion_first else C @ M)
    return T @ tool


def match_table(spec: dict, Q: np.ndarray, target: np.ndarray, where: str = "dh") -> tuple:
    """A table of ``spec``'s convention and rows whose tool frame is ``target`` (n, 4, 4) at the configurations
    ``Q`` (n, nq): (rows [{theta, d, a, alpha, beta} rad, mm], base 4x4, tool 4x4), fitted by Gauss-Newton
    from ``spec``'s own values.  Each row keeps ``d: 0`` where it writes Hayati's ``beta`` (a row with beta,
    or nearly parallel axes with ``d: 0``), so that it reads back; a tree whose kinematics no such table
    reproduces within 1e-6 mm is refused (VjmError)."""
    tree_from_dh(spec, where=where)   # a valid table
    conv = spec.get("convention", "standard")
    rows = [r for r in spec["joints"]]
    kinds = [r.get("type", "revolute") for r in rows]
    v0 = np.array([[_val(r.get(k, 0.0), f"{where}.{k}") for k in _PARAMS] for r in rows])
    free = np.ones_like(v0, dtype=bool)
    for i, v in enumerate(v0):
        hayati = "beta" in rows[i] or (abs(np.sin(v[3])) < 1e-3 and v[1] == 0.0)
        free[i, 1], free[i, 4] = not hayati, hayati
    # what the base and the tool frames take (they commute with the first and last joints' motions) is kept as the
    # source writes it: standard, the first row's theta and d and the whole last row; modified, the whole first
    # row and the last row's theta and d
    if conv == "standard":
        free[0, :2] = False
        free[-1, :] = False
    else:
        free[0, :] = False
        free[-1, :2] = False
    B0 = _frame(spec.get("base"), f"{where}.base")
    T0 = _frame(spec.get("tool"), f"{where}.tool")
    scale = max(1.0, float(np.max(np.abs(target[:, :3, 3]))))

    def unpack(x):
        v = v0.copy()
        v[free] += x[12:]
        return B0 @ origin_transform(x[:3], x[3:6]), v, T0 @ origin_transform(x[6:9], x[9:12])

    def resid(x):
        B, v, Tt = unpack(x)
        T = _table_tool(conv, kinds, B, v, Tt, Q)
        E = np.einsum("nji,njk->nik", target[:, :3, :3], T[:, :3, :3])
        return np.concatenate([(T[:, :3, 3] - target[:, :3, 3]).ravel(),
                               scale * np.stack([E[:, 2, 1], E[:, 0, 2], E[:, 1, 0]], axis=1).ravel()])

    from scipy.optimize import least_squares

    # the corrections are small: Levenberg-Marquardt from the table's own values, its steps scaled by the columns
    # (the base and the tool overlap the first and last rows: the damping keeps one table near the source's)
    x = least_squares(resid, np.zeros(12 + int(free.sum())), method="lm", x_scale="jac", xtol=1e-15, ftol=1e-15,
                      gtol=1e-15, max_nfev=20000).x
    err = float(np.max(np.abs(resid(x))))
    if not err < 1e-6:
        raise VjmError(f"{where}: no table of these rows reproduces the calibrated kinematics (off by {err:.3g} mm); "
                       f"write the robot as a URDF")
    B, v, Tt = unpack(x)
    return [dict(zip(_PARAMS, map(float, row))) for row in v], B, Tt

