"""CAD-conforming tetrahedral meshing of a link with gmsh (OpenCASCADE kernel).

The body (and in block mode the reference block) is handed to gmsh as a BREP
file in a temporary folder; gmsh reads it with its own OpenCASCADE, so every
CAD face becomes a gmsh surface and every surface node lies on its CAD face.
In block mode body and block are fused by an OCC *fragment*: the faces they
share become one surface meshed once, so the body-block interface is
conforming whatever its shape (a plane, a bore).

The base and tip CAD faces are found among gmsh's surfaces by centre of mass
and area (never by tag order, which depends on the import and the fragment).
In block mode the tip interface is the set of surfaces the body and block
volumes share after the fragment (a seam of the block may split a tip face);
the area gate then checks it against the CAD tip faces.

Determinism: one thread, fixed 2D and 3D algorithms and gmsh's fixed random
seed; the same input gives the same arrays bit for bit, so no mesh cache is
needed (meshing takes well under a second on the bundled links).
"""
from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..runtime.errors import LinkFeaError, SolverError
from .linkmesh import tet_volumes

SEGMENTS_PER_CIRCLE = 16
"""``Mesh.MeshSizeFromCurvature``: elements per 2 pi of a curved face's radius.  16 keeps the
facet area of a cylinder within 0.7% of the CAD area (perimeter of a 16-gon), under the 1%
interface-area gate, which 8 (2.6%) and 12 (1.1%) are not."""

EDGE_SEGMENTS_PER_CIRCLE = 64
"""Curved edges bounding an interface face get at most 2 pi r / 64 long segments: a planar face
bounded by a circle then meshes to 99.84% of its area (the chord error, (2 pi / 64)^2 / 6),
well inside the 1% gate.  Elsewhere the curvature rule above applies."""

EDGE_GRADING = 0.3
"""Growth of the edge length away from a refined interface edge (mm per mm)."""

MIN_SIZE_FACTOR = 0.1
"""Smallest edge length allowed by the curvature rule, as a fraction of the target size:
a tiny fillet does not explode the element count."""

REFINED_MIN_SIZE_FACTOR = 0.01
"""Smallest edge length the error-driven refinement (``size_at``) may ask for, as a fraction of ``H``."""

CORNER_SIZE_FACTOR = 1.0
"""Edge length on the concave (re-entrant) CAD edges, as a fraction of the target size."""

INTERFACE_SIZE_FACTOR = 1.0
"""Edge length on the edges bounding the base and tip faces, as a fraction of the target size."""

FEATURE_GRADING = 0.3
"""Growth of the edge length away from a refined concave or interface edge (mm per mm)."""

ALGORITHM_2D = 6
"""Frontal-Delaunay for the surfaces."""

ALGORITHM_3D = 1
"""Delaunay for the volume (single-threaded, deterministic)."""

MATCH_TOL = 1e-6
"""Relative tolerance of the face matching (area, and centre of mass against the part size)."""


@dataclass(frozen=True)
class GmshMesh:
    """The raw output of :func:`mesh_gmsh`: linear tets and the interface triangles (indices into points)."""

    points: np.ndarray
    tets: np.ndarray
    block: np.ndarray
    base_facets: np.ndarray
    tip_facets: np.ndarray
    curved_edges: np.ndarray | None = None
    curved_points: np.ndarray | None = None




def version() -> str:
    import gmsh

    return str(gmsh.__version__)


def _face_key(face) -> tuple[float, np.ndarray]:
    return float(face.Area()), np.array(face.Center().toTuple(), dtype=float)


def match_surfaces(cad_faces, surfaces: dict[int, tuple[float, np.ndarray]], size: float, what: str) -> list[int]:
    """gmsh surface tags of ``cad_faces``, matched by area and centre of mass.

    ``surfaces`` maps a gmsh surface tag to its (area, centre of mass).  Each
    CAD face must match exactly one surface: the nearest one whose area and
    centre agree within :data:`MATCH_TOL` (relative to the area and to the
    part size ``size``).
    """
    tags = np.array(sorted(surfaces))
    areas = np.array([surfaces[t][0] for t in tags])
    cents = np.array([surfaces[t][1] for t in tags])
    out = []
    for f in cad_faces:
        a, c = _face_key(f)
        da = np.abs(areas - a) / max(a, 1e-300)
        dc = np.linalg.norm(cents - c, axis=1) / size
        ok = np.flatnonzero((da <= MATCH_TOL) & (dc <= MATCH_TOL))
        if len(ok) == 0:
            raise LinkFeaError(f"{what}: CAD face of area {a:.6g} mm^2 at {np.round(c, 4).tolist()} has no "
                               "matching gmsh surface")
        out.append(int(tags[ok[np.argmin(dc[ok] + da[ok])]]))
    if len(set(out)) != len(out):
        raise LinkFeaError(f"{what}: two CAD faces match the same gmsh surface")
    return out


