"""Model files (YAML) out: the mapping of a :class:`vjm.Model` and the atomic write.

:mod:`vjm.modelio.read` reads what this writes (the format is described there).  This module
imports no :mod:`vjm.model.machine`, so that ``Model.save`` can call it.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np
import yaml

from linkfea.files.atomic import plain, write_text

from ..errors import VjmError
from ..model.links import LinkSpring


def _link_to_yaml(link: LinkSpring, out_dir: str):
    src = link.source
    if link.compliance is None:
        return {"rigid": True}
    if src and "linkfea" in src:
        return {"linkfea": os.path.relpath(src["linkfea"], out_dir)}
    if src and "beam" in src:
        return {"beam": dict(src["beam"])}
    if link.frame is not None:
        return {"compliance": np.asarray(link.compliance).tolist(), "frame": link.frame.to_dict()}
    return {"compliance": np.asarray(link.compliance).tolist()}


def model_to_dict(model, out_dir: str = ".") -> dict:
    """The mapping that :func:`model_from_dict` reads back to an equal model."""
    a = model.actuator
    if model.description is not None:
        out = {"name": model.name, "geometry": {k: float(v) for k, v in model.geometry.items()},
               "actuator": {"stiffness": float(a.stiffness), "compliance_slope": float(a.compliance_slope),
                            "q_ref": float(a.q_ref)}}
        for k in ("foot", "leg"):
            if k in model.links:
                out[k] = _link_to_yaml(model.links[k], out_dir)
        out["joints"] = {"passive_stiffness": model.joints.passive_stiffness}
        out["effects"] = plain(model.effects)
        raw = model.description.raw
        out["platform"] = plain(raw["platform"])
        others = {k: v for k, v in model.links.items() if k not in ("foot", "leg")}
        if others:
            out["links"] = {k: _link_to_yaml(v, out_dir) for k, v in others.items()}
        out["chains"] = plain(raw["chains"])
        return out
    return {
        "architecture": model.architecture,
        "name": model.name,
        "geometry": {k: float(v) for k, v in model.geometry.items()},
        "actuator": {"stiffness": float(a.stiffness), "compliance_slope": float(a.compliance_slope),
                     "q_ref": float(a.q_ref)},
        "foot": _link_to_yaml(model.foot, out_dir),
        "leg": _link_to_yaml(model.leg, out_dir),
        "joints": {"passive_stiffness": model.joints.passive_stiffness},
        "effects": plain(model.effects),
    }


HEADER = ("# vjm model file. Units: N, mm, rad; actuator stiffness N/mm (rotary: N mm/rad);\n"
          "# compliances 6x6 in each spring's frame, order Fx Fy Fz Mx My Mz, mm/N and rad/(N mm).\n"
          "# Spring frames: foot at the carriage (x along the actuator axis); leg at its distal end, x along it\n"
          "# (parallelogram legs: one bar, in its tip frame). See vjm.modelio.read for the format.\n")
#: the last line of a model file vjm wrote: the sha256 of the text above it (how a save knows its own file)
MARK = "# written by vjm; sha256 of the lines above: "
#: a model file larger than this is not looked into (not one vjm wrote)
OWN_MAX_BYTES = 50_000_000


#: the header of a robot's model file (its first line is HEADER's: how :func:`own_model_file` knows both)
ROBOT_HEADER = (HEADER.split("\n", 1)[0] + "\n"
                "# A serial or tree robot: a URDF (m, kg, converted to mm at the edge) or a DH table, its joint and\n"
                "# link springs, masses and payload in N, mm, kg, rad. See vjm.modelio.robotfile for the format.\n")


def model_file_text(doc: dict, header: str = HEADER) -> str:
    """The text of a model file holding mapping ``doc``: the header, the YAML, the checksum line."""
    body = header + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)
    return body + MARK + hashlib.sha256(body.encode("utf-8")).hexdigest() + "\n"


def own_model_file(path) -> bool:
    """Is ``path`` a model file vjm wrote, unchanged since?  A regular file (not a link) that starts with
    the header line and ends with the checksum line of the text above it."""
    p = Path(path)
    try:
        if p.is_symlink() or not p.is_file() or p.stat().st_size > OWN_MAX_BYTES:
            return False
        data = p.read_bytes()
    except OSError:
        return False
    body, _, last = data.rstrip(b"\n").rpartition(b"\n")
    body += b"\n"
    return (body.startswith(HEADER.split("\n", 1)[0].encode()) and last.startswith(MARK.encode())
            and last[len(MARK):].decode("ascii", "replace") == hashlib.sha256(body).hexdigest())


def check_model_out(path) -> None:
    """Refuse to replace, before any work, a file at ``path`` that vjm did not write (or that was edited
    since), a folder, and a symbolic link."""
    p = Path(path)
    if p.is_symlink():
        state = "" if p.exists() else ", which does not exist"
        raise VjmError(f"{p} is a symbolic link to {os.readlink(p)}{state}: a model is never saved through or "
                       f"over a link; give the real path or remove the link")
    if p.is_dir():
        raise VjmError(f"{p} is a folder: give a model file name such as {p / 'model.yaml'}")
    if p.exists() and not own_model_file(p):
        raise VjmError(f"{p} exists and is not a model file vjm wrote (or it was changed since: its last line is "
                       f"not the checksum of the text above); it is never overwritten: choose another name or move it")


def save_model(model, path) -> None:
    """Write ``model`` as YAML (atomic: temporary file, then os.replace); round-trips with load_model.

    An existing file at ``path`` is replaced only if vjm wrote it and it is unchanged since
    (:func:`own_model_file`); anything else (your ``notes.txt``, a model file you edited) is refused."""
    if getattr(model, "kind", "") == "serial":  # a robot writes its own mapping (vjm.modelio.robotwrite)
        model.save(path)
        return
    path = os.path.abspath(os.fspath(path))
    check_model_out(path)
    write_text(path, model_file_text(model_to_dict(model, os.path.dirname(path))))
