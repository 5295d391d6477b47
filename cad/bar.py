"""Straight bar: the validation link (a cantilever with a closed form).

The bar runs along x from the base (x = 0, clamped) to the tip (x = length),
centred on y = z = 0.  The reference block has the bar's cross-section and
continues it beyond the tip.  All lengths in mm.
"""
import cadquery as cq

from linkfea.cad import Link, Plane, resolve_params
from linkfea.runtime.errors import LinkFeaError
from linkfea.mechanics.frames import Frame

PARAMS = {
    "length": 200.0,          # mm, base (x=0) to tip (x=length)
    "section": "rect",        # rect | circle | tube
    "width": 20.0,            # mm, along y (rect)
    "height": 10.0,           # mm, along z (rect)
    "diameter": 20.0,         # mm, outer diameter (circle, tube)
    "inner_diameter": 12.0,   # mm, bore (tube)
    "block_length": 0.0,      # mm, reference block length; 0 = half the largest section size
    "material": "steel",
}


def section_sketch(wp: cq.Workplane, p: dict) -> cq.Workplane:
    """The cross-section drawn on a YZ workplane."""
    if p["section"] == "rect":
        return wp.rect(p["width"], p["height"])
    if p["section"] == "circle":
        return wp.circle(p["diameter"] / 2.0)
    return wp.circle(p["diameter"] / 2.0).circle(p["inner_diameter"] / 2.0)


def build(**params) -> Link:
    """Build the bar link; see ``PARAMS`` for names, units and defaults."""
    p = resolve_params(PARAMS, params, positive=("length", "width", "height", "diameter", "inner_diameter"),
                       nonnegative=("block_length",))
    if p["section"] not in ("rect", "circle", "tube"):
        raise LinkFeaError(f"parameter 'section' must be rect, circle or tube, got {p['section']!r}")
    if p["section"] == "tube" and not p["inner_diameter"] < p["diameter"]:
        raise LinkFeaError(f"tube needs inner_diameter < diameter, got {p['inner_diameter']} >= {p['diameter']}")
    L = p["length"]
    size = max(p["width"], p["height"]) if p["section"] == "rect" else p["diameter"]
    lb = p["block_length"] or size / 2.0
    body = section_sketch(cq.Workplane("YZ"), p).extrude(L).val()
    block = section_sketch(cq.Workplane("YZ").workplane(offset=L), p).extrude(lb).val()
    return Link(
        name="bar",
        body=body,
        block=block,
        base=Plane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)),
        tip=Plane((L, 0.0, 0.0), (1.0, 0.0, 0.0)),
        frame=Frame.from_x((L, 0.0, 0.0), (1.0, 0.0, 0.0)),
        params=p,
        material=p["material"],
        source=__file__,
    )