def _options(gmsh, H: float, threads: int = 1) -> None:
    opt = gmsh.option.setNumber
    opt("General.Terminal", 0)
    opt("General.Verbosity", 1)
    opt("General.NumThreads", threads)
    opt("Mesh.MaxNumThreads1D", threads)
    opt("Mesh.MaxNumThreads2D", threads)
    opt("Mesh.MaxNumThreads3D", threads)
    opt("Mesh.Algorithm", ALGORITHM_2D)
    opt("Mesh.Algorithm3D", ALGORITHM_3D)
    opt("Mesh.MeshSizeMax", H)
    opt("Mesh.MeshSizeMin", MIN_SIZE_FACTOR * H)
    opt("Mesh.MeshSizeFromCurvature", SEGMENTS_PER_CIRCLE)
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeExtendFromBoundary", 1)
    opt("Mesh.ElementOrder", 1)
    opt("Mesh.Optimize", 1)
    opt("Geometry.OCCFixDegenerated", 0)
    opt("Geometry.OCCFixSmallEdges", 0)
    opt("Geometry.OCCFixSmallFaces", 0)
    opt("Geometry.OCCSewFaces", 0)
    opt("Geometry.OCCScaling", 1.0)


def _curve_radius(gmsh, curve: int) -> float:
    """Smallest radius of curvature of a gmsh curve (inf for a straight one), from 9 samples."""
    lo, hi = gmsh.model.getParametrizationBounds(1, curve)
    u = np.linspace(lo[0], hi[0], 9)
    k = np.abs(np.asarray(gmsh.model.getCurvature(1, curve, u), dtype=float))
    k = k[np.isfinite(k)]
    return float(1.0 / k.max()) if len(k) and k.max() > 1e-9 else float("inf")


def _interface_edge_fields(gmsh, surfaces: list[int], H: float) -> list[int]:
    """Size fields along the curved edges of the planar interface faces (:data:`EDGE_SEGMENTS_PER_CIRCLE`).

    Curved interface faces (a bore) are left to the curvature rule: their chord error is the
    surface's own, which finer edges would not remove.
    """
    planar = [s for s in surfaces if gmsh.model.getType(2, s) == "Plane"]
    if not planar:
        return []
    curves = sorted({abs(t) for _, t in gmsh.model.getBoundary([(2, s) for s in planar], combined=False,
                                                              oriented=False)})
    sizes: dict[float, list[int]] = {}
    for c in curves:
        h = 2.0 * np.pi * _curve_radius(gmsh, c) / EDGE_SEGMENTS_PER_CIRCLE
        if h < H:
            sizes.setdefault(round(max(h, MIN_SIZE_FACTOR * H), 9), []).append(c)
    return [_threshold(gmsh, cs, h, H, EDGE_GRADING) for h, cs in sorted(sizes.items())]


def _threshold(gmsh, curves: list[int], h: float, H: float, grading: float) -> int:
    """A gmsh field: size ``h`` on ``curves``, growing by ``grading`` per mm up to ``H``."""
    f = gmsh.model.mesh.field
    d = f.add("Distance")
    f.setNumbers(d, "CurvesList", curves)
    f.setNumber(d, "Sampling", 100)
    t = f.add("Threshold")
    f.setNumber(t, "InField", d)
    f.setNumber(t, "SizeMin", h)
    f.setNumber(t, "SizeMax", H)
    f.setNumber(t, "DistMin", 0.0)
    f.setNumber(t, "DistMax", (H - h) / grading)
    return t


