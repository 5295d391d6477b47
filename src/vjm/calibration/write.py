"""A calibration written back: the calibrated URDF, and the robot file with the joint stiffnesses found.

The URDF is the source URDF with, for every joint the calibration corrected, its ``<origin>`` times the
correction ``exp(origin error) Rot(axis, offset)`` (a joint offset is a turn of the origin about the
joint's own axis, which commutes with the joint's motion), and each marker as a fixed link
``<frame>_marker`` on its measured frame (one per measured point: a marker on each hand).  Everything else (inertials, limits, meshes) is kept as written.
The robot file beside it names that URDF and carries everything the source model file states (``home:``, tools,
gravity, joint and link springs, added masses, payload, payload limit), each value the fit identified in place of
the nominal one: a fitted compliance ``c`` as the joint's stiffness ``1 / c`` (N mm/rad, the robot file's unit),
rounded at the second significant digit of its standard deviation, which a comment gives; a joint not identified
keeps its nominal stiffness, with a comment saying why.  Loaded back, vjm and pinocchio reproduce the calibrated
positions; :func:`calibrated_model` is that file's model in memory, the same rounded values in it.
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET

import numpy as np

from ..errors import VjmError
from ..kinematics.transforms import elementary
from ..robot.model import RobotModel
from ..robot.tree import _rigid_inverse, origin_transform
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


def _joints(cal, doc: dict) -> dict:
    """{joint: (its robot file entry, comment)}: a fitted compliance's stiffness (rounded, with its standard
    deviation) in place of the source's; a joint the fit did not identify keeps the source's entry."""
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
        c, s = cal.values.get(key), cal.std.get(key)
        if c is not None and c > 0:
            sk = None if s is None else s / c ** 2   # the stiffness' standard deviation, to first order
            out[name] = ({**(spec or {}), "stiffness": rounded(1.0 / c, sk)},
                         f"fitted: +- {_sd(sk)} {ku}; compliance {rounded(c, s).text} +- {_sd(s)} {cu}")
        elif spec is not None:
            reason = (why[key] if key in why else f"its fitted compliance {c:.3g} {cu} is not > 0" if c is not None
                      else "its compliance was not fitted")
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
    """The payload: the fitted mass (kg) at the first measured point where identified, else the source's."""
    src = cal.model
    nominal = doc.get("payload")
    if nominal is None and not doc and src.payload is not None:
        p = src.payload
        nominal = {"frame": p.frame, "mass": float(p.mass), "com": [float(x) for x in p.com]}
    m, s = cal.values.get("payload.mass"), cal.std.get("payload.mass")
    if m is not None and m > 0:
        return ({"frame": cal.frame, "mass": rounded(m, s), "com": [float(x) for x in cal.p0]},
                f"fitted: mass +- {_sd(s)} kg, at the measured point of {cal.frame}")
    if nominal is None:
        return None, None
    return nominal, ("not identified (" + (f"its fitted mass {m:.3g} kg is not > 0" if m is not None
                                           else "the payload was not fitted") + "): the source model's")


def calibrated_mapping(cal, urdf_name: str) -> tuple[dict, dict]:
    """The calibrated robot file's mapping and its comments ({key or joints.<name>: text}): the source model
    file's every entry (tools, gravity, home, joint springs, added masses, payload, payload limit; the link
    springs only as a comment of :func:`robot_file`: the fit takes the links as rigid),
    the fitted values in place of the nominal ones where identified (:class:`Rounded`), the URDF
    ``urdf_name`` and the markers as the first tools."""
    src = cal.model
    doc = _source_doc(src)
    markers = [f"{f}_marker" for f in cal.markers]
    d: dict = {"name": f"{src.name or 'robot'} (calibrated)", "urdf": urdf_name,
               "tools": markers + [t for t in src.tools if t not in markers]}
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
    if doc.get("masses"):
        d["masses"] = doc["masses"]
        notes["masses"] = "as the source model states them (not fitted)"
    # The fit takes the links as rigid (its torsional joint compliances absorb the links' sag under the
    # robot's weight): the source's link springs on top of them would count that sag twice, so they are
    # written as a comment (robot_file), not as springs of this model.
    payload, notes["payload"] = _payload(cal, doc)
    if payload is not None:
        d["payload"] = payload
    if "payload_limit" in doc:
        d["payload_limit"] = doc["payload_limit"]
    return d, {k: v for k, v in notes.items() if v}


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


