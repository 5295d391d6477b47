"""A calibration written back: the calibrated URDF (or DH table), and the robot file with the joint stiffnesses found.

The URDF is the source URDF with, for every joint the calibration corrected, its ``<origin>`` times the
correction ``exp(origin error) Rot(axis, offset)`` (a joint offset is a turn of the origin about the
joint's own axis, which commutes with the joint's motion), and each marker as a fixed link
``<frame>_marker`` on its measured frame (one per measured point: a marker on each hand).  Everything else (inertials, limits, meshes) is kept as written.
The robot file beside it names that URDF and carries everything the source model file states (``home:``, tools,
gravity, joint and link springs, added masses, payload, payload limit), each value the fit identified in place of
the nominal one.  The fit corrects the source model (:mod:`vjm.calibration.nominal`): a fitted ``<joint>.compliance``
``dc`` is a correction, and the file writes the joint's *total* stiffness ``1 / (1/k + dc)`` (N mm/rad, the robot
file's unit; a table's knots or an expression corrected alike), rounded at the second significant digit of its
standard deviation, the source's value and the correction in a comment; the payload likewise (the source's mass plus
the fitted one).  A joint not identified keeps its nominal stiffness, with a comment saying why.

A source written as a DH table is written back as a DH table (``calibrated.yaml`` alone, :func:`calibrated_files`):
the same convention and rows re-fitted to the calibrated kinematics (:func:`calibrated_dh`), the markers as
``frames:`` of the table.  Loaded back, vjm and pinocchio reproduce the calibrated positions;
:func:`calibrated_model` is that file's model in memory, the same rounded values in it.
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Callable

import numpy as np

from ..errors import VjmError
from ..kinematics.transforms import elementary
from ..robot.model import RobotModel
from ..robot.tree import _rigid_inverse, origin_transform
from .nominal import nominal_values
from .serial import GEOMETRY, _delta, rotation_matrix

MM = 1000.0


def rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of a rotation matrix (``R = Rz(y) Ry(p) Rx(r)``)."""
    p = float(np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0])))
    if np.hypot(R[0, 0], R[1, 0]) < 1e-12:   # gimbal lock: put the whole turn in the roll
        return float(np.arctan2(-R[1, 2], R[1, 1])), p, 0.0
    return float(np.arctan2(R[2, 1], R[2, 2])), p, float(np.arctan2(R[1, 0], R[0, 0]))


def corrections(cal) -> dict:
    """{joint name: 4x4 correction (mm) right-multiplying its URDF origin} of the fitted geometry."""
    out = {}
    for j in cal.model.tree.joints:
        d = np.array([cal.values.get(f"{j.name}.{k}", 0.0) for k in GEOMETRY])
        if not np.any(d):
            continue
        turn = elementary(j.kind, np.array([d[0]]))[0]
        if j.align is not None:
            turn = j.align @ turn @ _rigid_inverse(j.align)
        out[j.name] = _delta(d[1:]) @ turn
    return out


def _fmt(v) -> str:
    return " ".join(repr(float(x)) for x in v)


def calibrated_urdf(cal, urdf_path) -> str:
    """The text of the calibrated URDF (see the module docstring)."""
    try:
        tree = ET.parse(urdf_path)
    except (OSError, ET.ParseError) as e:
        raise VjmError(f"{urdf_path}: cannot read the URDF ({e})") from None
    root = tree.getroot()
    joints = {j.get("name"): j for j in root.findall("joint") if j.get("name")}   # not <transmission>'s
    for name, K in corrections(cal).items():
        if name not in joints:
            raise VjmError(f"{urdf_path}: no joint {name!r} (the calibrated model's)")
        el = joints[name].find("origin")
        if el is None:
            el = ET.SubElement(joints[name], "origin")
        O = origin_transform([float(x) * MM for x in el.get("xyz", "0 0 0").split()],
                             [float(x) for x in el.get("rpy", "0 0 0").split()])
        N = O @ K
        el.set("xyz", _fmt(N[:3, 3] / MM))
        el.set("rpy", _fmt(rpy(N[:3, :3])))
    links = {x.get("name") for x in root.findall("link")}
    for frame, p in cal.markers.items():   # a fixed marker link per measured point (one on each hand ...)
        if frame not in links:
            raise VjmError(f"{urdf_path}: the measured frame {frame!r} is no link: the marker cannot be attached")
        ET.SubElement(root, "link", name=f"{frame}_marker")
        jm = ET.SubElement(root, "joint", name=f"{frame}_marker_joint", type="fixed")
        ET.SubElement(jm, "parent", link=frame)
        ET.SubElement(jm, "child", link=f"{frame}_marker")
        ET.SubElement(jm, "origin", xyz=_fmt(p / MM), rpy="0 0 0")
    return ET.tostring(root, encoding="unicode")