TRIANGLE_KINK = 0.5
"""|n1 - n2| below which two triangle faces (an STL's) meet at no corner: 0.5 is 29 degrees.  A
tessellated fillet or bore kinks by the exporter's angular tolerance (a few to some 20 degrees) at
every triangle edge; taken as corners they would be hundreds of false singularities."""


def concave_edges(solid) -> list:
    """The concave (re-entrant) edges of a CAD solid, where the stress is singular.

    At the middle ``p`` of an edge shared by two faces with outward normals ``n1`` and ``n2``,
    the point ``p + d (n1 - n2)`` lies inside the solid exactly when the edge is concave (the
    material is the union of the two half-spaces there, not their intersection).  Tangent
    edges (``n1 ~ n2``, a fillet's border) are not corners.  Between two planar triangles (a
    triangle surface made solid) the test needs no point classification: the edge is concave when
    the third corner of one triangle lies outside the other's plane; kinks below
    :data:`TRIANGLE_KINK` are the tessellation of a smooth surface, not corners.
    """
    import cadquery as cq
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape

    amap = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(solid.wrapped, TopAbs_EDGE, TopAbs_FACE, amap)
    d = 1e-4 * float(solid.BoundingBox().DiagonalLength)
    out = []
    for i in range(1, amap.Extent() + 1):
        faces = {cq.Face(f).hashCode(): cq.Face(f) for f in amap.FindFromIndex(i)}
        if len(faces) != 2:
            continue
        edge = cq.Edge(amap.FindKey(i))
        p = edge.positionAt(0.5)
        f1, f2 = faces.values()
        n = f1.normalAt(p) - f2.normalAt(p)
        v1, v2 = f1.Vertices(), f2.Vertices()
        if len(v1) == 3 and len(v2) == 3 and f1.geomType() == "PLANE" and f2.geomType() == "PLANE":
            if n.Length < TRIANGLE_KINK:
                continue
            ends = {v.hashCode() for v in edge.Vertices()}
            third = [v for v in v1 if v.hashCode() not in ends]
            if third and f2.normalAt(p).dot(cq.Vector(third[0].toTuple()) - p) > d:
                out.append(edge)
            continue
        if n.Length < 0.1:
            continue
        if solid.isInside(p + n * d, tolerance=0.1 * d):
            out.append(edge)
    return out


def _corner_fields(gmsh, solid, curves: list[int], H: float) -> list[int]:
    """A size field along the concave edges of ``solid`` (:data:`CORNER_SIZE_FACTOR`), matched to
    gmsh ``curves`` by length and centre of mass; an edge gmsh split (a fragment) is left out."""
    h = CORNER_SIZE_FACTOR * H
    if h >= H:
        return []
    occ = gmsh.model.occ
    cand = {c: (float(occ.getMass(1, c)), np.array(occ.getCenterOfMass(1, c))) for c in curves}
    size = float(solid.BoundingBox().DiagonalLength)
    tags = []
    for e in concave_edges(solid):
        L, c = float(e.Length()), np.array(e.Center().toTuple())
        for t, (Lt, ct) in cand.items():
            if abs(Lt - L) <= MATCH_TOL * L and np.linalg.norm(ct - c) <= MATCH_TOL * size:
                tags.append(t)
                break
    return [_threshold(gmsh, sorted(set(tags)), h, H, FEATURE_GRADING)] if tags else []


def _size_fields(gmsh, solid, body_vols: list[int], interfaces: list[int], H: float) -> None:
    """The background size: the smallest of the interface-edge, interface-border and corner fields."""
    fields = _interface_edge_fields(gmsh, interfaces, H)
    if INTERFACE_SIZE_FACTOR < 1.0:
        curves = sorted({abs(t) for _, t in gmsh.model.getBoundary([(2, s) for s in interfaces], combined=False,
                                                                  oriented=False)})
        fields.append(_threshold(gmsh, curves, INTERFACE_SIZE_FACTOR * H, H, FEATURE_GRADING))
    bnd = gmsh.model.getBoundary([(3, v) for v in body_vols], combined=False, oriented=False)
    surf = sorted({abs(t) for _, t in bnd})
    curves = sorted({abs(t) for _, t in gmsh.model.getBoundary([(2, s) for s in surf], combined=False,
                                                              oriented=False)})
    fields += _corner_fields(gmsh, solid, curves, H)
    if not fields:
        return
    f = gmsh.model.mesh.field
    m = f.add("Min")
    f.setNumbers(m, "FieldsList", fields)
    f.setAsBackgroundMesh(m)


