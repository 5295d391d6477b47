"""P2 (10-node tetrahedron) topology and the vectorized isotropic elasticity assembly.

The link mesh is a linear tet mesh; :func:`p2_mesh` promotes it to 10-node quadratic tets (the
4 vertices, then the midpoints of edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3) -- the order of
scikit-fem's ``ElementTetP2``, VTK's ``QUADRATIC_TETRA`` and CalculiX's C3D10 alike).

Global numbering: P2 node ``n`` is vertex ``n`` for ``n < n_vertices``, then one node per
unique mesh edge; degree of freedom ``3 n + c`` is component ``c`` (CAD axes) of node ``n``.
:func:`assemble_upper` is an exact, vectorized form of scikit-fem's ``linear_elasticity`` on
``ElementTetP2`` (tests/linkfea/test_fem_assembly.py checks it against ``skfem.asm``).

Units: N, mm, MPa.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np
import scipy.sparse as sp

from ..mechanics.materials import Material
from ..runtime.errors import LinkFeaError

# Local edges of a tet, in the P2 node order 4..9.
TET_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])


# --------------------------------------------------------------------------
# P2 topology
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class P2Mesh:
    """Quadratic-tet discretization of a linear tet mesh, owned by scikit-fem.

    scikit-fem's ``MeshTet`` and ``ElementTetP2`` define the P2 nodes, their numbering
    (vertices, then one node per mesh edge), their locations and the facets; the
    attributes below are views of that, in the layout the assembly kernel and the
    writers (VTK, CalculiX) use.

    Attributes
    ----------
    points : ndarray (N, 3)
        P2 node coordinates (scikit-fem's DOF locations): vertices, then edge midpoints.
    cells : ndarray (m, 10) int
        P2 nodes of each tet (scikit-fem's element DOFs: vertices, then edges in
        ``TET_EDGES`` order).
    edges : ndarray (E, 2) int
        Vertex pairs (sorted) of the mesh edges; edge ``e`` is node ``n_vertices + e``.
    n_vertices : int
    mesh : skfem.MeshTet
    dofs : skfem.assembly.Dofs
        Of the scalar ``ElementTetP2``: DOF ``n`` is P2 node ``n``; vector DOF ``3 n + c``
        is component ``c`` of node ``n`` (scikit-fem's ``ElementVector`` numbering).
    curved : ndarray (m,) bool or None
        Cells with a mid-edge node off its edge's midpoint (second-order geometry: a boundary
        edge on a curved CAD face).  They are integrated isoparametrically; None: all straight.
    """

    points: np.ndarray
    cells: np.ndarray
    edges: np.ndarray
    n_vertices: int
    mesh: Any = field(default=None, repr=False)
    dofs: Any = field(default=None, repr=False)
    curved: Optional[np.ndarray] = field(default=None, repr=False)

    def facet_index(self, facets: np.ndarray) -> np.ndarray:
        """Indices into scikit-fem's ``mesh.facets`` of triangles ``facets`` (k, 3) given by vertices."""
        facets = np.asarray(facets, dtype=np.int64).reshape(-1, 3)
        nv = self.n_vertices
        if len(facets) and (facets.min() < 0 or facets.max() >= nv):
            raise LinkFeaError("interface facets refer to vertices that are not in the mesh")
        if nv >= 2**21:
            raise LinkFeaError(f"mesh too large for facet lookup ({nv} vertices)")
        ours = np.sort(facets, axis=1)
        theirs = np.asarray(self.mesh.facets, dtype=np.int64)  # (3, nf), each column sorted
        key = (ours[:, 0] * nv + ours[:, 1]) * nv + ours[:, 2]
        fkey = (theirs[0] * nv + theirs[1]) * nv + theirs[2]
        order = np.argsort(fkey)
        pos = np.minimum(np.searchsorted(fkey, key, sorter=order), len(fkey) - 1)
        idx = order[pos]
        if not np.all(fkey[idx] == key):
            raise LinkFeaError("interface facets are not faces of the tet mesh")
        return idx

    def facet_nodes(self, facets: np.ndarray) -> np.ndarray:
        """Sorted unique P2 nodes (vertices and edge midpoints) of triangles ``facets`` (k, 3):
        scikit-fem's DOFs of those facets."""
        idx = self.facet_index(facets)
        if len(idx) == 0:
            return np.zeros(0, dtype=np.int64)
        return np.unique(np.asarray(self.dofs.get_facet_dofs(idx).flatten(), dtype=np.int64))


def p2_mesh(points: np.ndarray, tets: np.ndarray, curved_edges: Optional[np.ndarray] = None,
            curved_points: Optional[np.ndarray] = None) -> P2Mesh:
    """Promote a linear tet mesh to P2 with scikit-fem (``MeshTet``, ``ElementTetP2`` DOFs).

    The tets keep their vertex order (``sort_t=False``): the kernel needs the given,
    positive orientation.  ``curved_edges`` (k, 2) vertex pairs and ``curved_points`` (k, 3)
    move those edges' nodes off the midpoints (second-order geometry, e.g. gmsh's mid-edge
    nodes on the CAD surfaces); a cell whose curved map would fold (Jacobian not positive at
    a quadrature point) gets its edges straightened back.
    """
    import skfem
    from skfem.assembly import Dofs

    points = np.asarray(points, dtype=float)
    tets = np.asarray(tets, dtype=np.int64)
    if points.ndim != 2 or points.shape[1] != 3 or tets.ndim != 2 or tets.shape[1] != 4:
        raise LinkFeaError(f"mesh must have points (n, 3) and tets (m, 4), got {points.shape} and {tets.shape}")
    if len(tets) == 0:
        raise LinkFeaError("mesh has no tetrahedra")
    nv = len(points)
    if tets.min() < 0 or tets.max() >= nv:
        raise LinkFeaError("tets refer to points that do not exist")
    # C-contiguous (n_dim, n) arrays: scikit-fem would copy them itself, with a warning each.
    mesh = skfem.MeshTet(np.ascontiguousarray(points.T), np.ascontiguousarray(tets.T), sort_t=False, validate=False)
    element = skfem.ElementTetP2()
    dofs = Dofs(mesh, element)
    cells = np.asarray(dofs.element_dofs.T, dtype=np.int64)
    # DOF locations: scikit-fem maps the element's reference DOF locations to each tet.
    X = mesh.mapping().F(np.asarray(element.doflocs, dtype=float).T)  # (3, m, 10)
    pts = np.empty((int(dofs.N), 3))
    pts[cells.ravel()] = X.transpose(1, 2, 0).reshape(-1, 3)
    pts[:nv] = points  # vertices exactly as given
    edges = np.asarray(mesh.edges.T, dtype=np.int64)
    curved = None
    if curved_edges is not None and len(curved_edges):
        pts, curved = _curve_edges(pts, cells, edges, nv, np.asarray(curved_edges, dtype=np.int64),
                                   np.asarray(curved_points, dtype=float))
    return P2Mesh(pts, cells, edges, nv, mesh, dofs, curved)


def link_p2(mesh) -> P2Mesh:
    """The P2 mesh of a :class:`linkfea.mesh.linkmesh.LinkMesh`, with its second-order geometry if it has one."""
    return p2_mesh(mesh.points, mesh.tets, getattr(mesh, "curved_edges", None), getattr(mesh, "curved_points", None))


def _curve_edges(pts, cells, edges, nv, curved_edges, curved_points):
    """Move the nodes of ``curved_edges`` to ``curved_points``; straighten the edges of cells that fold."""
    key = edges[:, 0] * nv + edges[:, 1]
    ce = np.sort(curved_edges, axis=1)
    ck = ce[:, 0] * nv + ce[:, 1]
    order = np.argsort(key)
    pos = order[np.minimum(np.searchsorted(key, ck, sorter=order), len(key) - 1)]
    if not np.all(key[pos] == ck):
        raise LinkFeaError("curved edges that are not edges of the tet mesh")
    straight = pts.copy()
    pts = pts.copy()
    pts[nv + pos] = curved_points
    for _ in range(3):
        moved = np.any(pts[cells[:, 4:]] != straight[cells[:, 4:]], axis=(1, 2))
        idx = np.flatnonzero(moved)
        det = _isoparametric_jacobians(pts[cells[idx]])[2]
        bad = idx[np.any(det <= 0.0, axis=1)]
        if len(bad) == 0:
            return pts, moved
        nodes = np.unique(cells[bad, 4:])
        pts[nodes] = straight[nodes]
    raise LinkFeaError("curved elements: straightening the folded cells did not converge")


CURVED_QUADRATURE_DEGREE = 2
"""Quadrature of curved cells: scikit-fem's degree-2 rule on the tet, the 4 points of C3D10 in
CalculiX and Abaqus (exact on straight cells; the CalculiX cross-check then solves the same
discrete problem on curved meshes too)."""


def _quadrature():
    """scikit-fem's rule of :data:`CURVED_QUADRATURE_DEGREE` on the reference tet: points (3, nq), weights (nq,) (sum 1/6)."""
    from skfem.quadrature import get_quadrature
    from skfem.refdom import RefTet

    X, W = get_quadrature(RefTet, CURVED_QUADRATURE_DEGREE)
    return np.asarray(X, dtype=float), np.asarray(W, dtype=float)


def _p2_reference_gradients(X: np.ndarray) -> np.ndarray:
    """dN_a/dxi_k (nq, 10, 3) of the 10 P2 shape functions at reference points ``X`` (3, nq).

    Barycentric ``lam = (1 - xi1 - xi2 - xi3, xi1, xi2, xi3)``; vertex ``i``: ``lam_i (2 lam_i - 1)``,
    edge (i, j) of :data:`TET_EDGES`: ``4 lam_i lam_j`` (scikit-fem's ``ElementTetP2`` order).
    """
    lam = np.vstack([1.0 - X.sum(axis=0), X]).T  # (nq, 4)
    dlam = np.vstack([-np.ones(3), np.eye(3)])  # (4, 3): d lam_m / d xi_k
    dN_dlam = np.zeros((len(lam), 10, 4))
    for i in range(4):
        dN_dlam[:, i, i] = 4.0 * lam[:, i] - 1.0
    for e, (i, j) in enumerate(TET_EDGES):
        dN_dlam[:, 4 + e, i] = 4.0 * lam[:, j]
        dN_dlam[:, 4 + e, j] = 4.0 * lam[:, i]
    return dN_dlam @ dlam


def _isoparametric_jacobians(X: np.ndarray):
    """Reference gradients (nq, 10, 3), Jacobians (m, nq, 3, 3) and their determinants (m, nq) of
    10-node tets with nodes ``X`` (m, 10, 3) at the quadrature points."""
    Q, _ = _quadrature()
    dN = _p2_reference_gradients(Q)  # (nq, 10, 3)
    J = np.matmul(X.transpose(0, 2, 1)[:, None], dN[None])  # (m, nq, 3, 3): dx_i / dxi_k
    return dN, J, np.linalg.det(J)


def _isoparametric_gradients(X: np.ndarray):
    """Physical gradients (m, nq, 10, 3) and Jacobian determinants (m, nq) of 10-node tets with nodes ``X`` (m, 10, 3)."""
    dN, J, det = _isoparametric_jacobians(X)
    Jinv = np.linalg.inv(np.where(det[..., None, None] > 0, J, np.eye(3)))
    return np.matmul(dN[None], Jinv), det  # dN/dx = dN/dxi J^-1


def _isoparametric_pair_integrals(X: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``S[e, i, j, p] = w_e int dN_a/dx_i dN_b/dx_j`` (m, 3, 3, 55) over curved 10-node tets, pairs ``p = (a <= b)``.

    The rule of :data:`CURVED_QUADRATURE_DEGREE` (the integrand is rational on a curved cell).
    """
    _, W = _quadrature()
    G, det = _isoparametric_gradients(X)
    wq = det * W[None, :] * w[:, None]  # (m, nq)
    GA = (G[:, :, _PAIR_A] * wq[:, :, None, None]).transpose(0, 2, 3, 1)  # (m, 55, 3, nq)
    GB = G[:, :, _PAIR_B].transpose(0, 2, 1, 3)  # (m, 55, nq, 3)
    return np.matmul(GA, GB).transpose(0, 2, 3, 1)  # batched 3 x nq x 3 products: (m, 3, 3, 55)


def assemble_upper_skfem(p2: P2Mesh, lam: float, mu: float, scale: Optional[np.ndarray] = None) -> sp.csr_matrix:
    """The reference assembly: ``skfem.asm(linear_elasticity)`` on ``ElementVector(ElementTetP2)``.

    ``intorder=2`` is exact for affine P2 (gradients are linear); a curved mesh uses scikit-fem's
    ``MeshTet2`` (isoparametric) with the kernel's rule, :data:`CURVED_QUADRATURE_DEGREE`.  Same DOF numbering as
    :func:`assemble_upper` (scikit-fem's); 7-10x slower (docs/benchmarks.md).  ``scale``
    multiplies both constants per element (assembled per distinct value).
    """
    import skfem
    from skfem.models.elasticity import linear_elasticity

    element = skfem.ElementVector(skfem.ElementTetP2())
    m = len(p2.cells)
    scale = np.ones(m) if scale is None else np.asarray(scale, dtype=float)
    mesh, intorder = p2.mesh, 2
    if p2.curved is not None and p2.curved.any():
        # Second-order geometry: scikit-fem's isoparametric P2 mesh on the same nodes, the kernel's rule.
        mesh = skfem.MeshTet2(np.ascontiguousarray(p2.points.T), np.ascontiguousarray(p2.cells[:, :4].T),
                              sort_t=False)
        intorder = CURVED_QUADRATURE_DEGREE
    K = None
    for s in np.unique(scale):
        elems = np.flatnonzero(scale == s)
        basis = skfem.Basis(mesh, element, intorder=intorder, elements=None if len(elems) == m else elems)
        Ks = skfem.asm(linear_elasticity(s * lam, s * mu), basis)
        K = Ks if K is None else K + Ks
    return sp.triu(K, format="csr")


# --------------------------------------------------------------------------
# Vectorized P2 elasticity assembly
# --------------------------------------------------------------------------
def _p2_gradient_tensor() -> np.ndarray:
    """Constant tensor ``T[a, b, k, l] = (1/V) int (dN_a/dlam_k)(dN_b/dlam_l)``.

    With barycentric coordinates ``lam`` (gradients ``g_k``), the P2 shape
    gradients are ``grad N_a = sum_{k,m} B[a,k,m] lam_m g_k`` (vertex:
    ``(4 lam_i - 1) g_i``, edge (i,j): ``4 lam_j g_i + 4 lam_i g_j``; the
    constant -1 is written ``-sum_m lam_m``).  The exact integral
    ``int lam_m lam_n dV = V (1 + delta_mn) / 20`` then makes the element
    integral exact (the same as a degree-2 quadrature rule).
    """
    B = np.zeros((10, 4, 4))
    for i in range(4):
        B[i, i, :] = -1.0
        B[i, i, i] += 4.0
    for e, (i, j) in enumerate(TET_EDGES):
        B[4 + e, i, j] += 4.0
        B[4 + e, j, i] += 4.0
    M0 = (np.ones((4, 4)) + np.eye(4)) / 20.0
    return np.einsum("akm,mn,bln->abkl", B, M0, B)


_T = _p2_gradient_tensor()
def _pair_tensor() -> np.ndarray:
    """``T3[p, K, L]`` (55, 3, 3): ``T`` for local node pairs ``p = (a <= b)`` on the gradients ``g_1..g_3``.

    ``g_0 = -g_1 - g_2 - g_3``, so only 3 independent gradients remain and
    ``int dN_a/dx_i dN_b/dx_j = V sum_KL T3[p, K, L] g_K[i] g_L[j]``.
    """
    M = np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    a, b = np.triu_indices(10)
    return np.einsum("abkl,kK,lL->abKL", _T, M, M)[a, b]


def tet_geometry(points: np.ndarray, tets: np.ndarray):
    """Barycentric gradients ``g`` (m, 4, 3) and volumes ``V`` (m,) of linear tets."""
    X = points[tets]  # (m, 4, 3)
    Jt = X[:, 1:, :] - X[:, :1, :]  # rows: edge vectors from vertex 0, i.e. J^T
    det = np.linalg.det(Jt)
    if np.any(~np.isfinite(det)) or np.any(det <= 0.0):
        bad = int(np.sum(~(det > 0)))
        raise LinkFeaError(f"{bad} tetrahedra are degenerate or negatively oriented (zero/negative volume)")
    # grad lam_{1..3} are the rows of J^{-1} = columns of (J^T)^{-1}.
    g123 = np.linalg.inv(Jt).transpose(0, 2, 1)
    g = np.concatenate([-g123.sum(axis=1, keepdims=True), g123], axis=1)
    return g, det / 6.0


# Local node pairs (a <= b) of a 10-node tet.
_PAIR_A, _PAIR_B = np.triu_indices(10)
_T3 = _pair_tensor().reshape(55, 9)
_CHUNK = 8192


def assemble_upper(p2: P2Mesh, lam: float, mu: float, scale: Optional[np.ndarray] = None) -> sp.csr_matrix:
    """Upper triangle (with diagonal) of the global P2 elasticity stiffness, CSR.

    Isotropic elasticity: block ``(a, b)`` of an element matrix is
    ``K_ij = lam S_ij + mu S_ji + mu delta_ij tr(S)`` with
    ``S_ij = int dN_a/dx_i dN_b/dx_j`` integrated exactly (P2 gradients are
    linear: ``int lam_m lam_n = V (1 + delta_mn) / 20``).  ``S`` of the 55
    local node pairs (a <= b) comes from one small matrix product per element
    chunk.  Blocks are transposed where the global node order is the reverse
    of the local one (the element matrix is symmetric), summed per unique node
    pair with ``bincount`` (cache-resident targets), then written once into a
    CSR structure built from the node graph (upper half of the diagonal
    blocks).  No COO sort.

    Parameters
    ----------
    p2 : P2Mesh
    lam, mu : float
        Lame constants, MPa.
    scale : ndarray (m,), optional
        Per-element multiplier of both constants (e.g. the stiff block).
    """
    cells = p2.cells
    m = len(cells)
    N = len(p2.points)
    g, V = tet_geometry(p2.points[:p2.n_vertices], cells[:, :4])
    g123 = g[:, 1:, :]
    ws = np.ones(m) if scale is None else np.asarray(scale, dtype=float)
    w = V * ws  # per unit mu
    curved = p2.curved if p2.curved is not None and p2.curved.any() else None
    ratio = lam / mu

    # Node-level upper pattern: unique pairs (r <= c), sorted row-major.
    na = cells[:, _PAIR_A]
    nb = cells[:, _PAIR_B]
    swapped = na > nb
    ukeys, inv = np.unique((np.minimum(na, nb) * N + np.maximum(na, nb)).ravel(), return_inverse=True)
    inv = inv.reshape(m, 55)
    npairs = len(ukeys)
    ur, uc = ukeys // N, ukeys % N

    # Sum the 3x3 blocks (per unit mu) of all elements per node pair.
    blocks = np.zeros((9, npairs))
    for s0 in range(0, m, _CHUNK):
        sl = slice(s0, min(s0 + _CHUNK, m))
        mc = sl.stop - sl.start
        H = np.einsum("eKi,eLj->eijKL", g123[sl] * w[sl, None, None], g123[sl]).reshape(mc * 9, 9)
        S = (H @ _T3.T).reshape(mc, 3, 3, 55)
        if curved is not None:
            cv = np.flatnonzero(curved[sl])
            if len(cv):
                S[cv] = _isoparametric_pair_integrals(p2.points[cells[sl][cv]], ws[sl][cv])
        tr = S[:, 0, 0] + S[:, 1, 1] + S[:, 2, 2]
        sw = swapped[sl]
        idx = inv[sl].ravel()
        for i in range(3):
            blocks[4 * i] += np.bincount(idx, weights=((ratio + 1.0) * S[:, i, i] + tr).ravel(), minlength=npairs)
            for j in range(i + 1, 3):
                x = np.where(sw, S[:, j, i], S[:, i, j])  # S_ij of the block in global orientation
                y = np.where(sw, S[:, i, j], S[:, j, i])
                blocks[3 * i + j] += np.bincount(idx, weights=(ratio * x + y).ravel(), minlength=npairs)
                blocks[3 * j + i] += np.bincount(idx, weights=(ratio * y + x).ravel(), minlength=npairs)
    blocks *= mu

    # CSR structure: DOF row 3r+i holds (3 - i) + 3 (deg - 1) entries; for DOF
    # (3r+i, 3c+j) of the pair of rank q in node row r (degree D) the position is
    # indptr[3r] + 3q + i (3D - 1) - i (i - 1) / 2 + j (diagonal pair: q = 0, j >= i).
    deg = np.bincount(ur, minlength=N)
    if np.any(deg == 0):
        raise LinkFeaError("mesh has points that belong to no tetrahedron")
    row_start = np.concatenate([[0], np.cumsum(deg)[:-1]])
    rank = np.arange(npairs) - row_start[ur]
    row_len = (3 - np.arange(3))[None, :] + 3 * (deg[:, None] - 1)
    indptr = np.concatenate([[0], np.cumsum(row_len.ravel())])
    nnz = int(indptr[-1])
    bi, bj = np.repeat(np.arange(3), 3), np.tile(np.arange(3), 3)
    keep = (rank[:, None] > 0) | (bj >= bi)[None, :]  # drop the lower half of diagonal blocks
    pos = (indptr[3 * ur] + 3 * rank)[:, None] + bi * (3 * deg[ur, None] - 1) - bi * (bi - 1) // 2 + bj
    data = np.empty(nnz)
    cols = np.empty(nnz, dtype=np.int64)
    data[pos[keep]] = blocks.T[keep]
    cols[pos[keep]] = (3 * uc[:, None] + bj)[keep]
    idx_dtype = np.int32 if nnz < 2**31 - 1 else np.int64
    return sp.csr_matrix((data, cols.astype(idx_dtype), indptr.astype(idx_dtype)), shape=(3 * N, 3 * N))


def lame(material: Material):
    """Lame constants (lambda, mu) in MPa."""
    E, nu = material.E, material.nu
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
