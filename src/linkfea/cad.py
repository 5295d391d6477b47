"""Links from CadQuery scripts or STEP files.

A :class:`Link` is the CAD-side value of the link stage: the body solid, an
optional pseudo-rigid reference block fused at the tip, the base (clamped) and
tip interface selectors, and the reference frame.

The concerns live in their own modules and are re-exported here:
:mod:`linkfea.selectors` (selector syntax and face picking),
:mod:`linkfea.step` (STEP loading and validation, frame and block from the tip
faces) and :mod:`linkfea.params` (script parameters).
"""
from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import LinkFeaError
from .frames import Frame
from .materials import get_material
from .params import parse_param_args, resolve_params  # noqa: F401  (re-exported)
from .resources import cad_dir, find_script
from .selectors import (  # noqa: F401  (re-exported)
    DEFAULT_TOL,
    Box,
    Plane,
    Selector,
    faces_area_centroid,
    faces_mean_normal,
    parse_selector,
    select_faces,
)
from .step import interface_frame_and_block, load_step, tessellate, validate_solid  # noqa: F401  (re-exported)

CAD_DIR = cad_dir()
"""Folder of the bundled link scripts (``bar``, ``orthoglide_foot``, ...)."""


# --------------------------------------------------------------------------- links
@dataclass(frozen=True)
class Link:
    """A link ready for meshing.

    Attributes
    ----------
    name : str
    body : cadquery.Solid
        The deformable link, mm.
    block : cadquery.Solid or None
        Pseudo-rigid reference block fused to the body at the tip interface.
        ``None`` is allowed in rigid mode (the tip faces are then coupled directly).
    base, tip : Plane or Box
        Selectors of the clamped base interface and of the tip interface, both
        applied to the faces of ``body``.
    frame : Frame
        Reference frame: origin at the tip interface centroid, x along the link.
    params : dict
        Parameters the link was built with (mm unless stated).
    material : str
        Material name (see :func:`linkfea.materials.get_material`).
    source : str
        Script path or STEP path the link came from.
    """

    name: str
    body: Any
    block: Any
    base: Selector
    tip: Selector
    frame: Frame
    params: dict = field(default_factory=dict)
    material: str = "steel"
    source: str = ""

    @property
    def base_faces(self) -> list:
        return select_faces(self.body, self.base)

    @property
    def tip_faces(self) -> list:
        return select_faces(self.body, self.tip)


def resolve_script(spec: str | Path) -> Path:
    """A cad/ script path, or a bare name like ``bar`` (a local ``./bar.py`` or ``./cad/bar.py`` wins
    over the bundled one): see :func:`linkfea.resources.find_script`."""
    return find_script(spec)


def load_script(path: str | Path):
    """Import a cad/ script as a module (it must define ``PARAMS`` and ``build``)."""
    path = resolve_script(path)
    modname = f"linkfea_cad_{path.stem}"
    spec = importlib.util.spec_from_file_location(modname, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    if not (hasattr(mod, "PARAMS") and callable(getattr(mod, "build", None))):
        raise LinkFeaError(f"{path}: a link script must define PARAMS and build(**params)")
    return mod


def is_step(spec) -> bool:
    return Path(str(spec)).suffix.lower() in (".step", ".stp")


def build_link(spec, params: dict | None = None, material: str | None = None,
               base=None, tip=None, with_block: bool = True, block_length: float | None = None) -> Link:
    """Build a :class:`Link` from a cad/ script (name or path), a STEP file or a triangle surface
    (STL, OBJ, PLY: :mod:`linkfea.surface`).

    For scripts, ``base``/``tip`` override the script's selectors and
    ``material`` the script's material; a new ``tip`` also rebuilds the frame
    and the block from the selected faces, as for STEP files.  For STEP files ``base`` and ``tip``
    are required and ``params`` must be empty.
    """
    if material is not None:
        get_material(material)
    from .surface import is_surface, load_surface

    if is_surface(spec):
        if params:
            raise LinkFeaError("--param applies to cad/ scripts, not to surface files")
        if base is None or tip is None:
            raise LinkFeaError("a surface file (STL, OBJ, PLY) needs --base and --tip selectors")
        return load_surface(spec, parse_selector(base), parse_selector(tip), material or "steel",
                            with_block=with_block, block_length=block_length)
    if is_step(spec):
        if params:
            raise LinkFeaError("--param applies to cad/ scripts, not to STEP files")
        if base is None or tip is None:
            raise LinkFeaError("a STEP file needs --base and --tip selectors")
        return load_step(spec, parse_selector(base), parse_selector(tip), material or "steel",
                         with_block=with_block, block_length=block_length)
    mod = load_script(spec)
    p = dict(params or {})
    if material is not None:
        if "material" not in mod.PARAMS:
            raise LinkFeaError(f"{spec}: this script has no material parameter")
        p["material"] = material
    link = mod.build(**p)
    if not isinstance(link, Link):
        raise LinkFeaError(f"{spec}: build() must return a linkfea.cad.Link")
    changes: dict = {}
    if base is not None:
        changes["base"] = parse_selector(base)
    if tip is not None:
        changes["tip"] = parse_selector(tip)
    if changes:
        from dataclasses import replace
        link = replace(link, **changes)
    check_link(link)
    if tip is not None:
        # A new tip interface: the script's frame and block belong to the old one, so both are
        # rebuilt from the selected faces by the STEP rule.
        frame, block, _ = interface_frame_and_block(link.body, link.base_faces, link.tip_faces, with_block,
                                                    block_length, link.name)
        from dataclasses import replace
        link = replace(link, frame=frame, block=block)
    return link


def check_link(link: Link) -> None:
    """Selectors find faces, base and tip do not overlap, solids are valid."""
    for nm, s in (("body", link.body), ("block", link.block)):
        if s is not None and not s.isValid():
            raise LinkFeaError(f"{link.name}: the {nm} solid is not valid")
    bf, tf = link.base_faces, link.tip_faces
    if not bf:
        raise LinkFeaError(f"{link.name}: base selector {link.base} finds no face")
    if not tf:
        raise LinkFeaError(f"{link.name}: tip selector {link.tip} finds no face")
    if {f.hashCode() for f in bf} & {f.hashCode() for f in tf} or _faces_touch(bf, tf):
        raise LinkFeaError(f"{link.name}: base and tip interfaces overlap ({link.base} / {link.tip})")
    get_material(link.material)


def _faces_touch(fa, fb, tol=1e-6) -> bool:
    """True where a base face and a tip face share a point (an edge or a vertex)."""
    import cadquery as cq
    a = cq.Compound.makeCompound(fa)
    b = cq.Compound.makeCompound(fb)
    return a.distance(b) <= tol