#: said once at the head of a calibrated robot file
UNITS = ("# Units: N, mm, kg, rad; gravity in m/s^2.  A joint's stiffness is in N mm/rad (N/mm for a prismatic\n"
         "# joint), the inverse of its compliance in rad/(N mm) (mm/N).\n")

#: fitted effects the robot file and the URDF have no place for (listed in the file's head, not carried)
_NOT_CARRIED = ("lateral", "bending", "varying", "alpha", "backlash", "guide_tilt_lower", "guide_tilt_upper",
                "column_tilt_lower", "column_tilt_upper", "link_scale")


class Rounded(float):
    """A fitted value rounded to its significant digits: the number, and its text as the file writes it."""

    text: str

    def __new__(cls, text: str):
        self = super().__new__(cls, float(text))
        self.text = text
        return self


def _float_text(v: float) -> str:
    """A float's text that YAML reads back as that float (a mantissa with a dot: ``1.0e-08``, not ``1e-08``)."""
    t = repr(float(v))
    return t.replace("e", ".0e") if "e" in t and "." not in t else t


def rounded(value: float, std: float | None, digits: int = 2) -> Rounded:
    """``value`` rounded at the ``digits``-th significant digit of its standard deviation ``std`` (so that the
    last digit kept is finer than ``std``) and at least at its own second significant digit (a value smaller
    than its uncertainty keeps its order of magnitude, not 0); in full where ``std`` is unknown."""
    v = float(value)
    if std is None or not np.isfinite(std) or std <= 0 or v == 0 or not np.isfinite(v):
        return Rounded(_float_text(v))
    mag = int(np.floor(np.log10(abs(v))))
    e = min(int(np.floor(np.log10(std))) - (digits - 1), mag - 1)   # the place of the last digit kept
    if e < 0 and 1e-3 <= abs(v) < 1e5:
        return Rounded(f"{v:.{-e}f}")
    return Rounded(f"{v:.{mag - e}e}")


def _spring_spec(js) -> dict:
    """A :class:`~vjm.robot.model.JointSpring` as a robot file states it."""
    if js.stiffness is not None:
        return {"stiffness": float(js.stiffness)}
    if js.table is not None:
        return {"stiffness": {"table": [[float(a), float(b)] for a, b in zip(*js.table)]}}
    return {"stiffness": str(js.expression)}


def _source_doc(model) -> dict:
    """The source robot file's mapping, its file paths made absolute (the calibrated file is written
    elsewhere); {} for a model not read from a file."""
    from ..modelio.robotwrite import absolute_paths

    if model.raw is None:
        return {}
    base = os.path.dirname(model.path) if model.path else os.path.dirname(model.tree.source)
    return absolute_paths(model.raw, base)


def _sd(s) -> str:
    return "no standard deviation" if s is None or not np.isfinite(s) else f"{s:.2g}"


