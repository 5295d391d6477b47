"""The tetrahedral mesh of a link (:class:`LinkMesh`), its geometry, and the checks both meshers end in.

:mod:`linkfea.mesh.gmsh` and :mod:`linkfea.mesh.pytetwild` hand their raw arrays to
:func:`finish_mesh`: the quality report and the interface-area gate (a base or tip area
more than :data:`AREA_GATE` off its CAD faces is an error, never a silent number).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..mechanics.frames import Frame
from ..runtime.errors import LinkFeaError

AREA_GATE = 0.01
"""Largest relative difference between an interface's mesh area and its CAD faces' area."""


SLIVER_SHARE = 0.2
"""Share of tets with a radius ratio below 0.1 (``quality["n_poor_tets"]``) above which a mesh is called
unreliable: the meshes of STEP files and scripts (gmsh) and of triangle surfaces (pytetwild) have few (a
coarse gmsh mesh of a small bar, 4%); gmsh on an exported STL (every thin triangle a face) had 66%, and a
compliance 0.5-5.7% too stiff."""


def sliver_warning(name: str, quality: dict, n_tets: int, mesher: str) -> str:
    """The warning for a mesh of slivers (see :data:`SLIVER_SHARE`), or ''."""
    poor = int(quality.get("n_poor_tets", 0))
    if n_tets <= 0 or poor <= SLIVER_SHARE * n_tets:
        return ""
    hint = ("; gmsh meshes every triangle of a surface file as a face: use --mesher pytetwild (the default "
            "for STL, OBJ and PLY)" if mesher == "gmsh" else "; try another --mesh-size or mesher")
    return (f"{name}: {100 * poor / n_tets:.0f}% of the mesh's tets are slivers (radius ratio below 0.1, the worst "
            f"{quality.get('radius_ratio_min', float('nan')):.2g}): the compliance is unreliable (too stiff){hint}")


@dataclass(frozen=True)
class LinkMesh:
    """A linear tetrahedral mesh of a link, ready for P2 analysis.

    Attributes
    ----------
    points : ndarray (n, 3)
        Vertex coordinates in CAD coordinates, mm.
    tets : ndarray (m, 4) int
        Positively oriented tetrahedra.
    block : ndarray (m,) bool
        True for cells of the pseudo-rigid reference block.
    base_facets : ndarray (k, 3) int
        Boundary triangles of the clamped base interface.
    tip_facets : ndarray (k2, 3) int
        Boundary (or body/block interface) triangles of the tip interface.
    frame : Frame
        The link's reference frame (origin at the tip interface centroid, x along the link).
    edge_length : float
        Target edge length used for meshing, mm.
    envelope : float
        Surface envelope of the mesher, mm: how far boundary vertices may sit from the CAD.
    quality : dict
        Mesh quality report (e.g. min/mean scaled Jacobian or aspect ratio).
    cache_key : str
        SHA-256 key of the cached raw mesh ('' if not cached).
    mesher : str
        ``"gmsh"`` or ``"pytetwild"`` ('' for meshes built by hand).
    mesher_version : str
        Version of the mesher's package.
    curved_edges, curved_points : ndarray (k, 2) int and (k, 3), or None
        Second-order geometry: mesh edges (vertex pairs) whose P2 node lies off the midpoint, on
        the CAD surface (gmsh), and those nodes; None for straight-sided P2 (pytetwild).
    """

    points: np.ndarray
    tets: np.ndarray
    block: np.ndarray
    base_facets: np.ndarray
    tip_facets: np.ndarray
    frame: Frame
    edge_length: float
    envelope: float = 0.0
    quality: dict = field(default_factory=dict)
    cache_key: str = ""
    mesher: str = ""
    mesher_version: str = ""
    curved_edges: np.ndarray | None = None
    curved_points: np.ndarray | None = None

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    @property
    def n_tets(self) -> int:
        return len(self.tets)


def tet_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes of tetrahedra (positive for the orientation used here)."""
    a = points[tets]
    return np.einsum("ij,ij->i", np.cross(a[:, 1] - a[:, 0], a[:, 2] - a[:, 0]), a[:, 3] - a[:, 0]) / 6.0


