"""Tetrahedral meshing of a link with pytetwild (fTetWild), chosen by ``mesher="pytetwild"``.

The body and (optionally) the reference block are tessellated separately and
handed to fTetWild together: both are closed surfaces, so the winding number
is 1 everywhere inside their union while the shared tip face is still an input
surface, which the tetrahedra conform to.  Block cells are then found by the
centroid test against the block solid.

fTetWild keeps the output surface within an *envelope* of
``epsilon * bbox diagonal`` of the input but moves vertices inside it, so the
interface facets are selected within that envelope (plus the tessellation
tolerance) and by their normal, never with a tight tolerance: a tight one
silently drops much of the clamp.

pytetwild is not deterministic from run to run, so the raw mesh (points, tets)
is cached (:func:`linkfea.mesh.cache.cache_dir_default`) keyed by the
SHA-256 of the input surfaces, the meshing parameters and
:data:`MESH_VERSION`; a repeated run reuses it bit for bit, concurrent runs of one key
share one mesh (the first meshes, the others wait and read) and a damaged entry is
meshed again (:mod:`linkfea.mesh.cache`).
"""
from __future__ import annotations

import hashlib
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..cad.link import interface_faces
from ..runtime.errors import LinkFeaError, SolverError
from .cache import cache_dir_default, cached_mesh
from .linkmesh import LinkMesh, check_interface_areas, finish_mesh, tet_faces, tet_volumes, tri_areas_normals

MESH_VERSION = "linkfea-mesh-2"
"""Bumped whenever the meshing code changes the cached arrays."""

ANGULAR_TOL = 0.1
"""Tessellation angular deflection, rad: a circle becomes a >= 63-gon, whose area is 0.2% short.
(0.2 rad loses 0.7% of a circle's area, which shows in the compliance.)"""

NORMAL_COS = 0.8
"""Minimum |cos| between a mesh facet normal and the CAD face normal to count as on the face."""


def _surface(shape, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Tessellation with coincident vertices merged (OCC repeats edge vertices per face)."""
    from ..cad.step import tessellate

    V, F = tessellate(shape, tol, ANGULAR_TOL)
    U, inv = np.unique(V, axis=0, return_inverse=True)
    return U, inv.reshape(-1)[F]


def _polydata(V, F):
    import pyvista as pv

    return pv.PolyData(V, np.hstack([np.full((len(F), 1), 3), F]).astype(np.int64).ravel())


SEGMENTS_PER_CIRCLE = 8
"""A curved face of radius r gets edges of at most 2 pi r / 8 near it (the sizing field)."""

GRADING = 0.3
"""Growth of the local edge length with the distance from a small curved face (mm per mm)."""


def curved_features(shape) -> list[tuple[object, float]]:
    """(face, radius) of the cylindrical, conical, spherical and toroidal faces of ``shape``."""
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.GeomAbs import GeomAbs_Cone, GeomAbs_Cylinder, GeomAbs_Sphere, GeomAbs_Torus

    out = []
    for f in shape.Faces():
        a = BRepAdaptor_Surface(f.wrapped)
        t = a.GetType()
        if t == GeomAbs_Cylinder:
            r = a.Cylinder().Radius()
        elif t == GeomAbs_Sphere:
            r = a.Sphere().Radius()
        elif t == GeomAbs_Torus:
            r = a.Torus().MinorRadius()
        elif t == GeomAbs_Cone:
            bb = f.BoundingBox()
            r = 0.5 * min(bb.xlen, bb.ylen, bb.zlen) or 0.5 * max(bb.xlen, bb.ylen, bb.zlen)
        else:
            continue
        out.append((f, float(r)))
    return out


def sizing_field(shapes, H: float, ttol: float, edges=(), edge_size: float | None = None):
    """Background tet grid with a target edge length refined near small curved faces.

    Where a curved face of radius ``r`` would get fewer than
    :data:`SEGMENTS_PER_CIRCLE` edges around at size ``H``, the size near it is
    ``h_f = 2 pi r / 8`` and grows by :data:`GRADING` per mm away from it.
    With ``edges`` (CAD edges, the borders of the interface faces) and
    ``edge_size``, the size is also at most ``edge_size`` on those edges,
    growing by :data:`GRADING` per mm away.
    Returns ``None`` when nothing needs it (the uniform size ``H`` is used).
    """
    import cadquery as cq
    import pyvista as pv

    feats = [(f, 2.0 * np.pi * r / SEGMENTS_PER_CIRCLE) for s in shapes for f, r in curved_features(s)]
    feats = [(f, h) for f, h in feats if h < H]
    use_edges = bool(edges) and edge_size is not None and edge_size < H
    if not feats and not use_edges:
        return None
    comp = cq.Compound.makeCompound(list(shapes))
    bb = comp.BoundingBox()
    lo = np.array([bb.xmin, bb.ymin, bb.zmin]) - H
    hi = np.array([bb.xmax, bb.ymax, bb.zmax]) + H
    h_min = min([h for _, h in feats] + ([edge_size] if use_edges else []))
    step = max(h_min, float(np.linalg.norm(hi - lo)) / 50.0)
    n = np.maximum(1, np.ceil((hi - lo) / step).astype(int))
    grid = pv.ImageData(dimensions=tuple(n + 1), spacing=tuple((hi - lo) / n), origin=tuple(lo)).to_tetrahedra()
    pts = np.asarray(grid.points, dtype=float)
    vals = np.full(len(pts), float(H))
    for f, h in feats:
        Vf, Ff = _surface(f, ttol)
        _, cp = _polydata(Vf, Ff).find_closest_cell(pts, return_closest_point=True)
        vals = np.minimum(vals, h + GRADING * np.linalg.norm(pts - cp, axis=1))
    if use_edges:
        from scipy.spatial import cKDTree

        samples = np.vstack([np.array([v.toTuple() for v in e.positions(
            np.linspace(0.0, 1.0, max(2, int(np.ceil(e.Length() / (0.25 * edge_size))) + 1)))]) for e in edges])
        dist, _ = cKDTree(samples).query(pts)
        vals = np.minimum(vals, edge_size + GRADING * dist)
        # The grid is far coarser than edge_size: add the edge samples as background vertices
        # (value edge_size) so the field really reaches it on the edges, between them linear.
        from scipy.spatial import Delaunay

        keep = cKDTree(pts).query(samples)[0] > 1e-9
        allp = np.vstack([pts, samples[keep]])
        allv = np.concatenate([vals, np.full(int(keep.sum()), float(edge_size))])
        tets = Delaunay(allp).simplices.astype(np.int32)
        return allp, tets, allv
    return pts, np.asarray(grid.cells_dict[pv.CellType.TETRA], dtype=np.int32), vals


REFINE_STEPS = 4
"""pytetwild: at most this many refinements of the interface borders to pass the area gate."""

SMOOTH_COS = 0.95
"""An interface face's edge is smooth (a fillet's tangent border) when the normals of its two
faces at the edge's middle are within acos(0.95) = 18 degrees of each other."""