def _total_spec(spec, dc: float, s) -> tuple[object, str, str] | None:
    """The stiffness entry (a robot file's) of a spring ``spec`` (its ``stiffness:``; None: the joint is rigid in the
    source) whose compliance is corrected by ``dc``: the total ``1 / (1/k + dc)`` -- a number (rounded at the
    fitted standard deviation ``s``), a table of the corrected knots, or the expression with the correction --,
    the total compliance's text and the stiffness' standard deviation's; None if the total is not > 0."""
    if dc == 0.0 and spec is not None:   # no correction: the source's entry as written
        return spec, "the source's", _sd(None if s is None or isinstance(spec, (str, dict)) else s * float(spec) ** 2)
    if spec is None or isinstance(spec, (int, float)):
        c = dc + (0.0 if spec is None else 1.0 / float(spec))
        if not c > 0:
            return None
        sk = None if s is None else s / c ** 2   # the stiffness' standard deviation, to first order
        return rounded(1.0 / c, sk), f"{c:.4g}", _sd(sk)
    if isinstance(spec, dict):   # a table: each knot's compliance corrected
        knots = [[float(a), 1.0 / float(b) + dc] for a, b in spec["table"]]
        if not all(c > 0 for _, c in knots):
            return None
        return {"table": [[a, float(f"{1.0 / c:.6g}")] for a, c in knots]}, "the table's, each knot", "its knots'"
    return f"1 / (1 / ({spec}) + {rounded(dc, s).text})", "the expression's", "its"


def _joints(cal, doc: dict) -> dict:
    """{joint: (its robot file entry, comment)}: where the fit corrected a joint's compliance, the total's stiffness
    (the source's compliance plus the fitted correction; rounded, with the correction's standard deviation) in place
    of the source's; a joint the fit did not identify keeps the source's entry."""
    src = cal.model
    declared = doc.get("joints") or {}
    why = {n: w for n, w in cal.removed}
    kinds = {j.name: j.kind for j in src.tree.joints}
    out = {}
    for name in list(src.q_names) + [n for n in declared if n not in src.q_names]:
        spec = declared.get(name)
        if spec is None and not doc and name in src.joint_springs:   # a model built in memory
            spec = _spring_spec(src.joint_springs[name])
        ku, cu = ("N/mm", "mm/N") if kinds.get(name, "r")[0] == "t" else ("N mm/rad", "rad/(N mm)")
        key = f"{name}.compliance"
        dc, s = cal.values.get(key), cal.std.get(key)
        total = None if dc is None else _total_spec((spec or {}).get("stiffness"), dc, s)
        if total is not None:
            c0 = nominal_values(src, [key])[key]
            out[name] = ({**(spec or {}), "stiffness": total[0]},
                         f"fitted: +- {total[2]} {ku}; total compliance {total[1]} {cu} = the source's {c0:.4g} + the "
                         f"fitted correction {rounded(dc, s).text} +- {_sd(s)}")
        elif spec is not None:
            reason = (why[key] if key in why else f"the total of its fitted correction {dc:.3g} {cu} is not > 0"
                      if dc is not None else "its compliance was not fitted")
            out[name] = (spec, f"not identified ({reason}): the source model's value")
    return out


def _gravity(cal) -> tuple[list, str | None]:
    """The gravity (m/s^2, base frame): the source's, turned by the base tilt where one was fitted."""
    g = np.asarray(cal.model.gravity, dtype=float)
    tilt = [f"base.tilt_r{a}" for a in "xy"]
    if not any(k in cal.values for k in tilt):
        return [float(x) for x in g], None
    w = [cal.values.get(k, 0.0) for k in tilt]
    s = [cal.std.get(k) for k in tilt if k in cal.values]
    sg = None if any(x is None for x in s) else float(np.linalg.norm(g)) * max(s)
    return ([rounded(x, sg) for x in rotation_matrix([w[0], w[1], 0.0]) @ g],
            "turned by the fitted base tilt: " + ", ".join(f"{k.split('.')[1]} = {cal.values[k]:.3g} +- "
                                                           f"{_sd(cal.std.get(k))} rad" for k in tilt if k in cal.values))


