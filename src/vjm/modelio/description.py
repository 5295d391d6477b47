"""Machine descriptions: any parallel machine as chains of elementary transforms (YAML).

A description file is a model file (same keys ``name``, ``geometry``,
``actuator``, ``foot``, ``leg``, ``joints``, ``effects``) whose machine is given by
``platform`` and ``chains`` instead of a built-in ``architecture``::

    geometry: {L: 310, r: 50}           # mm; names usable in the expressions below
    platform:
      dof: 3                            # 3 (translations) or 6
      seed: [0, 0, 0]                   # seed pose: x, y, z [, rx, ry, rz] (mm, rad rotation vector)
      attachments: {a1: [Rz(-40*deg), Tx(rp)]}   # optional frames on the platform
      workspace: [[-100, -100, -100], [100, 100, 100]]   # optional box for maps, mm
    links:                              # optional links besides foot and leg
      strut: {beam: {...}}
    chains:
      - name: x
        copies: {permute: [y, z, x], count: 3, names: [x, y, z]}
        seed: {q0: 0}                   # seed values of the chain's variables (default 0)
        limits: {q0: [-100, 100]}       # optional ranges (mm, rad): a pose needing more is unreachable
        transforms: [Tx(-L - r), Tx(q0) actuated, spring foot, Rz(q1), Ry(q2), Tx(L),
                     spring leg, Ry(q3), Rz(q4), Tx(r)]

Elements of ``transforms``, read left to right as the product of eq. 1:

* ``Tx(expr)`` ... ``Rz(expr)``: a constant; ``expr`` is arithmetic on numbers, geometry
  names, ``pi``, ``deg`` (= pi/180) and ``sin cos tan asin acos atan atan2 sqrt``;
* ``Tx(q)``, ``Rz(-q)``: a joint coordinate ``q`` (a name that is not a geometry key),
  ``passive`` (default), ``actuated`` (with the actuator's 1-dof spring) or ``joint`` (a
  1-dof passive-joint spring of stiffness ``joints.passive_stiffness``; left out when
  that is null, i.e. ideal joints).  A name used twice is one coordinate (``Ry(q2) Tx(L)
  Ry(-q2)`` is a parallelogram's coupled rotation);
* ``spring NAME``: a 6-dof spring (``Tx Ty Tz Rx Ry Rz``, eq. 18) whose compliance is
  the link ``NAME`` (``foot``, ``leg`` or a key of ``links``) in the current frame;
* ``spring NAME parallelogram(q, L, d)``: the equivalent spring of a parallelogram whose
  bars are link ``NAME`` (one bar, tip frame), of length ``L``, ``d`` apart, at angle ``q``
  (eq. 20-22; the chain must hold ``Ry(q) Tx(L) Ry(-q)`` before it).

A chain ends at the platform frame (the end-effector point), or at a platform
attachment ``platform: a1``, in which case the attachment's inverse closes it.
``copies`` repeats a chain by a symmetry ``S`` (``rotate: [Rz(120*deg)]`` or
``permute: [y, z, x]``, the rotation taking x, y, z to those axes): copy ``k`` is
``S^k chain S^-k``, so it reaches the platform frame at the pose rotated by ``S^k``.
Every chain has exactly one actuated coordinate.
"""
from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import VjmError
from ..kinematics.transforms import KINDS, elementary

PLATFORM_KEYS = ("dof", "seed", "attachments", "workspace")
MAX_COPIES = 64
"""Most copies of one chain (machines have 3 or 6 legs; ``count: 1000000000`` grew past 6 GB)."""
CHAIN_KEYS = ("name", "transforms", "copies", "seed", "platform", "limits")
ROLES = ("passive", "actuated", "joint")
KIND_OF = {k.capitalize(): k for k in KINDS}          # "Tx" -> "tx"
_FUNCS: dict[str, Callable[..., float]] = {"sin": math.sin, "cos": math.cos, "tan": math.tan, "asin": math.asin, "acos": math.acos,
          "atan": math.atan, "atan2": math.atan2, "sqrt": math.sqrt}
_IDENT = re.compile(r"^\s*(-?)\s*([A-Za-z_]\w*)\s*$")


@dataclass(frozen=True)
class Element:
    """One element of a chain: a constant, a joint coordinate or a 6-dof spring."""

    kind: str                  # tx..rz, or "spring"
    role: str                  # const | passive | actuated | joint | spring
    expr: str = ""             # constant's expression
    var: str = ""              # coordinate name
    coef: float = 1.0
    link: str = ""             # spring's link
    parallelogram: tuple = ()  # (angle variable, L expr, d expr)
    text: str = ""