def _curved_edge_nodes(gmsh, vols: list[int], points: np.ndarray, elements):
    """Second-order geometry of the boundary: each mesh edge on a curved CAD face or edge, as a vertex
    pair (indices into ``points``) and its midpoint projected onto that face or edge (gmsh's
    closest point on the OCC geometry; an edge on a CAD edge goes onto the CAD edge).  Planar faces
    and straight CAD edges keep their midpoints, so they are skipped.
    """
    surfs = sorted({abs(t) for _, t in gmsh.model.getBoundary([(3, v) for v in vols], combined=False,
                                                             oriented=False)})
    curves = sorted({abs(t) for _, t in gmsh.model.getBoundary([(2, s) for s in surfs], combined=False,
                                                              oriented=False)})
    found = []
    for dim, ents, skip, etype, nn, local in ((2, surfs, "Plane", 2, 3, [[0, 1], [1, 2], [2, 0]]),
                                               (1, curves, "Line", 1, 2, [[0, 1]])):
        for e in ents:
            if gmsh.model.getType(dim, e) == skip:
                continue
            el = elements(dim, e, etype, nn)
            if len(el) == 0:
                continue
            pairs = np.unique(np.sort(el[:, local].reshape(-1, 2), axis=1), axis=0)
            mid = 0.5 * (points[pairs[:, 0]] + points[pairs[:, 1]])
            proj, _ = gmsh.model.getClosestPoint(dim, e, mid.ravel())
            found.append((pairs, np.asarray(proj, dtype=float).reshape(-1, 3)))
    if not found:
        return np.zeros((0, 2), dtype=np.int64), np.zeros((0, 3))
    # An edge on a CAD edge also borders its faces: the CAD edge's projection (listed last) wins.
    pairs = np.vstack([p for p, _ in found])[::-1]
    proj = np.vstack([q for _, q in found])[::-1]
    n = len(points)
    _, first = np.unique(pairs[:, 0] * n + pairs[:, 1], return_index=True)
    return pairs[first], proj[first]