def robot_file(cal, urdf_name: str) -> str:
    """The robot file (YAML text) naming the calibrated URDF: :func:`calibrated_mapping`, each fitted value
    with its standard deviation and each joint not identified with why, as comments."""
    d, notes = calibrated_mapping(cal, urdf_name)
    head = ("# Calibrated by vjm.calibration.engine from absolute poses: the calibrated URDF and everything the\n"
            "# source model file states, each value the fit identified in place of the source's, rounded at the\n"
            "# second significant digit of its standard deviation (given beside it, +-); a joint \"not identified\"\n"
            "# keeps the source's value.\n" + UNITS)
    links = _source_doc(cal.model).get("links")
    if links:
        head += ("# The source model's link springs, left out: the calibration takes the links as rigid and its joint\n"
                 "# compliances absorb their sag, so adding them back would count it twice:\n"
                 + "".join(f"#   {line}\n" for line in _yaml({"links": links}).splitlines()))
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
    springs (not its link springs: the fit takes the links as rigid), added masses, payload, gravity and ``home:`` where nothing was identified.
    ``tree.source`` stays the source URDF: the corrections are in the tree, not in that file.  ``path`` and
    ``raw`` are None: no file holds it (:meth:`save` says so; write the files with :func:`write_calibrated`)."""
    from dataclasses import replace

    from ..robot.model import JointSpring, Payload
    from ..robot.tree import Frame, Tree

    src = cal.model
    tree = src.tree
    fix = corrections(cal)
    joints = tuple(replace(j, placement=j.placement @ fix[j.name]) if j.name in fix else j for j in tree.joints)
    frames = list(tree.frames)
    for frame, p in cal.markers.items():
        f = tree.frame(frame)
        P = f.placement.copy()
        P[:3, 3] += P[:3, :3] @ np.asarray(p, dtype=float)
        frames += [Frame(f"{frame}_marker_joint", f.joint, P), Frame(f"{frame}_marker", f.joint, P.copy())]
    d, _ = calibrated_mapping(cal, "calibrated.urdf")
    new = Tree(tree.name, joints, tuple(frames), tree.bodies, tuple(d["tools"]), tree.source, tree.declared)
    springs = {}
    for n, spec in d.get("joints", {}).items():
        k = spec.get("stiffness")
        if isinstance(k, Rounded):   # fitted
            springs[n] = JointSpring(stiffness=float(k))
        elif k is not None:
            springs[n] = src.joint_springs[n]
    carried = src.raw is not None   # a model built in memory has no file entries for its 6x6 and link springs
    pl = d.get("payload")
    payload = None if pl is None else Payload(str(pl["frame"]), float(pl["mass"]),
                                              np.asarray(pl.get("com", [0, 0, 0]), dtype=float))
    home = d.get("home")
    return RobotModel(new, springs, dict(src.joint6) if carried else {}, {},
                      payload, tuple(float(g) for g in d["gravity"]), d["name"],
                      strict_limits=bool(d.get("strict_limits", False)),
                      home=None if home is None else tuple(home))


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


def calibrated_commands(cal, targets, seed) -> str:
    """commands.csv of a calibration (``--targets`` of ``vjm calibrate`` and ``vjm diagnose``): the compensation
    of the ``targets`` file (:func:`vjm.robot.compensate.compensate_file`) on the calibrated model
    (:func:`calibrated_model`), its first tool (the first measured point's marker) as the tool; its first line
    names calibrated.yaml, the file of that model in the same output set."""
    from ..robot.compensate import TOL, compensate_file

    m = calibrated_model(cal)
    return compensate_file(m, targets, seed, m.tools[0], None, TOL, model_file="calibrated.yaml")[1]