def smooth_border_edges(solid, faces) -> list:
    """The edges of ``faces`` where ``solid`` continues smoothly into another face (a fillet).

    fTetWild keeps its surface within the envelope of the input, so across a sharp edge it
    cannot cut the corner by more than about the envelope; across a tangent edge it can, and the
    interface face loses a strip there.  An edge shared by two of ``faces`` is no border.
    """
    import cadquery as cq
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape

    amap = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(solid.wrapped, TopAbs_EDGE, TopAbs_FACE, amap)
    own = {f.hashCode() for f in faces}
    out = []
    for i in range(1, amap.Extent() + 1):
        adj = list({cq.Face(f).hashCode(): cq.Face(f) for f in amap.FindFromIndex(i)}.values())
        mine = [f for f in adj if f.hashCode() in own]
        other = [f for f in adj if f.hashCode() not in own]
        if len(mine) != 1 or len(other) != 1:
            continue
        edge = cq.Edge(amap.FindKey(i))
        p = edge.positionAt(0.5)
        if mine[0].normalAt(p).dot(other[0].normalAt(p)) >= SMOOTH_COS:
            out.append(edge)
    return out


def mesh_with_pytetwild(link, H, block_solid, epsilon, cache_dir, use_cache, sizing, progress, area_gate) -> LinkMesh:
    """fTetWild, then, while an interface misses the area gate, a finer sizing field along its borders.

    fTetWild drops a strip about half a local edge wide along the border of an interface face
    whose edges are smooth (fillets), so the lost area scales with the edge size there: each
    step shrinks the border size by the ratio the gate needs (with a margin), by a factor 2 to 4.
    """
    edges: list = []
    edge_h = None
    for step in range(REFINE_STEPS + 1):
        m = _pytetwild_once(link, H, block_solid, epsilon, cache_dir, use_cache, sizing, progress, edges, edge_h)
        q = m.quality
        worst = max(abs(q["base_area_error"]), abs(q["tip_area_error"]))
        q["interface_border_size"] = edge_h
        if area_gate is None or worst <= area_gate:
            return m
        if step < REFINE_STEPS:
            if not edges:
                faces = link.base_faces + link.tip_faces
                # Only a smooth border loses a strip: refining the sharp ones too costs tets for nothing.
                edges = smooth_border_edges(link.body, faces) or [e for f in faces for e in f.Edges()]
            edge_h = (edge_h or H) * min(0.5, max(0.25, 0.6 * area_gate / worst))
            progress(f"interface area off by {100 * worst:.2g}%: refining the interface borders to {edge_h:.3g} mm")
    check_interface_areas(link.name, m.quality, (link.base, link.tip), area_gate)
    return m  # not reached: the gate raised


