"""Model files (YAML) in and out, validated.

Format (units N, mm, rad; compliances in mm/N, rad/(N mm), order Fx Fy Fz Mx My Mz)::

    architecture: orthoglide-3PUU     # | orthoglide-3PRPaR | delta-3RRPaR
    name: free text
    geometry: {L: 310, r: 50, d: 80}  # mm (delta also R: base radius, arm: arm length)
    actuator:
      stiffness: 3660                 # N/mm (prismatic) or N mm/rad (rotary)
      compliance_slope: 0             # optional, (mm/N)/mm: c(q) = 1/stiffness + slope (q - q_ref)
      q_ref: 0                        # optional, mm (rad)
    foot: <link>                      # spring frames: see vjm.models.orthoglide / delta
    leg: <link>
    joints: {passive_stiffness: null} # optional, N mm/rad: elastic passive joints
    effects: {}                       # optional: fitted additive effects of the discrepancy workflow,
                                      # e.g. {gravity: {weight: 12.0}}, checked against its effect library

``<link>`` is exactly one of::

    {rigid: true}
    {compliance: [[...6 numbers...], ... 6 rows]}            # in the spring frame
    {beam: {section: rect, width: 40, height: 20, length: 310, material: steel, shear: true}}
           # section: rect (width along y, height along z) | circle (diameter) |
           # tube (diameter, inner_diameter); material: name, or E (MPa) and nu
    {linkfea: path/to/result.json}    # output of `linkfea compute`, path relative to this file

A beam is a cantilever clamped at its base, its compliance taken in its tip
frame (x along the beam): eq. 14 plus Timoshenko shear unless ``shear: false``.
A linkfea result's reference frame (origin at the tip interface, x along
the link) is taken as the spring frame.
"""
from __future__ import annotations

import json
import os

import numpy as np
import yaml

from linkfea.atomic import plain, write_text
from linkfea.checks import did_you_mean

from .description import parse_description
from .errors import VjmError
from .model import Actuator, Joints, Link, Model, validate_compliance
from .models import ARCHITECTURES
from .models.described import NAME as DESCRIBED
from .resources import data_file

#: ``calibration``: the covariance vjm diagnose writes with model_updated.yaml (read by vjm path, not by the Model)
TOP_KEYS = ("architecture", "name", "geometry", "actuator", "foot", "leg", "joints", "effects", "calibration")
#: keys of a machine description (vjm.description), besides TOP_KEYS
DESCRIPTION_KEYS = ("platform", "links", "chains")
LINK_KINDS = ("rigid", "compliance", "beam", "linkfea")


