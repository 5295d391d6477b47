"""Orthoglide-like foot: the bracket between an actuator slider and a leg.

A mounting flange (clamped where it bolts to the slider, face x = 0), a
pocketed arm with a cross rib, and a cylindrical boss at the far end whose
end face (x = length) carries the leg's joint.  The reference block is a
disc fused on that end face.  Not a beam: the flange, the open pocket and the
boss all shear and warp.  Lengths in mm.

``fillet`` is the machining radius (the end mill's) on every concave edge: the pocket's floor
and corners and the arm's junctions with the flange and the boss.  0 gives sharp re-entrant
edges, an idealisation whose stress is singular there.
"""
import cadquery as cq

from linkfea.cad import Link, Plane, resolve_params
from linkfea.runtime.errors import LinkFeaError
from linkfea.mechanics.frames import Frame

PARAMS = {
    "length": 140.0,          # mm, flange face (x=0) to boss end face (x=length)
    "flange_width": 70.0,     # mm, along y
    "flange_height": 60.0,    # mm, along z
    "flange_thickness": 12.0, # mm, along x
    "arm_width": 40.0,        # mm, along y
    "arm_height": 30.0,       # mm, along z
    "wall": 6.0,              # mm, pocket side walls and floor
    "rib": 6.0,               # mm, cross rib thickness (mid pocket)
    "boss_diameter": 36.0,    # mm
    "boss_length": 20.0,      # mm, along x
    "block_length": 10.0,     # mm, reference block along x
    "fillet": 0.0,            # mm, machining radius on the concave edges (0: sharp)
    "material": "aluminium",
}


def build(**params) -> Link:
    """Build the foot; see ``PARAMS``."""
    p = resolve_params(PARAMS, params, positive=[k for k, v in PARAMS.items() if isinstance(v, float) and k != "fillet"],
                       nonnegative=["fillet"])
    L, tf, lb = p["length"], p["flange_thickness"], p["boss_length"]
    x_arm = L - lb
    if x_arm <= tf + 2 * p["wall"] + p["rib"]:
        raise LinkFeaError(f"length {L} leaves no room for the arm (flange {tf} + boss {lb})")
    if 2 * p["wall"] >= min(p["arm_width"], p["arm_height"]):
        raise LinkFeaError(f"wall {p['wall']} too thick for the arm section {p['arm_width']} x {p['arm_height']}")
    if p["boss_diameter"] > min(p["flange_width"], p["flange_height"]):
        raise LinkFeaError("boss_diameter must not exceed the flange size")
    flange = cq.Workplane("YZ").rect(p["flange_width"], p["flange_height"]).extrude(tf)
    arm = cq.Workplane("YZ").workplane(offset=tf).rect(p["arm_width"], p["arm_height"]).extrude(x_arm - tf + 1e-3 * L)
    boss = cq.Workplane("YZ").workplane(offset=x_arm).circle(p["boss_diameter"] / 2).extrude(lb)
    body = flange.union(arm).union(boss)
    # Open pocket from the top (+z) of the arm, split by a cross rib at mid-length.
    w, h = p["arm_width"] - 2 * p["wall"], p["arm_height"] - p["wall"]
    x0, x1 = tf + p["wall"], x_arm - p["wall"]
    xm = 0.5 * (x0 + x1)
    for a, b in ((x0, xm - p["rib"] / 2), (xm + p["rib"] / 2, x1)):
        pocket = (cq.Workplane("XY").box(b - a, w, h, centered=(False, True, False))
                  .translate((a, 0, p["arm_height"] / 2 - h + 1e-9)))
        body = body.cut(pocket)
    body = body.val()
    if p["fillet"] > 0:
        body = _fillet_concave(body, p["fillet"])
    block = cq.Workplane("YZ").workplane(offset=L).circle(p["boss_diameter"] / 2).extrude(p["block_length"]).val()
    return Link(name="orthoglide_foot", body=body, block=block,
                base=Plane((0.0, 0.0, 0.0), (1.0, 0.0, 0.0)), tip=Plane((L, 0.0, 0.0), (1.0, 0.0, 0.0)),
                frame=Frame.from_x((L, 0.0, 0.0), (1.0, 0.0, 0.0)), params=p, material=p["material"],
                source=__file__)


def _fillet_concave(body, r: float):
    """Round every concave edge of ``body`` with radius ``r`` (one OCC fillet operation)."""
    from linkfea.mesh.gmsh import concave_edges

    try:
        out = body.fillet(r, concave_edges(body))
    except Exception:  # OCC raises StdFail_NotDone without a useful message
        out = None
    if out is None or not out.isValid():
        raise LinkFeaError(f"fillet {r:g} mm: OpenCASCADE cannot round the foot's concave edges with this radius; "
                           "try a slightly different one")
    return out