@dataclass(frozen=True)
class ChainSpec:
    name: str
    elements: tuple[Element, ...]
    seed: tuple                # ((name, value), ...)
    symmetry: tuple = ()       # constant elements of S (expressions), applied ``power`` times
    power: int = 0
    attach: str = ""
    limits: tuple = ()         # ((name, lo, hi), ...): a pose needing a value outside is unreachable


@dataclass(frozen=True)
class Description:
    """A parsed machine description (expressions kept, evaluated against the model's geometry)."""

    dof: int
    seed: tuple                # pose, 3 or 6 numbers
    attachments: tuple         # ((name, (Element, ...)), ...)
    chains: tuple[ChainSpec, ...]
    workspace: tuple | None
    links: tuple[str, ...]     # link names the chains refer to
    raw: dict                  # platform, links and chains as written (to save the file back)

    def __repr__(self):        # the kinematic key of a model: everything but ``raw``
        return f"Description({self.dof}, {self.seed}, {self.attachments}, {self.chains})"


# ------------------------------------------------------------------ expressions

MAX_EXPRESSION = 1000
"""Longest expression read, in characters (a parser fed a megabyte of nesting exhausts the stack)."""


def _refused(node: ast.AST) -> str:
    """What a node that is no arithmetic is, for the message."""
    if isinstance(node, ast.Call):
        f = node.func
        name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None
        if name in _FUNCS:
            return f"calling {name}() with keyword arguments"
        return f"calling {name}()" if name else "a call"
    if isinstance(node, ast.Attribute):
        return f"attribute access .{node.attr}"
    return {ast.Subscript: "indexing", ast.Lambda: "a lambda", ast.Constant: "a constant that is no number",
            ast.JoinedStr: "a formatted string", ast.IfExp: "a conditional"}.get(type(node), type(node).__name__)


def _binary(op, a: float, b: float, expr: str, where: str) -> float:
    """``a op b``, only the one asked for (``a ** b`` of ``1000 * 200`` overflows); a power with no real
    value is a VjmError, not Python's complex number."""
    if op is ast.Add:
        return a + b
    if op is ast.Sub:
        return a - b
    if op is ast.Mult:
        return a * b
    if op is ast.Div:
        return a / b if b != 0 else math.inf
    if a < 0 and b != int(b):
        raise VjmError(f"{where}: {expr!r} has no real value (({a:g}) ** {b:g}: a negative number to a fractional "
                       f"power)")
    if a == 0 and b < 0:
        raise VjmError(f"{where}: {expr!r} has no value (0 ** {b:g} divides by zero)")
    return a ** b


def evaluate(expr: str, geometry: dict, where: str) -> float:
    """Value of an arithmetic expression on geometry names (VjmError naming ``where``)."""
    names = {"pi": math.pi, "deg": math.pi / 180.0, **{k: v for k, v in geometry.items()
                                                        if isinstance(v, (int, float))}}

    def ev(node):
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            return float(node.value)
        if isinstance(node, ast.Name):
            if node.id not in names:
                raise VjmError(f"{where}: unknown name {node.id!r} (geometry keys: {', '.join(geometry) or 'none'})")
            return float(names[node.id])
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = ev(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)):
            return _binary(type(node.op), ev(node.left), ev(node.right), expr, where)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FUNCS \
                and not node.keywords:
            return float(_FUNCS[node.func.id](*[ev(a) for a in node.args]))
        raise VjmError(f"{where}: {expr!r} is not an arithmetic expression of numbers and geometry names "
                       f"({_refused(node)} is not allowed: expressions are data, never code; functions: "
                       f"{', '.join(_FUNCS)})")

    text = str(expr).strip()
    if len(text) > MAX_EXPRESSION:
        raise VjmError(f"{where}: an expression of {len(text)} characters is too long (limit {MAX_EXPRESSION})")
    try:
        v = ev(ast.parse(text, mode="eval"))
    except SyntaxError:
        raise VjmError(f"{where}: cannot read {expr!r} as an expression") from None
    except (RecursionError, MemoryError):
        raise VjmError(f"{where}: the expression is nested too deeply to read") from None
    except VjmError:  # a ValueError already naming ``where``: not to be wrapped a second time
        raise
    except OverflowError:
        raise VjmError(f"{where}: {expr!r} is too large: its value is beyond the largest floating-point "
                       f"number (about 1.8e308)") from None
    except (ValueError, TypeError) as exc:
        raise VjmError(f"{where}: {expr!r} cannot be evaluated ({exc})") from None
    if not math.isfinite(v):
        raise VjmError(f"{where}: {expr!r} is not finite")
    return v