def _payload(cal, doc: dict) -> tuple[dict | None, str | None]:
    """The payload: the source's plus the fitted correction (kg) at the first measured point, one point mass where
    both ride on the same link (at their common centre of mass, in the measured frame); else the source's."""
    src = cal.model
    nominal = doc.get("payload")
    if nominal is None and not doc and src.payload is not None:
        p = src.payload
        nominal = {"frame": p.frame, "mass": float(p.mass), "com": [float(x) for x in p.com]}
    m, s = cal.values.get("payload.mass"), cal.std.get("payload.mass")
    if m is None:
        return nominal, None if nominal is None else "not identified (the payload was not fitted): the source model's"
    pl = src.payload
    m0 = 0.0 if pl is None else float(pl.mass)
    if not m0 + m > 0:
        return nominal, f"not identified (the source's {m0:.3g} kg plus the fitted correction {m:.3g} kg is not > 0)" \
            + (": the source model's" if nominal is not None else "")
    tree = src.tree
    here = tree.frame(cal.frame)
    if pl is not None and m0 > 0 and tree.frame(pl.frame).joint != here.joint:
        return nominal, (f"the source model's; the fitted correction {m:.3g} +- {_sd(s)} kg at the measured point of "
                         f"{cal.frame} is not carried (the payload rides on another link)")
    com = np.asarray(cal.p0, dtype=float) * m
    if pl is not None and m0 > 0:   # the source's payload, in the measured frame
        P = _rigid_inverse(here.placement) @ tree.frame(pl.frame).placement
        com = com + m0 * (P[:3, :3] @ np.asarray(pl.com, dtype=float) + P[:3, 3])
    return ({"frame": cal.frame, "mass": rounded(m0 + m, s), "com": [float(x) for x in com / (m0 + m)]},
            f"fitted: total {m0 + m:.4g} kg = the source's {m0:.4g} + the fitted correction {rounded(m, s).text} +- "
            f"{_sd(s)} kg at the measured point of {cal.frame}")


def calibrated_mapping(cal, urdf_name: str | None) -> tuple[dict, dict]:
    """The calibrated robot file's mapping and its comments ({key or joints.<name>: text}): the source model
    file's every entry (tools, gravity, home, joint and link springs, added masses, payload, payload limit), the
    fitted values in place of the nominal ones where identified (:class:`Rounded`; a compliance or a payload as
    the total, the source's plus the fitted correction), the URDF ``urdf_name`` -- or, for a source written as a
    DH table, the table re-fitted to the calibrated kinematics (:func:`calibrated_dh`) -- and the markers as
    the first tools."""
    src = cal.model
    doc = _source_doc(src)
    markers = [f"{f}_marker" for f in cal.markers]
    d: dict = {"name": f"{src.name or 'robot'} (calibrated)"}
    move: Callable[[str], np.ndarray] | None = None
    if is_dh(src):
        d["dh"], move = calibrated_dh(cal)
    else:
        d["urdf"] = urdf_name
    d["tools"] = markers + [t for t in src.tools if t not in markers]
    notes: dict = {}
    d["gravity"], notes["gravity"] = _gravity(cal)
    if "strict_limits" in doc:
        d["strict_limits"] = doc["strict_limits"]
    if src.home is not None:
        d["home"] = [float(x) for x in src.home]
    joints = _joints(cal, doc)
    if joints:
        d["joints"] = {n: spec for n, (spec, _) in joints.items()}
        notes.update({f"joints.{n}": text for n, (_, text) in joints.items()})
    if doc.get("links"):   # the fit deflected them as the source states them (vjm.calibration.nominal)
        d["links"] = doc["links"] if move is None else {k: _moved_entry(v, move) for k, v in doc["links"].items()}
        notes["links"] = "as the source model states them (not fitted; the calibration deflects them)"
    if doc.get("masses"):
        d["masses"] = doc["masses"] if move is None else {k: _moved_com(v, move(k)) for k, v in doc["masses"].items()}
        notes["masses"] = "as the source model states them (not fitted)"
    payload, notes["payload"] = _payload(cal, doc)
    if payload is not None:
        d["payload"] = payload if move is None else _moved_com(payload, move(str(payload["frame"])))
    if "payload_limit" in doc:
        d["payload_limit"] = doc["payload_limit"]
    return d, {k: v for k, v in notes.items() if v}


def is_dh(model) -> bool:
    """Whether a robot's model file holds a DH table (its calibration is written back as one)."""
    return isinstance(model.raw, dict) and "dh" in model.raw


def _origin(T: np.ndarray) -> dict:
    return {"xyz": [float(x) for x in T[:3, 3]], "rpy": list(rpy(T[:3, :3]))}


def _moved_entry(entry, move) -> dict:
    """A ``links:`` entry (at: frame, xyz, rpy) placed where it was on its link, in the re-fitted frame."""
    T = move(str(entry["at"])) @ origin_transform(entry.get("xyz", [0, 0, 0]), entry.get("rpy", [0, 0, 0]))
    return {**entry, **_origin(T)}


