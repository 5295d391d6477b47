"""Triangle-surface input (STL, OBJ, PLY): a closed triangle mesh made into a link.

Surfaces from topology optimisation, scans or other tools have no B-rep.  The
triangles are read with trimesh, checked and repaired only where that is safe
(coincident vertices merged, degenerate and duplicate triangles dropped,
winding made consistent and outward); a surface that is still open is an error.
Each triangle then becomes a planar face of an OpenCASCADE solid, so the
selectors (``plane:``, ``box:``) pick input triangles, and the frame and block
follow the STEP rules (:func:`linkfea.cad.step.interface_frame_and_block`).  Such
links are meshed by pytetwild by default (fTetWild is made for triangle soups).
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..runtime.errors import LinkFeaError
from .selectors import Selector
from .step import link_from_solid

if TYPE_CHECKING:
    from .link import Link

SUFFIXES = (".stl", ".obj", ".ply")


def is_surface(spec) -> bool:
    return Path(str(spec)).suffix.lower() in SUFFIXES


def read_surface(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) and outward triangles (m, 3) of a closed surface file, after the safe repairs."""
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise LinkFeaError(f"surface file {str(path)!r} not found")
    try:  # unprocessed first: processing drops the triangles of a NaN vertex, which then reads as a hole
        tm = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises various errors on unreadable files
        raise LinkFeaError(f"cannot read surface file {str(path)!r}: {exc}") from None
    if not isinstance(tm, trimesh.Trimesh) or len(tm.faces) == 0:
        raise LinkFeaError(f"{path.name}: no triangles in the file")
    _check_finite(tm, path.name)
    tm.process()
    tm.update_faces(tm.nondegenerate_faces())
    tm.update_faces(tm.unique_faces())
    tm.remove_unreferenced_vertices()
    if not tm.is_watertight:
        edges = np.sort(tm.edges, axis=1)
        _, counts = np.unique(edges, axis=0, return_counts=True)
        raise LinkFeaError(f"{path.name}: the surface is not watertight ({int(np.sum(counts == 1))} open edges); "
                           "close it in the tool that made it and export again")
    _check_one_body(tm, path.name)
    trimesh.repair.fix_winding(tm)
    trimesh.repair.fix_inversion(tm)
    if not (tm.is_winding_consistent and tm.volume > 0):
        raise LinkFeaError(f"{path.name}: the surface has no consistent outward orientation (self-intersecting?)")
    return np.asarray(tm.vertices, dtype=float), np.asarray(tm.faces, dtype=np.int64)


def _check_finite(tm, name: str) -> None:
    """Refuse a vertex with a NaN or infinite coordinate, naming it and its first triangle."""
    V = np.asarray(tm.vertices, dtype=float)
    bad = np.flatnonzero(~np.all(np.isfinite(V), axis=1))
    if len(bad):
        tri = np.flatnonzero(np.any(np.isin(np.asarray(tm.faces), bad[:1]), axis=1))
        where = f", in triangle {int(tri[0]) + 1}" if len(tri) else ""
        more = f" (and {len(bad) - 1} more vertices)" if len(bad) > 1 else ""
        raise LinkFeaError(f"{name}: a vertex has a non-finite coordinate ({', '.join(f'{v:g}' for v in V[bad[0]])})"
                           f"{where}{more}; export the surface again")


def _check_one_body(tm, name: str) -> None:
    """Refuse a surface that is not one closed body: several pieces, or none with a volume.

    One closed piece per body: two bodies side by side, two that cross, or a body with a void are
    several pieces, of which the solid would keep one.  The volume is the signed sum over the
    triangles, computed here: trimesh's mass properties divide by it (a RuntimeWarning) first.
    """
    import trimesh

    pieces = trimesh.graph.connected_components(tm.face_adjacency, nodes=np.arange(len(tm.faces)))
    if len(pieces) > 1:
        raise LinkFeaError(f"{name}: expected one body, found {len(pieces)} separate closed surfaces (several "
                           "bodies, bodies that cross each other, or a body with a void); unite them into one "
                           "body in the tool that made them and export again")
    T = np.asarray(tm.triangles, dtype=float)
    volume = abs(float(np.einsum("ij,ij->i", T[:, 0], np.cross(T[:, 1], T[:, 2])).sum())) / 6.0
    if not volume > 1e-9 * float(np.ptp(tm.vertices, axis=0).max()) ** 3:
        raise LinkFeaError(f"{name}: the surface encloses no volume (a flat or folded sheet of triangles); a link "
                           "is a solid body")


def solid_from_triangles(V: np.ndarray, F: np.ndarray, label: str):
    """An OpenCASCADE solid with one planar face per triangle (sewn, closed)."""
    import cadquery as cq
    from OCP.BRepBuilderAPI import (
        BRepBuilderAPI_MakeFace,
        BRepBuilderAPI_MakePolygon,
        BRepBuilderAPI_MakeSolid,
        BRepBuilderAPI_Sewing,
    )
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_SHELL
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    sew = BRepBuilderAPI_Sewing(1e-9 * max(float(np.ptp(V, axis=0).max()), 1.0))
    for tri in F:
        poly = BRepBuilderAPI_MakePolygon(*(gp_Pnt(*map(float, V[i])) for i in tri), True)
        sew.Add(BRepBuilderAPI_MakeFace(poly.Wire(), True).Face())
    sew.Perform()
    exp = TopExp_Explorer(sew.SewedShape(), TopAbs_SHELL)
    if not exp.More():
        raise LinkFeaError(f"{label}: the triangles do not sew into a closed shell")
    solid = cq.Solid(BRepBuilderAPI_MakeSolid(TopoDS.Shell_s(exp.Current())).Solid())
    if solid.Volume() < 0:
        solid = cq.Solid(solid.wrapped.Reversed())
    if not (solid.isValid() and solid.Volume() > 0):
        raise LinkFeaError(f"{label}: the triangles do not make a valid closed solid")
    return solid


def load_surface(path, base: Selector, tip: Selector, material: str = "steel",
                 with_block: bool = True, block_length: float | None = None) -> Link:
    """A :class:`linkfea.cad.link.Link` from a closed triangle surface (see the module docstring)."""
    path = Path(path)
    V, F = read_surface(path)
    body = solid_from_triangles(V, F, path.name)
    return link_from_solid(body, path, base, tip, material, with_block, block_length)