def _call(text: str, where: str):
    """``Name(args) rest`` -> (Name, args, rest), with nested parentheses in args."""
    m = re.match(r"^\s*([A-Za-z_]\w*)\s*\(", text)
    if not m:
        raise VjmError(f"{where}: expected an elementary transform such as Tx(100) or Rz(q1), "
                       f"or 'spring LINK', got {text!r}")
    depth, i = 1, m.end()
    while i < len(text) and depth:
        depth += {"(": 1, ")": -1}.get(text[i], 0)
        i += 1
    if depth:
        raise VjmError(f"{where}: unbalanced parentheses in {text!r} (in a YAML [flow, list] quote an element "
                       f"that holds commas)")
    return m.group(1), text[m.end():i - 1], text[i:].strip()


def _split_args(s: str) -> list[str]:
    out, depth, cur = [], 0, ""
    for ch in s:
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
            continue
        depth += {"(": 1, ")": -1}.get(ch, 0)
        cur += ch
    out.append(cur)
    return [a.strip() for a in out]


def parse_element(text, geometry: dict, where: str) -> Element:
    """One element string -> Element (validated against the geometry's names)."""
    if not isinstance(text, str):
        raise VjmError(f"{where}: an element is a string such as 'Tx(100)', 'Rz(q1)' or 'spring leg', got {text!r}")
    words = text.split()
    if words and words[0] == "spring":
        if len(words) < 2 or not re.match(r"^[A-Za-z_]\w*$", words[1]):
            raise VjmError(f"{where}: 'spring' needs a link name, e.g. 'spring leg'")
        par: tuple = ()
        rest = " ".join(words[2:])
        if rest:
            name, args, tail = _call(rest, where)
            a = _split_args(args)
            if name != "parallelogram" or tail or len(a) != 3 or not _IDENT.match(a[0]):
                raise VjmError(f"{where}: after 'spring {words[1]}' only 'parallelogram(q, L, d)' may follow, "
                               f"got {rest!r}")
            for x in a[1:]:
                evaluate(x, geometry, where)
            par = (a[0], a[1], a[2])
        return Element("spring", "spring", link=words[1], parallelogram=par, text=text)
    name, arg, role = _call(text, where)
    if name not in KIND_OF:
        raise VjmError(f"{where}: unknown transform {name!r}; known: {', '.join(KIND_OF)} and 'spring LINK'")
    kind = KIND_OF[name]
    m = _IDENT.match(arg)
    if m and m.group(2) not in geometry and m.group(2) not in ("pi", "deg"):
        role = role or "passive"
        if role not in ROLES:
            raise VjmError(f"{where}: unknown role {role!r} of coordinate {m.group(2)!r}; known: {', '.join(ROLES)}")
        return Element(kind, role, var=m.group(2), coef=-1.0 if m.group(1) else 1.0, text=text)
    if role:
        raise VjmError(f"{where}: {arg!r} is a constant (numbers and geometry names), it cannot be {role!r}")
    evaluate(arg, geometry, where)
    return Element(kind, "const", expr=arg, text=text)


def _constants(items, geometry, where) -> tuple[Element, ...]:
    if isinstance(items, str):
        items = [items]
    if not isinstance(items, list):
        raise VjmError(f"{where}: expected a list of constant transforms, e.g. [Rz(120*deg)]")
    out = []
    for k, t in enumerate(items):
        e = parse_element(t, geometry, f"{where}[{k}]")
        if e.role != "const":
            raise VjmError(f"{where}[{k}] {t!r}: must be a constant transform")
        out.append(e)
    return tuple(out)


def constant_matrix(elements, geometry) -> np.ndarray:
    """The 4x4 product of constant elements."""
    T = np.eye(4)
    for e in elements:
        T = T @ elementary(e.kind, np.array([evaluate(e.expr, geometry, e.text)]))[0]
    return T