def _moved_com(entry, M: np.ndarray) -> dict:
    """A mass or payload entry (com in a frame) with its centre of mass where it was, in the re-fitted frame."""
    c = M[:3, :3] @ np.asarray(entry.get("com", [0, 0, 0]), dtype=float) + M[:3, 3]
    return {**entry, "com": [float(x) for x in c]}


def _frames_at(model, names, q: np.ndarray) -> dict:
    """{frame: its world frame (4, 4) at q (nq,)} of a robot's named frames (limits not checked)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {n: model.forward(q, n) for n in names}


def _row(source: dict, fitted: dict) -> dict:
    """A DH row: the source's name, type, limits and inertial, the fitted a, alpha, d, theta (and beta where
    the source has it or the fit needs it), in the order of :data:`vjm.modelio.dh.ROW_KEYS`."""
    from ..modelio.dh import ROW_KEYS

    new = {k: (0.0 if abs(v) < 1e-12 else v) for k, v in fitted.items()}   # round-off of the fit, not geometry
    if new.get("beta") == 0.0 and "beta" not in source:
        del new["beta"]
    return {k: new[k] if k in new else source[k] for k in ROW_KEYS if k in new or k in source}


def calibrated_dh(cal) -> tuple[dict, Callable[[str], np.ndarray]]:
    """The source's DH table re-fitted to the calibrated kinematics (:func:`vjm.modelio.dh.match_table`: the
    same convention and rows, new base, tool and row values, the joints' values meaning what they meant), each
    link's centre of mass where it was on its link, and each marker a ``frames:`` entry ``<frame>_marker`` on its
    measured frame; and ``move(frame)``, the 4x4 taking a point of the calibrated tree's ``frame`` into the
    re-fitted table's frame of that name (a DH link frame follows the calibrated axes)."""
    from ..modelio.dh import match_table, tree_from_dh
    from ..robot.model import RobotModel

    spec = cal.model.raw["dh"]
    cm = RobotModel(_corrected_tree(cal))
    lo, hi = cm.tree.limits
    lo, hi = np.where(np.isfinite(lo), lo, -np.pi), np.where(np.isfinite(hi), hi, np.pi)
    Q = lo + (hi - lo) * np.random.default_rng(0).random((48, cm.nq))
    table = {k: v for k, v in spec.items() if k != "frames"}
    if corrections(cal):   # the geometry corrected: the rows re-fitted (else the source's, as written)
        rows, B, Tt = match_table(spec, Q, _frames_at(cm, ["tool"], Q)["tool"])
        table["base"], table["tool"] = _origin(B), _origin(Tt)
        table["joints"] = [_row(r, new) for r, new in zip(spec["joints"], rows)]
    else:
        table["joints"] = [dict(r) for r in spec["joints"]]
    q0 = np.clip(np.zeros(cm.nq), lo, hi)
    names = [f.name for f in cm.tree.frames]
    old = _frames_at(cm, names, q0)
    refit = RobotModel(tree_from_dh(table))
    new = _frames_at(refit, [n for n in names if n in {f.name for f in refit.tree.frames}], q0)

    def move(frame: str) -> np.ndarray:
        return _rigid_inverse(new[frame]) @ old[frame] if frame in new else np.eye(4)

    for i, r in enumerate(table["joints"]):   # each link's centre of mass where the calibrated tree carries it
        if "com" in spec["joints"][i]:
            b = next(b for b in cm.tree.bodies if b.joint == i and b.name == cm.tree.joints[i].name)
            link = f"link{i + 1}"
            M = move(link) @ _rigid_inverse(cm.tree.frame(link).placement)
            r["com"] = [float(x) for x in M[:3, :3] @ np.asarray(b.com, dtype=float) + M[:3, 3]]
    marks = {}
    for f, p in cal.markers.items():
        T = move(f) @ origin_transform(np.asarray(p, dtype=float), [0, 0, 0])
        marks[f"{f}_marker"] = {"at": f, **_origin(T)}
    for n, e in (spec.get("frames") or {}).items():
        marks.setdefault(n, {**e, **_origin(move(str(e["at"])) @ origin_transform(e.get("xyz", [0, 0, 0]),
                                                                                   e.get("rpy", [0, 0, 0])))})
    if marks:
        table["frames"] = marks
    return table, move


