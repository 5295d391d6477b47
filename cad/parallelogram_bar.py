"""Orthoglide parallelogram bar: a rectangular bar with a pin boss at each end.

The bar runs along x; the pin axes are along z at x = 0 (base) and
x = pitch (tip).  The base interface is the bore of the first boss (clamped
on its pin); the tip interface is the bore of the second boss, and the
reference block is the pin filling it.  Frame origin at the second pin's
centre, x along the bar, y along the pin axis (CAD z), z = x cross y (CAD -y):
the spring frame of a parallelogram bar in vjm, whose pivots turn about y
(seed eq. 20-22).  Lengths in mm.
"""
import cadquery as cq

from linkfea.cad import Box, Link, resolve_params
from linkfea.runtime.errors import LinkFeaError
from linkfea.mechanics.frames import Frame

PARAMS = {
    "pitch": 310.0,          # mm, between pin centres
    "width": 16.0,           # mm, bar section along y
    "height": 8.0,           # mm, bar section along z
    "boss_diameter": 24.0,   # mm
    "boss_height": 12.0,     # mm, along z (the pin length)
    "bore": 10.0,            # mm, pin diameter
    "material": "aluminium",
}


def build(**params) -> Link:
    """Build the bar with its bosses; see ``PARAMS``."""
    p = resolve_params(PARAMS, params, positive=[k for k, v in PARAMS.items() if isinstance(v, float)])
    P, D, d = p["pitch"], p["boss_diameter"], p["bore"]
    if not d < D:
        raise LinkFeaError(f"bore {d} must be smaller than boss_diameter {D}")
    if p["width"] > D or p["height"] > p["boss_height"]:
        raise LinkFeaError("the bar section must fit inside the bosses (width <= boss_diameter, height <= boss_height)")
    if P <= D:
        raise LinkFeaError(f"pitch {P} must exceed boss_diameter {D}")
    hb = p["boss_height"]
    bar = cq.Workplane("XY").box(P, p["width"], p["height"], centered=(False, True, True))
    bosses = cq.Workplane("XY").pushPoints([(0, 0), (P, 0)]).circle(D / 2).extrude(hb).translate((0, 0, -hb / 2))
    bores = cq.Workplane("XY").pushPoints([(0, 0), (P, 0)]).circle(d / 2).extrude(hb).translate((0, 0, -hb / 2))
    body = bar.union(bosses).cut(bores).val()
    block = cq.Workplane("XY").center(P, 0).circle(d / 2).extrude(hb).translate((0, 0, -hb / 2)).val()
    r, g = d / 2, 0.1 * d  # boxes just around each bore (not the boss outside)
    return Link(name="parallelogram_bar", body=body, block=block,
                base=Box((-r - g, -r - g, -hb), (r + g, r + g, hb)),
                tip=Box((P - r - g, -r - g, -hb), (P + r + g, r + g, hb)),
                frame=Frame.from_x((P, 0.0, 0.0), (1.0, 0.0, 0.0), y_hint=(0.0, 0.0, 1.0)), params=p, material=p["material"],
                source=__file__)