def _pytetwild_once(link, H, block_solid, epsilon, cache_dir, use_cache, sizing, progress, edges, edge_h) -> LinkMesh:
    import cadquery as cq

    whole = link.body if block_solid is None else cq.Compound.makeCompound([link.body, block_solid])
    diag = whole.BoundingBox().DiagonalLength
    if H > diag:
        raise LinkFeaError(f"mesh size {H:g} mm exceeds the part size ({diag:.3g} mm bounding-box diagonal)")
    env = epsilon * diag
    # The tessellation is what fTetWild sees; keep its chord error well inside the envelope.
    ttol = 0.25 * env
    progress("tessellating")
    Vb, Fb = _surface(link.body, ttol)
    parts = [(Vb, Fb)]
    if block_solid is not None:
        parts.append(_surface(block_solid, ttol))
    V = np.vstack([p[0] for p in parts])
    offs = np.cumsum([0] + [len(p[0]) for p in parts[:-1]])
    F = np.vstack([p[1] + o for p, o in zip(parts, offs)])

    import pytetwild

    h = hashlib.sha256()
    for p in parts:
        h.update(np.ascontiguousarray(p[0], dtype="<f8").tobytes())
        h.update(np.ascontiguousarray(p[1], dtype="<i8").tobytes())
    shapes = [link.body] + ([block_solid] if block_solid is not None else [])
    bg = sizing_field(shapes, H, ttol, edges, edge_h) if (sizing or edge_h is not None) else None
    if bg is not None:
        h.update(np.ascontiguousarray(bg[2], dtype="<f8").tobytes())
    h.update(repr((MESH_VERSION, getattr(pytetwild, "__version__", "?"), float(H), float(epsilon),
                   len(parts), bg is not None)).encode())
    key = h.hexdigest()

    def make():
        progress(f"meshing with fTetWild (edge {H:.3g} mm{', refined near small curved faces' if bg is not None else ''})")
        try:
            kw = {} if bg is None else dict(bg_vertices=bg[0], bg_tets=bg[1], bg_values=bg[2])
            with _scratch_cwd():
                points, tets = pytetwild.tetrahedralize(V, F.astype(np.int32), edge_length_abs=H,
                                                        epsilon=epsilon, quiet=True, **kw)
        except Exception as exc:  # the extension raises RuntimeError on hopeless input
            raise SolverError(f"{link.name}: fTetWild failed: {exc}") from None
        return _clean(np.asarray(points, dtype=float), np.asarray(tets, dtype=np.int64))

    if use_cache:
        points, tets = cached_mesh(Path(cache_dir) if cache_dir is not None else cache_dir_default(), key, make, progress)
    else:
        points, tets = make()
    if len(tets) == 0:
        raise LinkFeaError(f"{link.name}: the mesher produced no tetrahedra (mesh size {H:g} mm too large?)")
    progress("tagging interfaces")
    block, base_facets, tip_facets = _tag_pytetwild(link, points, tets, block_solid, env, ttol)
    return finish_mesh(link, points, tets, block, base_facets, tip_facets, block_solid, H, env,
                       key if use_cache else "", "pytetwild", getattr(pytetwild, "__version__", "?"), None)


def _clean(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orient tets positively and drop unreferenced points."""
    vol = tet_volumes(points, tets)
    neg = vol < 0
    tets = tets.copy()
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    used, inv = np.unique(tets, return_inverse=True)
    return points[used], inv.reshape(tets.shape).astype(np.int64)


@contextmanager
def _scratch_cwd():
    """fTetWild writes scratch STL files into the working directory: keep them out of the user's."""
    old = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="linkfea-ftetwild-") as d:
        os.chdir(d)
        try:
            yield
        finally:
            os.chdir(old)