def _dumper():
    import yaml

    class Dumper(yaml.SafeDumper):
        pass

    Dumper.add_representer(Rounded, lambda dumper, v: dumper.represent_scalar("tag:yaml.org,2002:float", v.text))
    return Dumper


def _yaml(d) -> str:
    """YAML block style, its collections of scalars in flow style on one line."""
    import yaml

    return yaml.dump(d, Dumper=_dumper(), sort_keys=False, default_flow_style=None, width=1 << 30)


def robot_file(cal, urdf_name: str | None) -> str:
    """The robot file (YAML text) naming the calibrated URDF: :func:`calibrated_mapping`, each fitted value
    with its standard deviation and each joint not identified with why, as comments."""
    d, notes = calibrated_mapping(cal, urdf_name)
    what = "DH table" if urdf_name is None else "URDF"
    head = (f"# Calibrated by vjm.calibration.engine from absolute poses: the calibrated {what} and everything the\n"
            "# source model file states, each value the fit identified in place of the source's, rounded at the\n"
            "# second significant digit of its standard deviation (given beside it, +-); a joint \"not identified\"\n"
            "# keeps the source's value.  The fit corrects the source model: a joint's stiffness and the payload\n"
            "# here are the totals (the source's value plus the fitted correction, both given beside it).\n" + UNITS)
    flex = {k: v for k, v in cal.values.items() if k.rsplit(".", 1)[-1] in _NOT_CARRIED or ".coupling[" in k}
    if flex:   # fitted, but neither the URDF nor the robot file has a place for them: said, not dropped silently
        head += ("# Fitted effects this file and the URDF do not carry (vjm.calibration.flex, vjm.calibration.serial units):\n"
                 + "".join(f"#   {k} = {v:.6g} +- {_sd(cal.std.get(k))}\n" for k, v in flex.items()))
    out, top = [], None
    for line in _yaml(d).splitlines():   # the comments beside the lines of the keys they are about
        if not line.startswith(" "):
            top = line.split(":", 1)[0]
            if top in notes:
                out.append(f"# {top}: {notes[top]}")
        elif top == "joints" and not line.startswith("   ") and f"joints.{line.split(':', 1)[0].strip()}" in notes:
            line += f"   # {notes['joints.' + line.split(':', 1)[0].strip()]}"
        out.append(line)
    return head + "\n".join(out) + "\n"


def calibrated_model(cal) -> RobotModel:
    """The calibrated robot in memory: the :class:`~vjm.robot.model.RobotModel` that calibrated.urdf and
    calibrated.yaml describe (:func:`calibrated_urdf`, :func:`robot_file`), built without writing them.

    Each corrected joint's placement times its correction (:func:`corrections`: the URDF origin times the
    correction, as the written URDF has it), a marker frame ``<frame>_marker`` (and its fixed joint's frame) on
    each measured frame, the markers first among the tools, and the rest as :func:`calibrated_mapping` has
    it: the fitted values as the file rounds them (so that this is the model the file says), the source's
    joint and link springs, added masses, payload, gravity and ``home:`` where nothing was identified.  A source
    written as a DH table gives the model of its calibrated table (:func:`calibrated_dh`), read as the file is.
    ``tree.source`` stays the source URDF: the corrections are in the tree, not in that file.  ``path`` and
    ``raw`` are None: no file holds it (:meth:`save` says so; write the files with :func:`write_calibrated`)."""
    src = cal.model
    d, notes = calibrated_mapping(cal, "calibrated.urdf")
    if is_dh(src):
        from dataclasses import replace

        from ..modelio.read import model_from_dict

        m = model_from_dict(d, os.path.dirname(os.path.abspath(src.path or ".")))
        assert isinstance(m, RobotModel)   # a dh: mapping is a robot's
        return replace(m, raw=None)
    from ..modelio.robotfile import _joint_spring
    from ..robot.model import JointSpring, Payload

    new = _corrected_tree(cal, d["tools"])
    springs = {}
    for n, spec in d.get("joints", {}).items():
        k = spec.get("stiffness")
        if isinstance(k, Rounded):   # fitted
            springs[n] = JointSpring(stiffness=float(k))
        elif k is not None and n in src.joint_springs and not notes.get(f"joints.{n}", "").startswith("fitted"):
            springs[n] = src.joint_springs[n]
        elif k is not None:   # a corrected table or expression
            springs[n] = _joint_spring(k, f"joints.{n}.stiffness")
    carried = src.raw is not None   # a model built in memory has no file entries for its 6x6 and link springs
    pl = d.get("payload")
    payload = None if pl is None else Payload(str(pl["frame"]), float(pl["mass"]),
                                              np.asarray(pl.get("com", [0, 0, 0]), dtype=float))
    home = d.get("home")
    return RobotModel(new, springs, dict(src.joint6) if carried else {}, dict(src.links) if carried else {},
                      payload, tuple(float(g) for g in d["gravity"]), d["name"],
                      strict_limits=bool(d.get("strict_limits", False)),
                      home=None if home is None else tuple(home))