def mesh_gmsh(name: str, body, block, base_faces, tip_faces, H: float, curved: bool = False,
              size_at=None) -> GmshMesh:
    """Mesh ``body`` (and ``block``, fragment-fused) at target size ``H`` mm; see the module docstring.

    ``base_faces`` and ``tip_faces`` are CAD faces of ``body``.  Returns
    positively oriented tets, the block flag per tet, and the triangles of the
    base and tip surfaces.  With ``curved``, the mesh gets second-order geometry on its boundary
    (:func:`_curved_edge_nodes`): ``curved_edges`` (k, 2) are the vertex pairs whose P2 node is
    not the midpoint, ``curved_points`` (k, 3) those nodes, on the CAD faces.  ``size_at(x, y, z)``
    (mm), if given, caps the local size further (gmsh's size callback; down to
    :data:`REFINED_MIN_SIZE_FACTOR` of ``H``).
    """
    import gmsh

    if gmsh.isInitialized():
        raise LinkFeaError("gmsh is already in use in this process (nested meshing is not supported)")
    size = float(body.BoundingBox().DiagonalLength)
    with tempfile.TemporaryDirectory(prefix="linkfea-gmsh-") as d:
        gmsh.initialize(readConfigFiles=False, interruptible=False)
        try:
            _options(gmsh, H)
            gmsh.model.add(name or "link")
            occ = gmsh.model.occ
            files = []
            for nm, s in (("body", body), ("block", block)):
                if s is not None:
                    p = str(Path(d) / f"{nm}.brep")
                    s.exportBrep(p)
                    files.append(p)
            body_dt = occ.importShapes(files[0], highestDimOnly=True)
            if block is not None:
                block_dt = occ.importShapes(files[1], highestDimOnly=True)
                _, outmap = occ.fragment(body_dt, block_dt)
                body_vols = sorted({t for dim, t in outmap[0] if dim == 3})
                block_vols = sorted({t for dim, t in outmap[1] if dim == 3} - set(body_vols))
            else:
                body_vols = sorted(t for dim, t in body_dt if dim == 3)
                block_vols = []
            occ.synchronize()
            if not body_vols:
                raise LinkFeaError(f"{name}: gmsh found no volume in the body")
            # Candidate surfaces: the boundary of the body volumes (the base and tip faces are body faces).
            bnd = gmsh.model.getBoundary([(3, v) for v in body_vols], combined=False, oriented=False)
            cand = sorted({abs(t) for dim, t in bnd if dim == 2})
            surfaces = {t: (float(occ.getMass(2, t)), np.array(occ.getCenterOfMass(2, t))) for t in cand}
            base_s = match_surfaces(base_faces, surfaces, size, f"{name}: base")
            if block_vols:
                # The fragment may split a tip face where the block's own edges (a seam) cross it;
                # the conforming interface is exactly the surfaces body and block share.
                bb = gmsh.model.getBoundary([(3, v) for v in block_vols], combined=False, oriented=False)
                tip_s = sorted(set(cand) & {abs(t) for dim, t in bb if dim == 2})
                if not tip_s:
                    raise LinkFeaError(f"{name}: the block shares no face with the body after the fragment")
            else:
                tip_s = match_surfaces(tip_faces, surfaces, size, f"{name}: tip")
            _size_fields(gmsh, body, body_vols, base_s + tip_s, H)
            if size_at is not None:
                gmsh.option.setNumber("Mesh.MeshSizeMin", REFINED_MIN_SIZE_FACTOR * H)
                gmsh.model.mesh.setSizeCallback(lambda dim, tag, x, y, z, lc: min(lc, float(size_at(x, y, z))))
            try:
                gmsh.model.mesh.generate(3)
            except Exception as exc:  # gmsh raises a bare Exception with its last error
                raise SolverError(f"{name}: gmsh failed to mesh the link: {exc}") from None
            tags, coords, _ = gmsh.model.mesh.getNodes()
            points = np.asarray(coords, dtype=float).reshape(-1, 3)
            index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
            index[tags] = np.arange(len(tags))

            def elements(dim, ent, etype, nn):
                types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
                out = [np.asarray(n, dtype=np.int64).reshape(-1, nn) for ty, n in zip(types, nodes) if ty == etype]
                return index[np.vstack(out)] if out else np.zeros((0, nn), dtype=np.int64)

            parts = [(elements(3, v, 4, 4), False) for v in body_vols] + [(elements(3, v, 4, 4), True)
                                                                         for v in block_vols]
            tets = np.vstack([p for p, _ in parts])
            block_flag = np.concatenate([np.full(len(p), b) for p, b in parts])
            base_tris = np.vstack([elements(2, s, 2, 3) for s in base_s])
            tip_tris = np.vstack([elements(2, s, 2, 3) for s in tip_s])
            if curved:
                mid_pairs, mid_points = _curved_edge_nodes(gmsh, body_vols + block_vols, points, elements)
        finally:
            gmsh.finalize()
    if len(tets) == 0:
        raise LinkFeaError(f"{name}: gmsh produced no tetrahedra (mesh size {H:g} mm too large?)")
    # Keep only the points the tets use, in first-use order of their sorted tags (deterministic).
    used, inv = np.unique(tets, return_inverse=True)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    tets = inv.reshape(tets.shape).astype(np.int64)
    base_tris, tip_tris = remap[base_tris], remap[tip_tris]
    if (base_tris < 0).any() or (tip_tris < 0).any():
        raise LinkFeaError(f"{name}: an interface triangle has a node outside the volume mesh")
    curved_edges = curved_points = None
    if curved:
        pairs = np.sort(remap[mid_pairs], axis=1)
        off = np.linalg.norm(mid_points - 0.5 * (points[mid_pairs[:, 0]] + points[mid_pairs[:, 1]]), axis=1)
        keep = (off > 1e-12 * float(np.ptp(points[used], axis=0).max())) & (pairs >= 0).all(axis=1)
        curved_edges, curved_points = pairs[keep], mid_points[keep]
    points = points[used]
    neg = tet_volumes(points, tets) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return GmshMesh(points=points, tets=tets, block=block_flag, base_facets=base_tris, tip_facets=tip_tris,
                    curved_edges=curved_edges, curved_points=curved_points)