def select_facets(points: np.ndarray, tris: np.ndarray, faces, tol: float, ttol: float, body=None) -> np.ndarray:
    """Mask of triangles lying on CAD ``faces``: all 3 vertices within ``tol`` and normal aligned.

    ``tol`` is the mesher's envelope (plus tessellation error), so vertices the
    mesher moved off the CAD surface are still caught.  With ``body`` (the solid the faces bound),
    a triangle is kept only when its centroid is at least as close to ``faces`` as to the body's
    other faces: a face that continues smoothly into a fillet (or the facets of a tessellated one,
    as in an STL) has neighbours within ``tol`` of its plane and nearly parallel to it, and they are
    theirs, not the interface's (on the input triangles themselves they added 3% to a 12 x 12 mm face).
    """
    if len(tris) == 0 or not faces:
        return np.zeros(len(tris), dtype=bool)
    import cadquery as cq

    Vf, Ff = _surface(cq.Compound.makeCompound(faces), ttol)
    surf = _polydata(Vf, Ff)
    _, fn = tri_areas_normals(Vf, Ff)
    lo, hi = Vf.min(0) - tol, Vf.max(0) + tol
    vid = np.unique(tris)
    near = np.zeros(len(points), dtype=bool)
    cand = vid[np.all((points[vid] >= lo) & (points[vid] <= hi), axis=1)]
    if len(cand):
        _, cp = surf.find_closest_cell(points[cand], return_closest_point=True)
        near[cand] = np.linalg.norm(points[cand] - cp, axis=1) <= tol
    sel = near[tris].all(axis=1)
    if sel.any():
        idx = np.flatnonzero(sel)
        _, tn = tri_areas_normals(points, tris[idx])
        cent = points[tris[idx]].mean(axis=1)
        cells, cp = surf.find_closest_cell(cent, return_closest_point=True)
        sel[idx] = np.abs(np.einsum("ij,ij->i", tn, fn[cells])) >= NORMAL_COS
        rest = _other_faces(body, faces, lo - tol, hi + tol) if body is not None else []
        if rest and sel.any():
            keep = np.flatnonzero(sel)
            Vr, Fr = _surface(cq.Compound.makeCompound(rest), ttol)
            _, cr = _polydata(Vr, Fr).find_closest_cell(cent[sel[idx]], return_closest_point=True)
            c = cent[sel[idx]]
            d_face = np.linalg.norm(c - cp[sel[idx]], axis=1)
            sel[keep] = d_face <= np.linalg.norm(c - cr, axis=1)
    return sel


def _other_faces(body, faces, lo, hi) -> list:
    """The faces of ``body`` other than ``faces`` whose bounding box meets the box ``lo``..``hi``."""
    own = {f.hashCode() for f in faces}
    out = []
    for f in body.Faces():
        if f.hashCode() in own:
            continue
        b = f.BoundingBox()
        if b.xmin <= hi[0] and b.xmax >= lo[0] and b.ymin <= hi[1] and b.ymax >= lo[1] and b.zmin <= hi[2] \
                and b.zmax >= lo[2]:
            out.append(f)
    return out


def _tag_pytetwild(link, points, tets, block_solid, env, ttol):
    """Block cells (centroid in the block solid) and interface facets (envelope selection) of an fTetWild mesh."""
    name = link.name
    vol = tet_volumes(points, tets)
    if np.any(vol <= 0):
        raise LinkFeaError(f"{name}: mesh has {int(np.sum(vol <= 0))} degenerate tetrahedra")
    cent = points[tets].mean(axis=1)
    block = np.zeros(len(tets), dtype=bool)
    if block_solid is not None:
        import pyvista as pv

        bV, bF = _surface(block_solid, ttol)
        bb_lo, bb_hi = bV.min(0) - env, bV.max(0) + env
        cand = np.flatnonzero(np.all((cent >= bb_lo) & (cent <= bb_hi), axis=1))
        if len(cand):
            sel = pv.PolyData(cent[cand]).select_interior_points(_polydata(bV, bF), check_surface=False)
            block[cand] = np.asarray(sel["selected_points"]).astype(bool)
        if not block.any():
            raise LinkFeaError(f"{name}: no mesh cell falls in the reference block (mesh size too large?)")

    uniq, owners, oriented = tet_faces(tets)
    boundary = owners[:, 1] < 0
    # Boundary facets of the body only: the block's outer faces are no interface.
    body_bnd = boundary & ~block[owners[:, 0]]
    tol = 1.5 * env + ttol
    bnd_tris = oriented[body_bnd]
    base_faces, tip_faces = interface_faces(link)
    base_facets = bnd_tris[select_facets(points, bnd_tris, base_faces, tol, ttol, link.body)]
    if block_solid is not None:
        two = ~boundary
        iface = two & (block[owners[:, 0]] != block[np.maximum(owners[:, 1], 0)])
        tip_facets = oriented[iface]
    else:
        tip_facets = bnd_tris[select_facets(points, bnd_tris, tip_faces, tol, ttol, link.body)]
    return block, base_facets, tip_facets