def _corrected_tree(cal, tools=None):
    """The source's tree with each corrected joint's placement times its correction (:func:`corrections`: the URDF
    origin times the correction, as the written URDF has it) and a marker frame ``<frame>_marker`` (and its fixed
    joint's frame) on each measured frame; ``tools`` (default the source's)."""
    from dataclasses import replace

    from ..robot.tree import Frame, Tree

    tree = cal.model.tree
    fix = corrections(cal)
    joints = tuple(replace(j, placement=j.placement @ fix[j.name]) if j.name in fix else j for j in tree.joints)
    frames = list(tree.frames)
    for frame, p in cal.markers.items():
        f = tree.frame(frame)
        P = f.placement.copy()
        P[:3, 3] += P[:3, :3] @ np.asarray(p, dtype=float)
        frames += [Frame(f"{frame}_marker_joint", f.joint, P), Frame(f"{frame}_marker", f.joint, P.copy())]
    return Tree(tree.name, joints, tuple(frames), tree.bodies, tuple(tools or tree.tools), tree.source, tree.declared)


def write_calibrated(cal, urdf_path, out_urdf, out_yaml) -> None:
    """Write the calibrated URDF and its robot file; an existing file is never overwritten."""
    from linkfea.files.atomic import atomic_path

    for p in (out_urdf, out_yaml):
        if os.path.lexists(p):
            raise VjmError(f"{p}: exists; choose a new name (a calibration never overwrites a file)")
    texts = ((out_urdf, calibrated_urdf(cal, urdf_path)),
             (out_yaml, robot_file(cal, os.path.relpath(out_urdf, os.path.dirname(os.path.abspath(out_yaml))))))
    for p, text in texts:
        with atomic_path(p) as tmp:
            with open(tmp, "w") as f:
                f.write(text)


def calibrated_files(cal) -> dict:
    """{file name: text} of a calibration written back: ``calibrated.urdf`` (the source's URDF corrected) and
    ``calibrated.yaml`` naming it; for a source written as a DH table, ``calibrated.yaml`` alone, its table
    re-fitted."""
    if is_dh(cal.model):
        return {"calibrated.yaml": robot_file(cal, None)}
    return {"calibrated.urdf": calibrated_urdf(cal, cal.model.tree.source),
            "calibrated.yaml": robot_file(cal, "calibrated.urdf")}


def writable(model) -> bool:
    """Whether a robot's calibration can be written back: its source is a URDF file or a DH table read from a file."""
    urdf = model.tree.source
    return is_dh(model) or bool(urdf and os.path.isfile(urdf))


def calibrated_commands(cal, targets, seed) -> str:
    """commands.csv of a calibration (``--targets`` of ``vjm calibrate`` and ``vjm diagnose``): the compensation
    of the ``targets`` file (:func:`vjm.robot.compensate.compensate_file`) on the calibrated model
    (:func:`calibrated_model`), its first tool (the first measured point's marker) as the tool; its first line
    names calibrated.yaml, the file of that model in the same output set."""
    from ..robot.compensate import TOL, compensate_file

    m = calibrated_model(cal)
    return compensate_file(m, targets, seed, m.tools[0], None, TOL, model_file="calibrated.yaml")[1]