def _num(v, key: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise VjmError(f"{key} must be a finite number, got {v!r}")
    return float(v)


def beam_compliance(spec: dict, key: str = "beam") -> np.ndarray:
    """Cantilever compliance (tip frame) from a ``beam:`` mapping, via linkfea.beam."""
    from linkfea import beam as lb
    from linkfea.errors import LinkFeaError
    from linkfea.materials import get_material

    if not isinstance(spec, dict):
        raise VjmError(f"{key} must be a mapping (section, length, material ...)")
    known = {"section", "width", "height", "diameter", "inner_diameter", "length", "material", "E", "nu", "shear"}
    extra = set(spec) - known
    if extra:
        raise VjmError(f"{key}: unknown keys {sorted(extra)}; known: {sorted(known)}")
    try:
        if "material" in spec:
            mat = get_material(spec["material"])
            E, nu = mat.E, mat.nu
        elif "E" in spec and "nu" in spec:
            E, nu = _num(spec["E"], f"{key}.E"), _num(spec["nu"], f"{key}.nu")
        else:
            raise VjmError(f"{key}: give a material name or E (MPa) and nu")
        if "length" not in spec:
            raise VjmError(f"{key}.length is missing (mm)")
        length = _num(spec["length"], f"{key}.length")
        sec = spec.get("section")
        g = lambda k: _num(spec.get(k), f"{key}.{k}")  # noqa: E731
        if sec == "rect":
            s = lb.rect_section(g("width"), g("height"), nu)
        elif sec == "circle":
            s = lb.circle_section(g("diameter"), nu)
        elif sec == "tube":
            s = lb.tube_section(g("diameter"), g("inner_diameter"), nu)
        else:
            raise VjmError(f"{key}.section must be rect, circle or tube, got {sec!r}")
        return lb.cantilever_compliance(length, s, E, nu, shear=bool(spec.get("shear", True)))
    except LinkFeaError as exc:
        raise VjmError(f"{key}: {exc}") from None


def read_linkfea(path: str, key: str = "linkfea") -> np.ndarray:
    """The 6x6 compliance of a ``linkfea compute`` result (JSON), validated."""
    if not os.path.isfile(path):
        raise VjmError(f"{key}: file not found: {path}")
    C = None
    try:
        from linkfea import io as lio  # written alongside; optional here
        reader = getattr(lio, "read_result", None)
    except ImportError:
        reader = None
    if reader is not None:
        try:
            res = reader(path)
            C = res["compliance"] if isinstance(res, dict) else getattr(res, "compliance", None)
        except Exception as exc:  # any reader failure is a bad file for the user
            raise VjmError(f"{key}: cannot read {path}: {exc}") from None
    if C is None:
        try:
            with open(path, encoding="utf-8") as fh:
                data = json.load(fh)
        except (OSError, ValueError) as exc:
            raise VjmError(f"{key}: cannot read {path} as JSON: {exc}") from None
        if not isinstance(data, dict) or "compliance" not in data:
            raise VjmError(f"{key}: {path} has no 'compliance' key (expected a `linkfea compute` result)")
        C = data["compliance"]
    return validate_compliance(C, f"{key} ({path})")


def parse_link(spec, key: str, base_dir: str) -> Link:
    """One ``foot:`` / ``leg:`` entry -> Link (VjmError names ``key``)."""
    if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in LINK_KINDS:
        raise VjmError(f"{key} must be exactly one of: {{rigid: true}}, {{compliance: 6x6}}, {{beam: ...}}, "
                       f"{{linkfea: path}}; got {spec!r}")
    kind, val = next(iter(spec.items()))
    if kind == "rigid":
        if val is not True:
            raise VjmError(f"{key}.rigid must be true")
        return Link.rigid()
    if kind == "compliance":
        return Link(validate_compliance(val, f"{key}.compliance"), None)
    if kind == "beam":
        return Link(validate_compliance(beam_compliance(val, f"{key}.beam"), f"{key}.beam"), {"beam": dict(val)})
    if not isinstance(val, str):
        raise VjmError(f"{key}.linkfea must be a file path")
    path = os.path.normpath(os.path.join(base_dir, val))
    return Link(read_linkfea(path, f"{key}.linkfea"), {"linkfea": os.path.abspath(path)})


def model_from_dict(d: dict, base_dir: str = ".", path: str | None = None) -> Model:
    """Build a validated Model from the mapping of a model file."""
    if not isinstance(d, dict):
        raise VjmError("a model file must be a YAML mapping")
    described = "chains" in d or d.get("architecture") == DESCRIBED
    known = TOP_KEYS + DESCRIPTION_KEYS if described else TOP_KEYS
    extra = set(d) - set(known)
    if extra:
        raise VjmError(f"unknown top-level keys {sorted(extra)}; known: {list(known)}")
    if described:
        return _described_from_dict(d, base_dir, path)
    for k in ("architecture", "geometry", "actuator", "foot", "leg"):
        if k not in d:
            raise VjmError(f"{k}: missing (required keys: architecture, geometry, actuator, foot, leg)")
    arch = d["architecture"]
    if arch not in ARCHITECTURES:
        raise VjmError(f"architecture: unknown {arch!r}; known: {', '.join(ARCHITECTURES)}")
    geo = d["geometry"]
    if not isinstance(geo, dict):
        raise VjmError("geometry must be a mapping of lengths in mm")
    keys = ARCHITECTURES[arch].geometry_keys
    for k in geo:
        if k not in keys:
            raise VjmError(f"geometry.{k}: unknown key for {arch}{did_you_mean(str(k), keys)}; "
                           f"its geometry is {', '.join(keys)} (mm)")
    geo = {k: _num(v, f"geometry.{k}") for k, v in geo.items()}
    act = d["actuator"]
    if not isinstance(act, dict) or "stiffness" not in act:
        raise VjmError("actuator must be a mapping with at least 'stiffness'")
    extra = set(act) - {"stiffness", "compliance_slope", "q_ref"}
    if extra:
        raise VjmError(f"actuator: unknown keys {sorted(extra)}")
    actuator, jo, effects = _common(d)
    return Model(arch, geo, actuator, parse_link(d["foot"], "foot", base_dir), parse_link(d["leg"], "leg", base_dir),
                 jo, dict(effects), str(d.get("name", "")), path)


def _common(d: dict):
    """Actuator, joints and effects of a model file."""
    act = d["actuator"]
    if not isinstance(act, dict) or "stiffness" not in act:
        raise VjmError("actuator must be a mapping with at least 'stiffness'")
    extra = set(act) - {"stiffness", "compliance_slope", "q_ref"}
    if extra:
        raise VjmError(f"actuator: unknown keys {sorted(extra)}")
    actuator = Actuator(**{k: _num(v, f"actuator.{k}") for k, v in act.items()})
    joints = d.get("joints") or {}
    if not isinstance(joints, dict) or set(joints) - {"passive_stiffness"}:
        raise VjmError("joints must be a mapping with only 'passive_stiffness' (N mm/rad)")
    ps = joints.get("passive_stiffness")
    jo = Joints(None if ps is None else _num(ps, "joints.passive_stiffness"))
    return actuator, jo, check_effects(d.get("effects") or {})


def check_effects(effects) -> dict:
    """The ``effects:`` mapping, checked against the effect library (vjm.discrepancy.effects): each entry
    an additive effect with its own parameters, finite and within their ranges."""
    from .discrepancy import effects as fx

    if not isinstance(effects, dict):
        raise VjmError("effects must be a mapping name -> parameters")
    out = {}
    additive = [k for k, e in fx.REGISTRY.items() if e.kind == "additive"]
    for name, vals in effects.items():
        if name not in fx.REGISTRY:
            raise VjmError(f"effects.{name}: unknown effect{did_you_mean(str(name), fx.REGISTRY)}; the effects "
                           f"written here: {', '.join(additive)}")
        eff = fx.get(name, f"effects.{name}")
        if eff.kind != "additive":
            raise VjmError(f"effects.{name}: {name} changes the model itself; it is written as the model's own "
                           f"parameters (links, actuator, joints), not under effects")
        out[name] = fx.check_values(name, vals, None, f"effects.{name}")
        missing = [p.name for p in eff.param_specs(None) if p.name not in out[name]]
        if missing:
            raise VjmError(f"effects.{name}: missing {', '.join(missing)}")
    return out


def _described_from_dict(d: dict, base_dir: str, path: str | None) -> Model:
    """A machine description (vjm.description): platform, chains, links."""
    if d.get("architecture", DESCRIBED) != DESCRIBED:
        raise VjmError(f"architecture: a file with chains describes its machine itself; leave 'architecture' "
                       f"out or set it to {DESCRIBED!r}, got {d['architecture']!r}")
    for k in ("actuator", "chains", "platform"):
        if k not in d:
            raise VjmError(f"{k}: missing (a machine description needs platform, chains and actuator)")
    geo = d.get("geometry") or {}
    if not isinstance(geo, dict):
        raise VjmError("geometry must be a mapping of lengths in mm")
    geo = {k: _num(v, f"geometry.{k}") for k, v in geo.items()}
    links_raw = d.get("links") or {}
    if not isinstance(links_raw, dict):
        raise VjmError("links must be a mapping name -> link ({rigid: true}, {compliance: ...}, {beam: ...}, "
                       "{linkfea: path})")
    for k in ("foot", "leg"):
        if k in links_raw:
            raise VjmError(f"links.{k}: give {k} at the top level, as in every model file")
    links = {str(k): parse_link(v, f"links.{k}", base_dir) for k, v in links_raw.items()}
    names = set(links) | {k for k in ("foot", "leg") if k in d}
    desc = parse_description(d, geo, names)
    actuator, jo, effects = _common(d)
    foot = parse_link(d["foot"], "foot", base_dir) if "foot" in d else Link.rigid()
    leg = parse_link(d["leg"], "leg", base_dir) if "leg" in d else Link.rigid()
    return Model(DESCRIBED, geo, actuator, foot, leg, jo, dict(effects), str(d.get("name", "")), path,
                 links=links, description=desc)


def load_model(path, foot=None, leg=None) -> Model:
    """Read a model file; ``foot``/``leg`` (paths to linkfea results) override the file's links."""
    path = os.fspath(data_file(path))
    if not os.path.isfile(path):
        raise VjmError(f"model file not found: {path}")
    from .yamldata import read_yaml

    d = read_yaml(path, "model file")  # plain data: a YAML tag that builds objects is refused
    if isinstance(d, dict):
        d = dict(d)
        if foot is not None:
            d["foot"] = {"linkfea": os.path.abspath(foot)}
        if leg is not None:
            d["leg"] = {"linkfea": os.path.abspath(leg)}
    return model_from_dict(d, os.path.dirname(os.path.abspath(path)), os.path.abspath(path))


def _link_to_yaml(link: Link, out_dir: str):
    src = link.source
    if link.compliance is None:
        return {"rigid": True}
    if src and "linkfea" in src:
        return {"linkfea": os.path.relpath(src["linkfea"], out_dir)}
    if src and "beam" in src:
        return {"beam": dict(src["beam"])}
    return {"compliance": np.asarray(link.compliance).tolist()}


def model_to_dict(model: Model, out_dir: str = ".") -> dict:
    """The mapping that :func:`model_from_dict` reads back to an equal model."""
    a = model.actuator
    if model.description is not None:
        out = {"name": model.name, "geometry": {k: float(v) for k, v in model.geometry.items()},
               "actuator": {"stiffness": float(a.stiffness), "compliance_slope": float(a.compliance_slope),
                            "q_ref": float(a.q_ref)}}
        for k in ("foot", "leg"):
            if getattr(model, k).source != {"rigid": True} or k in model.description.links:
                out[k] = _link_to_yaml(getattr(model, k), out_dir)
        out["joints"] = {"passive_stiffness": model.joints.passive_stiffness}
        out["effects"] = plain(model.effects)
        raw = model.description.raw
        out["platform"] = plain(raw["platform"])
        if model.links:
            out["links"] = {k: _link_to_yaml(v, out_dir) for k, v in model.links.items()}
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


def save_model(model: Model, path) -> None:
    """Write ``model`` as YAML (atomic: temporary file, then os.replace); round-trips with load_model."""
    path = os.path.abspath(os.fspath(path))
    out_dir = os.path.dirname(path)
    text = HEADER + yaml.safe_dump(model_to_dict(model, out_dir), sort_keys=False, default_flow_style=None)
    write_text(path, text)


def with_links(model_path, out_path, foot=None, leg=None) -> Model:
    """Write a copy of a model file whose foot/leg read the given linkfea results; returns the model."""
    m = load_model(model_path, foot=foot, leg=leg)
    save_model(m, out_path)
    return load_model(out_path)
