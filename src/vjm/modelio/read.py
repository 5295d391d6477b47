"""Model files (YAML) in and out, validated.

Format (units N, mm, rad; compliances in mm/N, rad/(N mm), order Fx Fy Fz Mx My Mz)::

    architecture: orthoglide-3PUU     # | orthoglide-3PRPaR | delta-3RRPaR
    name: free text
    geometry: {L: 310, r: 50, d: 80}  # mm (delta also R: base radius, arm: arm length)
    actuator:
      stiffness: 3660                 # N/mm (prismatic) or N mm/rad (rotary)
      compliance_slope: 0             # optional, (mm/N)/mm: c(q) = 1/stiffness + slope (q - q_ref)
      q_ref: 0                        # optional, mm (rad)
    foot: <link>                      # spring frames: see vjm.architectures.orthoglide / delta
    leg: <link>                       # (or both under links: {foot: <link>, leg: <link>})
    joints: {passive_stiffness: null} # optional, N mm/rad: elastic passive joints
    effects: {}                       # optional: fitted additive effects of the discrepancy workflow,
                                      # e.g. {gravity: {weight: 12.0}}, checked against its effect library

``<link>`` is exactly one of::

    {rigid: true}
    {compliance: [[...6 numbers...], ... 6 rows]}            # in the spring frame
    {compliance: [[...]], frame: {origin: [...], x_axis: [...], y_axis: [...], z_axis: [...]}}
           # the same, stating the frame it was computed in (as a linkfea result does)
    {beam: {section: rect, width: 40, height: 20, length: 310, material: steel, shear: true}}
           # section: rect (width along y, height along z) | circle (diameter) |
           # tube (diameter, inner_diameter); material: name, or E (MPa) and nu
    {linkfea: path/to/result.json}    # output of `linkfea compute`, path relative to this file

A beam is a cantilever clamped at its base, its compliance taken in its tip
frame (x along the beam): eq. 14 plus Timoshenko shear unless ``shear: false``.
A linkfea result's reference frame (origin at the tip interface, x along
the link) is taken as the spring frame, and kept with the link.

``foot`` and ``leg`` at the top level are short for ``links: {foot: ..., leg: ...}``;
a machine description (``chains:``) names further links there.  Both forms load
into :attr:`vjm.Model.links`.

A file :func:`~vjm.modelio.write.save_model` writes begins with the comment lines of ``HEADER`` and ends
with ``# written by vjm; sha256 of the lines above: <hex>``: how a later save knows
the file as its own, unchanged (:func:`vjm.modelio.write.own_model_file`).  Reading
ignores both (comments).
"""
from __future__ import annotations

import os
import re

import numpy as np

from linkfea.runtime.checks import did_you_mean

from ..architectures import ARCHITECTURES
from ..architectures.described import NAME as DESCRIBED
from ..errors import VjmError
from ..model.base import Model
from ..model.links import LinkSpring, as_link, checked_compliance, linkfea_spring
from ..model.machine import Actuator, Joints, ParallelModel, validate_compliance
from ..resources import data_file
from .description import parse_description
from .write import save_model

#: ``calibration``: the covariance vjm diagnose writes with model_updated.yaml (read by vjm path, not by the Model)
TOP_KEYS = ("architecture", "name", "geometry", "actuator", "foot", "leg", "links", "joints", "effects", "calibration")
#: keys of a machine description (vjm.modelio.description), besides TOP_KEYS
DESCRIPTION_KEYS = ("platform", "chains")
LINK_KINDS = ("rigid", "compliance", "beam", "linkfea")


