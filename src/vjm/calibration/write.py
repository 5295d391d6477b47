"""A calibration written back: the calibrated URDF, and the robot file with the joint stiffnesses found.

The URDF is the source URDF with, for every joint the calibration corrected, its ``<origin>`` times the
correction ``exp(origin error) Rot(axis, offset)`` (a joint offset is a turn of the origin about the
joint's own axis, which commutes with the joint's motion), and each marker as a fixed link
``<frame>_marker`` on its measured frame (one per measured point: a marker on each hand).  Everything else (inertials, limits, meshes) is kept as written.
The robot file beside it names that URDF and gives each joint whose compliance was fitted its stiffness
``1 / c`` (N mm/rad): loaded back, vjm and pinocchio reproduce the calibrated positions.
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET

import numpy as np

from ..errors import VjmError
from ..kinematics.transforms import elementary
from ..robot.model import RobotModel
from ..robot.tree import _rigid_inverse, origin_transform
from .serial import GEOMETRY, _delta

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


def _robot_dict(cal, urdf_name: str) -> dict:
    """The mapping of the calibrated robot file: name, URDF, the markers as tools, gravity, fitted stiffnesses."""
    joints = {}
    for name in cal.model.q_names:
        c = cal.values.get(f"{name}.compliance")
        if c is not None and c > 0:
            joints[name] = {"stiffness": float(1.0 / c)}
    d: dict = {"name": f"{cal.model.name or 'robot'} (calibrated)", "urdf": urdf_name,
               "tools": [f"{f}_marker" for f in cal.markers], "gravity": [float(g) for g in cal.model.gravity]}
    if joints:
        d["joints"] = joints
    return d


def robot_file(cal, urdf_name: str) -> str:
    """The robot file (YAML text) naming the calibrated URDF, with the fitted joint stiffnesses."""
    import yaml

    d = _robot_dict(cal, urdf_name)
    head = ("# Calibrated by vjm.calibration.engine: joint stiffnesses (N mm/rad) fitted under self-weight;\n"
            "# the joints without one were rigid in the fit (not observable, or not fitted).\n")
    flex = {k: v for k, v in cal.values.items()
            if k.rsplit(".", 1)[-1] in ("lateral", "bending", "varying", "alpha", "backlash") or ".coupling[" in k}
    if flex:   # fitted, but neither the URDF nor the robot file has a place for them: said, not dropped silently
        head += ("# Fitted effects this file and the URDF do not carry (vjm.calibration.flex, vjm.calibration.serial units):\n"
                 + "".join(f"#   {k} = {v:.6g}\n" for k, v in flex.items()))
    return head + yaml.safe_dump(d, sort_keys=False)


def calibrated_model(cal) -> RobotModel:
    """The calibrated robot in memory: the :class:`~vjm.robot.model.RobotModel` that calibrated.urdf and
    calibrated.yaml describe (:func:`calibrated_urdf`, :func:`robot_file`), built without writing them.

    Each corrected joint's placement times its correction (:func:`corrections`: the URDF origin times the
    correction, as the written URDF has it), a marker frame ``<frame>_marker`` (and its fixed joint's frame) on
    each measured frame, the markers as the tools, the fitted joint stiffnesses, the source's gravity.  As the
    written robot file, it carries no added masses, link springs, payload or ``home:`` of the source model
    (their place is the source's file).  ``tree.source`` stays the source URDF: the corrections are in the
    tree, not in that file.  ``path`` and ``raw`` are None: no file holds it (:meth:`save` says so; write
    the files with :func:`write_calibrated`)."""
    from dataclasses import replace

    from ..robot.model import JointSpring
    from ..robot.tree import Frame, Tree

    src = cal.model
    tree = src.tree
    if (src.raw or {}).get("masses") and os.path.isfile(tree.source):
        from ..modelio.urdf import read_urdf  # the URDF's own bodies, without the robot file's added masses

        tree = read_urdf(tree.source, tree.tools)
    bodies = tree.bodies
    fix = corrections(cal)
    joints = tuple(replace(j, placement=j.placement @ fix[j.name]) if j.name in fix else j for j in tree.joints)
    frames = list(tree.frames)
    for frame, p in cal.markers.items():
        f = tree.frame(frame)
        P = f.placement.copy()
        P[:3, 3] += P[:3, :3] @ np.asarray(p, dtype=float)
        frames += [Frame(f"{frame}_marker_joint", f.joint, P), Frame(f"{frame}_marker", f.joint, P.copy())]
    d = _robot_dict(cal, "calibrated.urdf")
    new = Tree(tree.name, joints, tuple(frames), bodies, tuple(d["tools"]), tree.source, tree.declared)
    springs = {n: JointSpring(stiffness=v["stiffness"]) for n, v in d.get("joints", {}).items()}
    return RobotModel(new, springs, gravity=tuple(np.asarray(d["gravity"], dtype=float)), name=d["name"])


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
