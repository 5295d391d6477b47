"""Model files (YAML) out: the mapping of a :class:`vjm.Model` and the atomic write.

:mod:`vjm.modelfile` reads what this writes (the format is described there).  This module
imports no :mod:`vjm.model`, so that ``Model.save`` can call it.
"""
from __future__ import annotations

import os

import numpy as np
import yaml

from linkfea.atomic import plain, write_text

from .links import LinkSpring


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
          "# (parallelogram legs: one bar, in its tip frame). See vjm.modelfile for the format.\n")


def save_model(model, path) -> None:
    """Write ``model`` as YAML (atomic: temporary file, then os.replace); round-trips with load_model."""
    path = os.path.abspath(os.fspath(path))
    out_dir = os.path.dirname(path)
    text = HEADER + yaml.safe_dump(model_to_dict(model, out_dir), sort_keys=False, default_flow_style=None)
    write_text(path, text)