def _num(v, key: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise VjmError(f"{key} must be a finite number, got {v!r}")
    return float(v)


def beam_compliance(spec: dict, key: str = "beam") -> np.ndarray:
    """Cantilever compliance (tip frame) from a ``beam:`` mapping, via linkfea.beam.closed_form."""
    from linkfea.beam import closed_form as lb
    from linkfea.runtime.errors import LinkFeaError

    s, E, nu, length = beam_section(spec, key)
    try:
        return lb.cantilever_compliance(length, s, E, nu, shear=bool(spec.get("shear", True)))
    except LinkFeaError as exc:
        raise VjmError(f"{key}: {exc}") from None


def beam_section(spec: dict, key: str = "beam") -> tuple:
    """``(Section, E, nu, length)`` of a ``beam:`` mapping (MPa, mm): linkfea.beam.closed_form's section
    constants (its area, inertias), the material's moduli and the beam's length; VjmError naming ``key``."""
    from linkfea.beam import closed_form as lb
    from linkfea.mechanics.materials import get_material
    from linkfea.runtime.errors import LinkFeaError

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
        return s, E, nu, length
    except LinkFeaError as exc:
        raise VjmError(f"{key}: {exc}") from None


def _inline(spec: dict, key: str) -> LinkSpring:
    """``{compliance: 6x6[, frame: {...}]}`` -> LinkSpring."""
    from linkfea.mechanics.frames import Frame
    from linkfea.runtime.errors import LinkFeaError

    frame = None
    if "frame" in spec:
        try:
            frame = Frame.from_dict(spec["frame"])
        except (LinkFeaError, KeyError, TypeError, ValueError) as exc:
            raise VjmError(f"{key}.frame must be a frame (origin, x_axis, y_axis, z_axis in mm): {exc}") from None
    C = validate_compliance(spec["compliance"], f"{key}.compliance")
    return LinkSpring(checked_compliance(C, f"{key}.compliance", frame), None)


def parse_link(spec, key: str, base_dir: str) -> LinkSpring:
    """One ``foot:`` / ``leg:`` / ``links:`` entry -> LinkSpring (VjmError names ``key``)."""
    inline = isinstance(spec, dict) and set(spec) == {"compliance", "frame"}
    if not inline and (not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in LINK_KINDS):
        raise VjmError(f"{key} must be exactly one of: {{rigid: true}}, {{compliance: 6x6}}, {{beam: ...}}, "
                       f"{{linkfea: path}}; got {spec!r}")
    kind, val = next(iter(spec.items()))
    if kind == "rigid":
        if val is not True:
            raise VjmError(f"{key}.rigid must be true")
        return LinkSpring.rigid()
    if kind in ("compliance", "frame"):
        return _inline(spec, key)
    if kind == "beam":
        C = validate_compliance(beam_compliance(val, f"{key}.beam"), f"{key}.beam")
        return LinkSpring(checked_compliance(C, f"{key}.beam"), {"beam": dict(val)})
    if not isinstance(val, str):
        raise VjmError(f"{key}.linkfea must be a file path")
    path = os.path.normpath(os.path.join(base_dir, val))
    return linkfea_spring(path, f"{key}.linkfea")


def parse_links(d: dict, base_dir: str) -> dict:
    """All links of a model file: ``links:`` and the top-level ``foot`` / ``leg`` (short for links.foot ...)."""
    raw = d.get("links") or {}
    if not isinstance(raw, dict):
        raise VjmError("links must be a mapping name -> link ({rigid: true}, {compliance: ...}, {beam: ...}, "
                       "{linkfea: path})")
    out = {}
    for k in ("foot", "leg"):
        if k in d:
            if k in raw:
                raise VjmError(f"{k}: given twice, at the top level and under links; keep one")
            out[k] = parse_link(d[k], k, base_dir)
    out.update({str(k): parse_link(v, f"links.{k}", base_dir) for k, v in raw.items()})
    return out


def model_from_dict(d: dict, base_dir: str = ".", path: str | None = None) -> Model:
    """Build a validated :class:`vjm.Model` from the mapping of a model file: a robot (a ``urdf:`` or
    ``dh:`` key, :mod:`vjm.modelio.robotfile`) or a parallel machine."""
    if not isinstance(d, dict):
        raise VjmError("a model file must be a YAML mapping")
    from .robotfile import is_robot, robot_from_dict

    if is_robot(d):  # a serial or tree robot: a URDF or a DH table beside its springs (vjm.robot)
        return robot_from_dict(d, base_dir, path, parse_link)
    described = "chains" in d or d.get("architecture") == DESCRIBED
    known = TOP_KEYS + DESCRIPTION_KEYS if described else TOP_KEYS
    extra = set(d) - set(known)
    if extra:
        raise VjmError(f"unknown top-level keys {sorted(extra)}; known: {list(known)}")
    if described:
        return _described_from_dict(d, base_dir, path)
    links = parse_links(d, base_dir)
    for k in ("architecture", "geometry", "actuator", "foot", "leg"):
        if k not in d and k not in links:
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
    return ParallelModel(architecture=arch, geometry=geo, actuator=actuator, joints=jo, effects=dict(effects), name=str(d.get("name", "")), path=path,
                 links=links)


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
    """The ``effects:`` mapping, checked against the effect library (vjm.effects): each entry
    an additive effect with its own parameters, finite and within their ranges."""
    from .. import effects as fx

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
        missing = [p.name for p in eff.param_specs(None) if p.name not in out[name] and p.name not in eff.optional]
        if missing:
            raise VjmError(f"effects.{name}: missing {', '.join(missing)}")
    return out


def _described_from_dict(d: dict, base_dir: str, path: str | None) -> ParallelModel:
    """A machine description (vjm.modelio.description): platform, chains, links."""
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
    links = parse_links(d, base_dir)
    desc = parse_description(d, geo, set(links))
    _check_geometry_used(geo, desc.raw)
    actuator, jo, effects = _common(d)
    return ParallelModel(architecture=DESCRIBED, geometry=geo, actuator=actuator, joints=jo, effects=dict(effects), name=str(d.get("name", "")),
                 path=path, links=links, description=desc)


def _check_geometry_used(geo: dict, raw: dict) -> None:
    """Every geometry name of a description appears in one of its expressions: a name that none uses
    is a typo or a value that changes nothing, and is refused."""
    words: set = set()

    def walk(v):
        if isinstance(v, str):
            words.update(re.findall(r"[A-Za-z_][A-Za-z_0-9]*", v))
        elif isinstance(v, dict):
            for x in v.values():
                walk(x)
        elif isinstance(v, list):
            for x in v:
                walk(x)

    walk({k: v for k, v in raw.items() if k != "links"})
    unused = [k for k in geo if k not in words]
    if unused:
        raise VjmError(f"geometry.{unused[0]}: no expression of the platform or the chains uses it; remove it "
                       f"or use it (a geometry name changes the machine only through the expressions)")


def _is_result_path(link) -> bool:
    return isinstance(link, (str, os.PathLike)) and (os.fspath(link).endswith(".json") or os.path.isfile(link))


def is_robot_file(path) -> bool:
    """Whether a model file (a path or a bundled name) holds a serial or tree robot, read as plain data without
    loading it (so that a command checks its output before any work); False if it cannot be read (then
    :func:`load_model` says why)."""
    try:
        path = os.fspath(data_file(path))
        if not os.path.isfile(path):
            return False
        if path.lower().endswith(".urdf"):
            return True
        from .robotfile import is_robot
        from .yamldata import read_yaml

        return is_robot(read_yaml(path, "model file"))
    except VjmError:
        return False


def file_kind(path) -> str:
    """The :attr:`vjm.Model.kind` a model file (a path or a bundled name) loads to, "serial" or "parallel", read
    without loading it (:func:`is_robot_file`)."""
    return "serial" if is_robot_file(path) else "parallel"


def load_model(path, foot=None, leg=None, links: dict | None = None) -> Model:
    """Read a model file, with some of its links replaced: a :class:`vjm.Model` of either kind, a parallel
    machine (an architecture or a machine description) or a serial or tree robot (a YAML naming a URDF or
    holding a DH table, :mod:`vjm.modelio.robotfile`; or a ``.urdf`` file alone, a rigid robot).

    ``foot``, ``leg`` and the entries of ``links`` (name -> link) override the file's links;
    each may be a :class:`linkfea.LinkResult`, a :class:`linkfea.Compliance`, a
    :class:`~vjm.model.links.LinkSpring`, the path of a result JSON or a bundled link name
    (see :func:`vjm.model.links.as_link`).  A result path replaces the file's entry before it is
    read, so a file whose own link is unreadable still loads with it overridden.
    """
    path = os.fspath(data_file(path))
    if not os.path.isfile(path):
        raise VjmError(f"model file not found: {path}")
    if path.lower().endswith(".urdf"):  # a URDF alone: a rigid robot (its springs go in a model YAML beside it)
        if foot is not None or leg is not None or links:
            raise VjmError(f"{path}: a robot's link springs are given in a model YAML beside the URDF (links:)")
        return model_from_dict({"urdf": os.path.basename(path)}, os.path.dirname(os.path.abspath(path)),
                               os.path.abspath(path))
    from .yamldata import read_yaml

    d = read_yaml(path, "model file")  # plain data: a YAML tag that builds objects is refused
    given = {k: v for k, v in {**(links or {}), "foot": foot, "leg": leg}.items() if v is not None}
    from .robotfile import is_robot

    if is_robot(d) and given:
        raise VjmError(f"{path}: a robot's link springs are replaced in its model file (links:), not by "
                       f"foot/leg/links arguments")
    later = {}
    if isinstance(d, dict):
        d = dict(d)
        raw = dict(d["links"]) if isinstance(d.get("links"), dict) else None
        for k, link in given.items():
            if not _is_result_path(link):
                later[k] = link
                continue
            if raw is not None:
                raw.pop(k, None)
            entry = {"linkfea": os.path.abspath(link)}
            if k in ("foot", "leg"):
                d[k] = entry
            else:
                raw = {} if raw is None else raw
                raw[k] = entry
        if raw is not None:
            d["links"] = raw
    m = model_from_dict(d, os.path.dirname(os.path.abspath(path)), os.path.abspath(path))
    return m.replace(links={k: as_link(v, k) for k, v in later.items()}) if later else m


def with_links(model_path, out_path, foot=None, leg=None, links: dict | None = None) -> Model:
    """Write a copy of a model file with some links replaced (as :func:`load_model` takes them);
    returns the model read back from the copy.  A link computed in memory and never saved is
    written inline, with its frame."""
    m = load_model(model_path, foot=foot, leg=leg, links=links)
    save_model(m, out_path)
    return load_model(out_path)