def tri_areas_normals(points: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Areas (k,) and unit normals (k, 3) of triangles (right-hand rule)."""
    a = points[tris]
    c = np.cross(a[:, 1] - a[:, 0], a[:, 2] - a[:, 0])
    n2 = np.linalg.norm(c, axis=1)
    return 0.5 * n2, c / np.maximum(n2, 1e-300)[:, None]


# Faces of tet (0,1,2,3) ordered so their right-hand normal points outward for positive volume.
_TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])


def tet_faces(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All faces, grouped: (unique sorted faces (f,3), owner cells (f,2) with -1 for none, oriented faces (f,3)).

    The oriented face is the one seen from the first owner, outward from it.
    """
    m = len(tets)
    faces = tets[:, _TET_FACES].reshape(-1, 3)  # (4m, 3) outward from their cell
    cell = np.repeat(np.arange(m), 4)
    key = np.sort(faces, axis=1)
    uniq, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    if cnt.max() > 2:
        raise LinkFeaError("mesh: a face is shared by more than two tetrahedra (non-manifold mesh)")
    order = np.argsort(inv, kind="stable")
    starts = np.r_[0, np.cumsum(cnt)[:-1]]
    owners = -np.ones((len(uniq), 2), dtype=np.int64)
    owners[:, 0] = cell[order[starts]]
    two = cnt == 2
    owners[two, 1] = cell[order[starts[two] + 1]]
    oriented = faces[order[starts]]
    return uniq, owners, oriented


def radius_ratio(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Normalised radius ratio 3 r_in / R_circ per tet (1 = regular, 0 = degenerate)."""
    a = points[tets]
    vol = np.abs(tet_volumes(points, tets))
    faces = a[:, _TET_FACES]  # (m, 4, 3, 3)
    fa = 0.5 * np.linalg.norm(np.cross(faces[:, :, 1] - faces[:, :, 0], faces[:, :, 2] - faces[:, :, 0]), axis=2)
    r_in = 3.0 * vol / fa.sum(axis=1)
    # circumradius: |a^2 (b x c) + b^2 (c x a) + c^2 (a x b)| / (12 V) with edges from vertex 0
    b, c, d = a[:, 1] - a[:, 0], a[:, 2] - a[:, 0], a[:, 3] - a[:, 0]
    num = (np.einsum("ij,ij->i", b, b)[:, None] * np.cross(c, d) + np.einsum("ij,ij->i", c, c)[:, None] * np.cross(d, b)
           + np.einsum("ij,ij->i", d, d)[:, None] * np.cross(b, c))
    R = np.linalg.norm(num, axis=1) / np.maximum(12.0 * vol, 1e-300)
    return 3.0 * r_in / np.maximum(R, 1e-300)


def finish_mesh(link, points, tets, block, base_facets, tip_facets, block_solid, H, env, key, mesher, version,
                area_gate: float | None = AREA_GATE) -> LinkMesh:
    """Check the interfaces, measure the quality against the CAD, apply the area gate, build the :class:`LinkMesh`."""
    from ..cad.selectors import faces_area_centroid

    name = link.name
    vol = tet_volumes(points, tets)
    if np.any(vol <= 0):
        raise LinkFeaError(f"{name}: mesh has {int(np.sum(vol <= 0))} degenerate tetrahedra")
    base_faces, tip_faces = link.base_faces, link.tip_faces
    if len(base_facets) == 0:
        raise LinkFeaError(f"{name}: base selector {link.base} matches no mesh facet")
    if len(tip_facets) == 0:
        raise LinkFeaError(f"{name}: tip selector {link.tip} matches no mesh facet")
    if np.intersect1d(base_facets, tip_facets).size or (block.any() and np.intersect1d(base_facets, tets[block]).size):
        raise LinkFeaError(f"{name}: base and tip interfaces overlap in the mesh ({link.base} / {link.tip})")

    A_base_cad, _ = faces_area_centroid(base_faces)
    A_tip_cad, _ = faces_area_centroid(tip_faces)
    A_base = tri_areas_normals(points, base_facets)[0].sum()
    A_tip = tri_areas_normals(points, tip_facets)[0].sum()
    cad_vol = link.body.Volume() + (block_solid.Volume() if block_solid is not None else 0.0)
    rr = radius_ratio(points, tets)
    edges = np.unique(np.sort(np.concatenate([tets[:, [i, j]] for i, j in
                                              ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))]), axis=1), axis=0)
    el = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    quality = {
        "radius_ratio_min": float(rr.min()),
        "radius_ratio_mean": float(rr.mean()),
        "n_poor_tets": int(np.sum(rr < 0.1)),
        "edge_min": float(el.min()),
        "edge_mean": float(el.mean()),
        "edge_max": float(el.max()),
        "volume_error": float(vol.sum() / cad_vol - 1.0),
        "block_volume": float(vol[block].sum()),
        "base_area_error": float(A_base / A_base_cad - 1.0),
        "tip_area_error": float(A_tip / A_tip_cad - 1.0),
        "n_base_facets": int(len(base_facets)),
        "n_tip_facets": int(len(tip_facets)),
        "note": "radius ratio 3 r_in / R_circ (1 = regular tet); errors relative to the CAD",
    }
    if area_gate is not None:
        check_interface_areas(name, quality, (link.base, link.tip), area_gate)
    return LinkMesh(points=points, tets=tets, block=block, base_facets=base_facets, tip_facets=tip_facets,
                    frame=link.frame, edge_length=float(H), envelope=float(env), quality=quality, cache_key=key,
                    mesher=mesher, mesher_version=str(version))


def check_interface_areas(name: str, quality: dict, selectors, limit: float = AREA_GATE) -> None:
    """The interface-area gate: an error naming the face and the figure if an interface is off by more than ``limit``."""
    for which, sel in zip(("base", "tip"), selectors):
        err = quality[f"{which}_area_error"]
        if not abs(err) <= limit:
            raise LinkFeaError(f"{name}: the {which} interface ({sel}): mesh area differs from its CAD faces' "
                               f"area by {100 * err:+.2f}% (limit {100 * limit:g}%); refine the mesh or use "
                               "the other mesher")

