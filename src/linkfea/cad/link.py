"""The link value of the CAD stage, and its checks.

A :class:`Link` is the body solid, an optional pseudo-rigid reference block fused at the tip,
the base (clamped) and tip interface selectors, and the reference frame.  It is made by
:func:`linkfea.cad.build_link` (scripts), :mod:`linkfea.cad.step` (STEP files) and
:mod:`linkfea.cad.surface` (triangle surfaces), all of which import it from here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..mechanics.frames import Frame
from ..mechanics.materials import get_material
from ..runtime.errors import LinkFeaError
from .selectors import Selector, select_faces


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
        Material name (see :func:`linkfea.mechanics.materials.get_material`).
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


def interface_faces(link: Link) -> tuple[list, list]:
    """The body faces of the base and of the tip interface; a selector that finds none is refused.

    The one home of that check: :func:`check_link`, the meshers and the beam models use it.
    """
    bf, tf = link.base_faces, link.tip_faces
    for which, sel, found in (("base", link.base, bf), ("tip", link.tip, tf)):
        if not found:
            raise LinkFeaError(f"{link.name}: {which} selector {sel} finds no face{_nearest(link.body, sel)}")
    return bf, tf


def _nearest(body, selector) -> str:
    """``; nearest: ...`` naming the face groups closest to what ``selector`` asks (linkfea faces lists all)."""
    from .faces import nearest_selectors

    try:
        near = nearest_selectors(body, selector)
    except Exception:  # a body OpenCASCADE cannot walk: the message without the hint
        return ""
    return f"; nearest: {'; '.join(near)} (linkfea faces FILE lists them all)" if near else ""


def check_link(link: Link) -> None:
    """Selectors find faces, base and tip do not overlap, solids are valid."""
    for nm, s in (("body", link.body), ("block", link.block)):
        if s is not None and not s.isValid():
            raise LinkFeaError(f"{link.name}: the {nm} solid is not valid")
    bf, tf = interface_faces(link)
    if {f.hashCode() for f in bf} & {f.hashCode() for f in tf} or _faces_touch(bf, tf):
        raise LinkFeaError(f"{link.name}: base and tip interfaces overlap ({link.base} / {link.tip})")
    get_material(link.material)


def _faces_touch(fa, fb, tol=1e-6) -> bool:
    """True where a base face and a tip face share a point (an edge or a vertex)."""
    import cadquery as cq
    a = cq.Compound.makeCompound(fa)
    b = cq.Compound.makeCompound(fb)
    return a.distance(b) <= tol