def _permutation(spec, where) -> tuple[Element, ...]:
    """The rotation taking x, y, z to the given axes, written as constant elements."""
    axes = {"x": 0, "y": 1, "z": 2}
    if not (isinstance(spec, list) and sorted(spec) == ["x", "y", "z"]):
        raise VjmError(f"{where}.permute: expected the images of x, y, z, e.g. [y, z, x]")
    R = np.zeros((3, 3))
    for j, a in enumerate(spec):
        R[axes[a], j] = 1.0
    if np.linalg.det(R) < 0:
        raise VjmError(f"{where}.permute: {spec} is a reflection, not a rotation")
    # a rotation matrix as ZYX angles (exact for permutations)
    b = math.asin(max(-1.0, min(1.0, -R[2, 0])))
    a = math.atan2(R[1, 0], R[0, 0])
    c = math.atan2(R[2, 1], R[2, 2])
    return tuple(Element(k, "const", expr=repr(v), text=f"{k}({v})") for k, v in (("rz", a), ("ry", b), ("rx", c)))


def _parse_platform(d: dict, geometry: dict):
    """``platform``: (dof, seed, attachments, workspace or None)."""
    plat = d.get("platform")
    if not isinstance(plat, dict):
        raise VjmError("platform: missing; give at least {dof: 3} or {dof: 6}")
    extra = set(plat) - set(PLATFORM_KEYS)
    if extra:
        raise VjmError(f"platform: unknown keys {sorted(extra)}; known: {list(PLATFORM_KEYS)}")
    dof = plat.get("dof")
    if dof not in (3, 6) or isinstance(dof, bool):
        raise VjmError(f"platform.dof must be 3 (translations) or 6, got {dof!r}")
    seed = plat.get("seed", [0.0] * dof)
    if not (isinstance(seed, list) and len(seed) in (3, 6) and all(isinstance(v, (int, float)) for v in seed)):
        raise VjmError("platform.seed must be x, y, z [, rx, ry, rz] (mm, rad)")
    if dof == 3 and len(seed) == 6 and any(seed[3:]):
        raise VjmError("platform.seed: a 3-dof platform only translates; its seed orientation must be zero")
    att = plat.get("attachments") or {}
    if not isinstance(att, dict):
        raise VjmError("platform.attachments must be a mapping name -> list of constant transforms")
    attachments = tuple((str(k), _constants(v, geometry, f"platform.attachments.{k}")) for k, v in att.items())
    ws = plat.get("workspace")
    if ws is not None:
        try:
            ws = np.asarray(ws, dtype=float)
        except (TypeError, ValueError):
            ws = None
        if ws is None or ws.shape != (2, 3) or not np.all(ws[0] < ws[1]):
            raise VjmError("platform.workspace must be [[xmin, ymin, zmin], [xmax, ymax, zmax]] in mm")
        ws = tuple(map(tuple, ws.tolist()))
    return dof, seed, attachments, ws


def _chain_elements(name: str, tr, geometry: dict, link_names, used: set):
    """A chain's elements and the role of each coordinate; the links its springs use go into ``used``."""
    if not isinstance(tr, list) or not tr:
        raise VjmError(f"chain {name}: transforms must be a non-empty list of elements")
    els = tuple(parse_element(t, geometry, f"chain {name}, element {k + 1} {t!r}") for k, t in enumerate(tr))
    variables = {e.var for e in els if e.var}
    for k, e in enumerate(els):
        w = f"chain {name}, element {k + 1} {e.text!r}"
        if e.role == "spring":
            if e.link not in link_names:
                raise VjmError(f"{w}: no link {e.link!r}; links: {', '.join(sorted(link_names)) or 'none'}")
            if e.parallelogram and e.parallelogram[0] not in variables:
                raise VjmError(f"{w}: the parallelogram angle {e.parallelogram[0]!r} is no coordinate of the chain")
            used.add(e.link)
    roles: dict = {}
    for k, e in enumerate(els):
        if e.var and roles.setdefault(e.var, e.role) != e.role:
            raise VjmError(f"chain {name}, element {k + 1} {e.text!r}: coordinate {e.var!r} used with "
                           f"two roles ({roles[e.var]}, {e.role})")
    n_act = list(roles.values()).count("actuated")
    if n_act != 1:
        raise VjmError(f"chain {name}: needs exactly one actuated coordinate (e.g. 'Tx(q0) actuated'), "
                       f"has {n_act}")
    return els, roles


