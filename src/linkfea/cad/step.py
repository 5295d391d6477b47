"""STEP input: loading and validating a solid, and the frame and block built from its tip faces."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..mechanics.frames import Frame
from ..mechanics.materials import get_material
from ..runtime.errors import LinkFeaError
from .link import Link, check_link
from .selectors import Selector, faces_area_centroid, faces_mean_normal


def load_step(path, base: Selector, tip: Selector, material: str = "steel",
              with_block: bool = True, block_length: float | None = None) -> Link:
    """Load and validate a STEP link and build its frame and (optional) block.

    Checks: exactly one solid, a valid BRep (``BRepCheck``), no
    self-intersection (``BOPAlgo_ArgumentAnalyzer``), a watertight
    tessellation (trimesh).  The frame's origin is the area centroid of the
    tip faces; its x axis is their mean outward normal when they are planar
    and coplanar, otherwise the direction from the base centroid to the tip
    centroid (a bore, say).  With ``with_block`` the block is the tip faces
    extruded outward by ``block_length`` (default half the square root of the
    tip area); this needs planar tip faces.
    """
    body = read_step_solid(path)
    return link_from_solid(body, Path(path), base, tip, material, with_block, block_length)


def read_step_solid(path):
    """The one solid of a STEP file, checked (see :func:`load_step`)."""
    import cadquery as cq

    path = Path(path)
    if not path.is_file():
        raise LinkFeaError(f"STEP file {str(path)!r} not found")
    try:
        shape = cq.importers.importStep(str(path)).val()
    except Exception as exc:  # OCC raises bare exceptions on unreadable files
        raise LinkFeaError(f"cannot read STEP file {str(path)!r}: {exc}") from None
    solids = shape.Solids() if hasattr(shape, "Solids") else []
    if not solids:
        raise LinkFeaError(f"{path.name}: no closed solid in the STEP file (an open shell is not watertight)")
    if len(solids) > 1:
        raise LinkFeaError(f"{path.name}: expected one solid, found {len(solids)} "
                           "(several bodies, or a self-intersecting solid split on import)")
    body = solids[0]
    validate_solid(body, path.name)
    return body


def link_from_solid(body, path: Path, base: Selector, tip: Selector, material: str, with_block: bool,
                    block_length: float | None) -> Link:
    """The :class:`linkfea.cad.link.Link` of a checked solid read from ``path`` (a STEP file or a triangle surface).

    The selectors are checked on ``body`` (:func:`linkfea.cad.link.check_link`), then the frame and
    the block come from the tip faces (:func:`interface_frame_and_block`).  ``params`` records
    the block length used (a planar tip in block mode), nothing else.
    """
    get_material(material)
    link = Link(name=path.stem, body=body, block=None, base=base, tip=tip,
                frame=Frame(np.zeros(3), np.eye(3)), params={}, material=material, source=str(path))
    check_link(link)
    frame, block, h = interface_frame_and_block(body, link.base_faces, link.tip_faces, with_block,
                                                block_length, path.name)
    return Link(name=path.stem, body=body, block=block, base=base, tip=tip, frame=frame,
                params={"block_length": h} if with_block and h is not None else {},
                material=material, source=str(path))


def interface_frame_and_block(body, base_faces, tip_faces, with_block: bool, block_length, label: str):
    """Frame from the tip faces and, with ``with_block``, the block extruded from them.

    Origin: area centroid of the tip faces.  x: their mean outward normal
    when they are planar and coplanar, otherwise the direction from the base
    centroid to the tip centroid (a bore).  Block: planar tip faces extruded
    outward by ``block_length`` (default half the square root of their area);
    any other tip (a bore) is filled: the block is the empty space inside the
    tip faces' bounding box that touches them (a bore's pin), and it must touch
    the body on the tip faces only.

    Returns
    -------
    frame, block (or None), block length used (or None)
    """
    import cadquery as cq

    A, c_tip = faces_area_centroid(tip_faces)
    _, c_base = faces_area_centroid(base_faces)
    n = faces_mean_normal(tip_faces)
    planar = all(f.geomType() == "PLANE" for f in tip_faces) and np.linalg.norm(n) > 1 - 1e-6
    x = n if planar else c_tip - c_base
    if np.linalg.norm(x) < 1e-9:
        raise LinkFeaError(f"{label}: cannot orient the frame (tip and base centroids coincide)")
    frame = Frame.from_x(c_tip, x)
    if not with_block:
        return frame, None, None
    if not planar:
        return frame, fill_block(body, tip_faces, label), None
    h = block_length if block_length is not None else 0.5 * math.sqrt(A)
    if not (math.isfinite(h) and h > 0):
        raise LinkFeaError(f"block length must be > 0 mm, got {h}")
    v = cq.Vector(*(frame.axes[0] * h))
    parts = [cq.Solid.extrudeLinear(f, v) for f in tip_faces]
    block = parts[0] if len(parts) == 1 else cq.Compound.makeCompound(parts).fuse().clean()
    if hasattr(block, "Solids") and len(block.Solids()) == 1:
        block = block.Solids()[0]
    if block.intersect(body).Volume() > 1e-6 * block.Volume():
        raise LinkFeaError(f"{label}: the block extruded from the tip faces runs into the body")
    return frame, block, h


def fill_block(body, tip_faces, label: str):
    """The block of a non-planar tip: the space the tip faces enclose (a bore's pin).

    It is the part of the tip faces' bounding box outside the body that
    touches the tip faces.  Its contact with the body must be the tip faces
    and nothing else (an unselected chamfer in the box would be bonded too).
    """
    import cadquery as cq
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    tips = cq.Compound.makeCompound(tip_faces)
    # The exact box of the geometry: no triangulation, no shape tolerance (a STEP face's
    # tolerance would let the block stick out of the bore by that much).
    bnd = Bnd_Box()
    BRepBndLib.AddOptimal_s(tips.wrapped, bnd, False, False)
    lo, hi = np.array(bnd.Get()[:3]), np.array(bnd.Get()[3:])
    dx, dy, dz = (float(v) for v in hi - lo)
    box = cq.Solid.makeBox(dx, dy, dz, pnt=cq.Vector(*lo))
    tol = 1e-6 * max(float(np.linalg.norm(hi - lo)), 1.0)
    solids = [s for s in box.cut(body).Solids() if s.Volume() > 1e-9 * box.Volume() and s.distance(tips) <= tol]
    if not solids:
        raise LinkFeaError(f"{label}: the tip faces enclose no space to fill with a block; use --mode rigid")
    block = solids[0] if len(solids) == 1 else cq.Compound.makeCompound(solids)
    A_tip = sum(f.Area() for f in tip_faces)
    # A point inside each block face (a cylinder's area centroid lies on its axis, off the face).
    contact = sum(f.Area() for f in block.Faces() if body.distance(cq.Vertex.makeVertex(*_inner_point(f))) <= tol)
    if abs(contact - A_tip) > 1e-6 * A_tip:
        raise LinkFeaError(f"{label}: the block filling the tip faces touches the body on {contact:.6g} mm^2, "
                           f"not on the tip faces' {A_tip:.6g} mm^2 (select every face of the bore)")
    return block


def _inner_point(face) -> tuple:
    """A point of ``face`` inside its parameter range (not on its edges)."""
    u0, u1, v0, v1 = face._uvBounds()
    return face.positionAt(u0 + 0.37 * (u1 - u0), v0 + 0.41 * (v1 - v0)).toTuple()


def validate_solid(solid, label: str = "solid") -> None:
    """Raise :class:`LinkFeaError` unless ``solid`` is a valid, closed, non-self-intersecting solid."""
    import trimesh
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Check

    if not solid.isValid():
        raise LinkFeaError(f"{label}: the solid is not valid (BRepCheck failed: open shell or bad geometry)")
    if not BRepAlgoAPI_Check(solid.wrapped, True, True).IsValid():
        raise LinkFeaError(f"{label}: the solid intersects itself or has degenerate edges")
    if not solid.Volume() > 0:
        raise LinkFeaError(f"{label}: the solid has no volume (open or inside-out shell)")
    v, f = tessellate(solid, 1e-3 * _size(solid))
    tm = trimesh.Trimesh(v, f, process=True)
    # A sphere's pole is one point but the triangulation's fan ends there in a zero-area triangle
    # (two corners on the pole once merged), which leaves its edges used once or thrice: drop it.
    tm.update_faces(tm.nondegenerate_faces())
    if not tm.is_watertight:
        raise LinkFeaError(f"{label}: the surface is not watertight (open shell or gaps between faces)")


def _size(shape) -> float:
    """Bounding-box diagonal, mm."""
    return float(shape.BoundingBox().DiagonalLength)


def tessellate(shape, tol: float, angular_tol: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate a shape's surface: vertices (n, 3) float64 and triangles (m, 3) int64."""
    v, f = shape.tessellate(tol, angular_tol)
    V = np.array([p.toTuple() for p in v], dtype=float).reshape(-1, 3)
    F = np.array(f, dtype=np.int64).reshape(-1, 3)
    return V, F
