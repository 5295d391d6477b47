"""Filleted parts built with CadQuery and exported to STEP: the designer's own parts.

The L-bracket:

A horizontal arm (x from 0 to 80, 20 wide along y, 12 high along z) and an
upright at its far end (x from 68 to 80, up to z = 105), a 6 mm fillet in
the inner corner and an 8 mm bore through the arm.  Base: the arm's end face
x = 0; tip: the upright's top face z = 105.  The edges that border both
interface faces carry 4 mm fillets (along z at the base, along x at the tip),
so each interface face is a rectangle whose long edges run into fillets: the
case where a tessellation mesher loses a strip along every edge.
Interface faces: base 12 x 12 = 144 mm^2, tip 12 x 12 = 144 mm^2.

The flat link (``flat_link_step``, below): the same case with wide interface faces.
"""
from __future__ import annotations

from pathlib import Path

BASE = "plane:x=0"
TIP = "plane:z=105"
BASE_AREA = 12.0 * 12.0
TIP_AREA = 12.0 * 12.0


def bracket_solid():
    import cadquery as cq

    arm = cq.Workplane("XY").box(80.0, 20.0, 12.0, centered=(False, True, False))
    upright = cq.Workplane("XY").box(12.0, 20.0, 105.0, centered=(False, True, False)).translate((68.0, 0, 0))
    body = arm.union(upright)
    body = body.edges("|Y").edges(cq.selectors.NearestToPointSelector((68.0, 0.0, 12.0))).fillet(6.0)
    body = body.edges("|Z").edges("<X").fillet(4.0)
    body = body.edges("|X").edges(">Z").fillet(4.0)
    body = body.cut(cq.Workplane("XY").center(30.0, 0.0).circle(4.0).extrude(12.0))
    return body.val()


def bracket_step(folder) -> Path:
    """Write the bracket to ``folder/bracket.step`` and return the path."""
    import cadquery as cq

    path = Path(folder) / "bracket.step"
    cq.exporters.export(cq.Workplane().add(bracket_solid()), str(path))
    return path


# A flat link, 150 long (x) x 60 wide (y) x 10 thick (z), its four corners rounded in plan
# (r = 4 mm fillets on the edges along z).  Base: the end face x = 0; tip: the end face x = 150.
# Each interface face is 52 x 10 and both its short sides are tangent fillet borders: the strip a
# tessellation mesher loses there is narrow next to the 52 mm width, so a few border refinements
# pass the area gate (the bracket's 12 mm faces need far finer borders).
LINK_LENGTH = 150.0
LINK_BASE = "plane:x=0"
LINK_TIP = "plane:x=150"
LINK_FACE_AREA = (60.0 - 2 * 4.0) * 10.0


def flat_link_solid():
    import cadquery as cq

    plate = cq.Workplane("XY").box(LINK_LENGTH, 60.0, 10.0, centered=(False, True, False))
    return plate.edges("|Z").fillet(4.0).val()


def flat_link_step(folder) -> Path:
    """Write the flat link to ``folder/flat_link.step`` and return the path."""
    import cadquery as cq

    path = Path(folder) / "flat_link.step"
    cq.exporters.export(cq.Workplane().add(flat_link_solid()), str(path))
    return path