def _chain_seed_limits(name: str, c: dict, roles: dict, geometry: dict):
    """A chain's ``seed`` values and ``limits`` of its coordinates."""
    seed_v = c.get("seed") or {}
    if not isinstance(seed_v, dict):
        raise VjmError(f"chain {name}.seed must be a mapping coordinate -> value")
    sv = []
    for k, v in seed_v.items():
        if k not in roles:
            raise VjmError(f"chain {name}.seed: {k!r} is no coordinate of the chain")
        sv.append((str(k), evaluate(v, geometry, f"chain {name}.seed.{k}")))
    lim_raw = c.get("limits") or {}
    if not isinstance(lim_raw, dict):
        raise VjmError(f"chain {name}.limits must be a mapping coordinate -> [min, max]")
    limits = []
    for k, v in lim_raw.items():
        if k not in roles:
            raise VjmError(f"chain {name}.limits: {k!r} is no coordinate of the chain")
        if not (isinstance(v, list) and len(v) == 2):
            raise VjmError(f"chain {name}.limits.{k} must be [min, max]")
        lo, hi = (evaluate(x, geometry, f"chain {name}.limits.{k}") for x in v)
        if not lo < hi:
            raise VjmError(f"chain {name}.limits.{k}: min must be below max")
        limits.append((str(k), lo, hi))
    return tuple(sv), tuple(limits)


def _chain_copies(name: str, copies, geometry: dict, els, sv, attach: str, limits) -> list:
    """The chains a ``copies`` entry makes (by rotation or permutation of the axes)."""
    if not isinstance(copies, dict) or set(copies) - {"rotate", "permute", "count", "names"} \
            or ("rotate" in copies) == ("permute" in copies):
        raise VjmError(f"chain {name}.copies: expected {{rotate: [transforms] | permute: [y, z, x], count: N, "
                       f"names: [...]}}")
    count = copies.get("count")
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_COPIES:
        raise VjmError(f"chain {name}.copies.count must be an integer in [1, {MAX_COPIES}], got {count!r}")
    S = (_constants(copies["rotate"], geometry, f"chain {name}.copies.rotate") if "rotate" in copies
         else _permutation(copies["permute"], f"chain {name}.copies"))
    names = copies.get("names") or [f"{name}_{k + 1}" if k else name for k in range(count)]
    if not isinstance(names, list) or len(names) != count:
        raise VjmError(f"chain {name}.copies.names must list {count} names")
    return [ChainSpec(str(names[k]), els, sv, S, k, attach, limits) for k in range(count)]


def _parse_chain(i: int, c, geometry: dict, link_names, attachments, used: set) -> list:
    """``chains[i]`` -> its ChainSpec (several with ``copies``)."""
    if not isinstance(c, dict) or "name" not in c or "transforms" not in c:
        raise VjmError(f"chains[{i}]: a chain is a mapping with name and transforms")
    name = str(c["name"])
    extra = set(c) - set(CHAIN_KEYS)
    if extra:
        raise VjmError(f"chain {name}: unknown keys {sorted(extra)}; known: {list(CHAIN_KEYS)}")
    els, roles = _chain_elements(name, c["transforms"], geometry, link_names, used)
    sv, limits = _chain_seed_limits(name, c, roles, geometry)
    attach = c.get("platform", "")
    if attach and attach not in dict(attachments):
        raise VjmError(f"chain {name}: platform attachment {attach!r} is not in platform.attachments")
    copies = c.get("copies")
    if copies is None:
        return [ChainSpec(name, els, sv, attach=attach or "", limits=limits)]
    return _chain_copies(name, copies, geometry, els, sv, attach or "", limits)


def parse_description(d: dict, geometry: dict, link_names) -> Description:
    """The ``platform``, ``links`` and ``chains`` of a description file -> Description."""
    dof, seed, attachments, ws = _parse_platform(d, geometry)
    chains_raw = d.get("chains")
    if not isinstance(chains_raw, list) or not chains_raw:
        raise VjmError("chains: expected a list of chains, each {name, transforms}")
    chains: list = []
    used: set = set()
    for i, c in enumerate(chains_raw):
        chains += _parse_chain(i, c, geometry, link_names, attachments, used)
    seen = set()
    for c in chains:
        if c.name in seen:
            raise VjmError(f"chain {c.name}: two chains have this name")
        seen.add(c.name)
    raw = {k: d[k] for k in ("platform", "links", "chains") if k in d}
    return Description(dof, tuple(float(v) for v in seed), attachments, tuple(chains), ws, tuple(sorted(used)), raw)


def seed_frame(desc: Description) -> np.ndarray:
    from ..kinematics.poses import as_poses
    return as_poses(np.asarray(desc.seed), 6)[0]
