"""Quadratic-tetrahedron linear elasticity of a link under 6 unit wrenches.

The link mesh (:class:`linkfea.mesh.LinkMesh`) is a linear tet mesh; it is
promoted to 10-node quadratic tets (P2: the 4 vertices, then the midpoints of
edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3) -- the order of scikit-fem's
``ElementTetP2``, VTK's ``QUADRATIC_TETRA`` and CalculiX's C3D10 alike).

Global numbering: P2 node ``n`` is vertex ``n`` for ``n < n_vertices``, then
one node per unique mesh edge; degree of freedom ``3 n + c`` is component
``c`` (CAD axes) of node ``n``.

Two reference modes give the 6 unit-load solutions:

``"rigid"``
    Exact rigid coupling (RBE2-like) of every P2 node of the block cells and
    of the tip facets to a 6-DOF reference node at ``frame.origin``: with the
    kinematic map ``u = P u_hat`` the reduced system is ``P^T K P``.  The
    reference DOFs are the twist in *frame* axes, so a unit wrench in frame
    axes is a unit right-hand side on them.
``"block"``
    The seed paper's pseudo-rigid block (Pashkevich, Chablat & Wenger, sec.
    3.3): block cells get ``E * block_ratio`` and the unit wrench is applied to
    the block's nodes as the minimum-norm nodal force set with that resultant.

Units: N, mm, MPa.
"""
from __future__ import annotations

import logging
import time
import warnings
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp

from .errors import LinkFeaError, SolverError
from .frames import Frame
from .materials import Material

log = logging.getLogger(__name__)

# Local edges of a tet, in the P2 node order 4..9.
TET_EDGES = np.array([[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]])
# Local edges of a triangle.
TRI_EDGES = np.array([[0, 1], [1, 2], [0, 2]])

MODES = ("rigid", "block")


# --------------------------------------------------------------------------
# P2 topology
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class P2Mesh:
    """Quadratic-tet topology built on a linear tet mesh.

    Attributes
    ----------
    points : ndarray (N, 3)
        P2 node coordinates: vertices, then edge midpoints.
    cells : ndarray (m, 10) int
        P2 nodes of each tet (vertices, then edges in ``TET_EDGES`` order).
    edges : ndarray (E, 2) int
        Vertex pairs (sorted) of the unique edges; edge ``e`` is node ``n_vertices + e``.
    n_vertices : int
    """

    points: np.ndarray
    cells: np.ndarray
    edges: np.ndarray
    n_vertices: int

    def facet_nodes(self, facets: np.ndarray) -> np.ndarray:
        """Sorted unique P2 nodes (vertices and edge midpoints) of triangles ``facets`` (k, 3)."""
        facets = np.asarray(facets, dtype=np.int64).reshape(-1, 3)
        if len(facets) == 0:
            return np.zeros(0, dtype=np.int64)
        if facets.min() < 0 or facets.max() >= self.n_vertices:
            raise LinkFeaError("interface facets refer to vertices that are not in the mesh")
        pairs = np.sort(facets[:, TRI_EDGES].reshape(-1, 2), axis=1)
        nv = self.n_vertices
        keys = pairs[:, 0] * nv + pairs[:, 1]
        ekeys = self.edges[:, 0] * nv + self.edges[:, 1]  # sorted ascending by construction
        pos = np.searchsorted(ekeys, keys)
        pos = np.minimum(pos, len(ekeys) - 1)
        if not np.all(ekeys[pos] == keys):
            raise LinkFeaError("interface facets are not faces of the tet mesh (an edge is missing)")
        return np.unique(np.concatenate([facets.ravel(), nv + pos]))


def p2_mesh(points: np.ndarray, tets: np.ndarray) -> P2Mesh:
    """Promote a linear tet mesh to P2: add one node per unique edge at its midpoint."""
    points = np.asarray(points, dtype=float)
    tets = np.asarray(tets, dtype=np.int64)
    if points.ndim != 2 or points.shape[1] != 3 or tets.ndim != 2 or tets.shape[1] != 4:
        raise LinkFeaError(f"mesh must have points (n, 3) and tets (m, 4), got {points.shape} and {tets.shape}")
    if len(tets) == 0:
        raise LinkFeaError("mesh has no tetrahedra")
    nv = len(points)
    if tets.min() < 0 or tets.max() >= nv:
        raise LinkFeaError("tets refer to points that do not exist")
    pairs = np.sort(tets[:, TET_EDGES].reshape(-1, 2), axis=1)
    keys = pairs[:, 0] * nv + pairs[:, 1]
    ukeys, inv = np.unique(keys, return_inverse=True)
    edges = np.stack([ukeys // nv, ukeys % nv], axis=1)
    cells = np.hstack([tets, nv + inv.reshape(-1, 6)])
    pts = np.vstack([points, 0.5 * (points[edges[:, 0]] + points[edges[:, 1]])])
    return P2Mesh(pts, cells, edges, nv)


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
    w = V if scale is None else V * np.asarray(scale, dtype=float)  # per unit mu
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


def symmetric_from_upper(U: sp.spmatrix) -> sp.csr_matrix:
    """Full symmetric matrix from its upper triangle with diagonal."""
    U = sp.csr_matrix(U)
    return (U + sp.triu(U, k=1, format="csr").T).tocsr()


def lame(material: Material):
    """Lame constants (lambda, mu) in MPa."""
    E, nu = material.E, material.nu
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


# --------------------------------------------------------------------------
# Solvers: a factorizer takes the upper triangle (CSR, SPD) and returns solve(B)
# --------------------------------------------------------------------------
_PARDISO = []  # one solver object per process: creating one searches the disk for MKL (~0.5 s)


def pardiso_factorizer(U: sp.csr_matrix) -> Callable[[np.ndarray], np.ndarray]:
    """Factor with MKL PARDISO, real symmetric positive definite (mtype=2), upper triangle."""
    import pypardiso

    if not _PARDISO:
        _PARDISO.append(pypardiso.PyPardisoSolver(mtype=2))
    solver = _PARDISO[0]
    solver.set_matrix_type(2)
    U = sp.csr_matrix(U)
    U.sort_indices()
    try:
        solver.factorize(U)
    except Exception:
        solver.free_memory(everything=True)
        raise

    def solve(B):
        try:
            return solver.solve(U, np.asarray(B, dtype=float))
        finally:
            solver.free_memory(everything=True)
            solver.factorized_A = sp.csr_matrix((0, 0))

    solve.factorizer = "pardiso"
    return solve


def scipy_factorizer(U: sp.csr_matrix) -> Callable[[np.ndarray], np.ndarray]:
    """Factor with SuperLU on the full symmetric matrix (fallback; slower)."""
    from scipy.sparse.linalg import splu

    K = symmetric_from_upper(U).tocsc()
    lu = splu(K, permc_spec="MMD_AT_PLUS_A")

    def solve(B):
        return lu.solve(np.asarray(B, dtype=float))

    solve.factorizer = "superlu"
    return solve


def default_factorizer(U: sp.csr_matrix) -> Callable[[np.ndarray], np.ndarray]:
    """PARDISO if available and successful, else SuperLU; a fallback is logged and recorded.

    The returned ``solve`` carries ``factorizer`` (``"pardiso"`` or ``"superlu"``) and, after a
    fallback, ``fallback_reason``; :func:`solve_link` copies both into ``FeaSolution.solver``.
    """
    try:
        return pardiso_factorizer(U)
    except ImportError as exc:  # pypardiso is not installed (e.g. not x86-64): the documented fallback
        reason = f"pypardiso not available ({exc})"
        log.info("PARDISO not used: %s; factoring with SuperLU", reason)
    except Exception as exc:  # PARDISO installed but failed: say so, loudly
        reason = f"PARDISO failed: {type(exc).__name__}: {exc}"
        log.warning("%s; falling back to SuperLU (slower)", reason)
        warnings.warn(f"{reason}; falling back to SuperLU", RuntimeWarning, stacklevel=2)
    solve = scipy_factorizer(U)
    solve.fallback_reason = reason
    return solve


# --------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class FeaSolution:
    """Displacements of a link under the 6 unit wrenches.

    Attributes
    ----------
    points : ndarray (N, 3)
        P2 node coordinates (CAD, mm): mesh vertices first, then edge midpoints.
    cells : ndarray (m, 10) int
        P2 connectivity (vertex, then edge nodes in VTK/C3D10 order).
    displacements : ndarray (6, N, 3)
        Nodal displacements (CAD axes, mm) for unit Fx, Fy, Fz (N) and unit
        Mx, My, Mz (N mm) at ``frame.origin`` with components in frame axes.
    ref_nodes : ndarray (k,) int
        Nodes whose rigid motion defines the link's twist (coupled nodes in
        rigid mode, block nodes in block mode).
    clamped_nodes : ndarray int
        Nodes fixed at the base.
    n_dofs : int
        Size of the solved system.
    n_vertices : int
    frame : Frame
    mode : str
    timing : dict
        Seconds spent in ``assemble``, ``factor`` and ``solve``.
    solver : dict
        ``factorizer`` that ran (``pardiso``, ``superlu``, or the name of an injected one) and
        ``fallback_reason`` (None unless PARDISO was wanted but not used).
    ref_twists : ndarray (6, 6) or None
        Rigid mode only: reference-node twists (frame axes), column ``k`` for load ``k``.
    """

    points: np.ndarray
    cells: np.ndarray
    displacements: np.ndarray
    ref_nodes: np.ndarray
    clamped_nodes: np.ndarray
    n_dofs: int
    n_vertices: int
    frame: Frame
    mode: str
    timing: dict = field(default_factory=dict)
    ref_twists: Optional[np.ndarray] = None
    solver: dict = field(default_factory=dict)


def rigid_motion_matrix(points: np.ndarray, origin: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Nodal displacements (n, 3, 6) of a small rigid motion per unit twist component.

    Twist components are in the frame with rows ``axes``: ``u = R t + (R r) x (x - o)``
    with ``R = axes.T``.
    """
    R = np.asarray(axes, dtype=float).T
    d = np.asarray(points, dtype=float) - np.asarray(origin, dtype=float)
    out = np.empty((len(d), 3, 6))
    out[:, :, :3] = R
    # (R r) x d = -skew(d) R r
    sk = np.zeros((len(d), 3, 3))
    sk[:, 0, 1], sk[:, 0, 2] = -d[:, 2], d[:, 1]
    sk[:, 1, 0], sk[:, 1, 2] = d[:, 2], -d[:, 0]
    sk[:, 2, 0], sk[:, 2, 1] = -d[:, 1], d[:, 0]
    out[:, :, 3:] = -sk @ R
    return out


def _block_flags(mesh) -> np.ndarray:
    block = np.asarray(mesh.block, dtype=bool).reshape(-1)
    if len(block) != len(mesh.tets):
        raise LinkFeaError(f"mesh.block has {len(block)} entries for {len(mesh.tets)} tets")
    return block


def interface_nodes(p2: P2Mesh, mesh, mode: str):
    """Clamped P2 nodes and reference nodes of a link mesh.

    The clamp holds every P2 node of the base facets.  The reference nodes are
    the P2 nodes of the block cells and of the tip facets (rigid mode) or of
    the block cells (block mode).

    Returns
    -------
    clamped, ref_nodes : ndarray of int (sorted)
    """
    block = _block_flags(mesh)
    clamped = p2.facet_nodes(mesh.base_facets)
    if len(clamped) == 0:
        raise LinkFeaError("no base facets: the link must be clamped at its base interface")
    block_nodes = np.unique(p2.cells[block]) if block.any() else np.zeros(0, dtype=np.int64)
    if mode == "rigid":
        ref_nodes = np.union1d(block_nodes, p2.facet_nodes(mesh.tip_facets))
        if len(ref_nodes) == 0:
            raise LinkFeaError("rigid mode needs tip facets or block cells to couple to the reference node")
    elif mode == "block":
        if len(block_nodes) == 0:
            raise LinkFeaError("block mode needs pseudo-rigid block cells (mesh.block is all False)")
        ref_nodes = block_nodes
    else:
        raise LinkFeaError(f"unknown reference mode {mode!r}; use one of {', '.join(MODES)}")
    if np.intersect1d(clamped, ref_nodes).size:
        raise LinkFeaError("the base (clamped) and tip (reference) interfaces share nodes: they overlap")
    return clamped, ref_nodes


def solve_link(mesh, material: Material, mode: str = "rigid", block_ratio: float = 1000.0,
               solver: Optional[Callable] = None, progress: Optional[Callable[[str], None]] = None) -> FeaSolution:
    """Solve the 6 unit-wrench load cases of a clamped link with P2 tets.

    Parameters
    ----------
    mesh : linkfea.mesh.LinkMesh
    material : Material
    mode : {"rigid", "block"}
        Exact rigid coupling (reduction ``P^T K P``) or the pseudo-rigid block.
    block_ratio : float
        Block stiffness multiplier in ``"block"`` mode.
    solver : callable, optional
        A factorizer ``solver(U) -> solve(B)``, where ``U`` is the upper
        triangle (CSR) of the SPD system and ``B`` an (n, 6) right-hand side.
        Defaults to :func:`default_factorizer` (PARDISO, else SuperLU).
    progress : callable, optional
        Called with a stage name ("assemble", "factor", "solve") when it starts.

    Returns
    -------
    FeaSolution
    """
    if mode not in MODES:
        raise LinkFeaError(f"unknown reference mode {mode!r}; use one of {', '.join(MODES)}")
    if not (np.isfinite(block_ratio) and block_ratio > 0):
        raise LinkFeaError(f"block_ratio must be a positive number, got {block_ratio}")
    report = progress or (lambda stage: None)
    factorizer = solver or default_factorizer
    frame = mesh.frame
    block = _block_flags(mesh)
    timing = {}

    report("assemble")
    t0 = time.perf_counter()
    p2 = p2_mesh(mesh.points, mesh.tets)
    clamped, ref_nodes = interface_nodes(p2, mesh, mode)
    lam0, mu0 = lame(material)
    scale = np.where(block, block_ratio, 1.0) if mode == "block" else None
    U = assemble_upper(p2, lam0, mu0, scale)
    n_nodes = len(p2.points)

    fixed = np.zeros(n_nodes, dtype=bool)
    fixed[clamped] = True
    if mode == "rigid":
        fixed[ref_nodes] = True  # eliminated: they follow the reference node
    free_dofs = np.flatnonzero(np.repeat(~fixed, 3))
    Rm = rigid_motion_matrix(p2.points[ref_nodes], frame.origin, frame.axes).reshape(-1, 6)
    ref_dofs = (3 * ref_nodes[:, None] + np.arange(3)).ravel()

    U_f = U[free_dofs]
    U_ff = U_f[:, free_dofs]
    nf = len(free_dofs)
    if mode == "rigid":
        # K_fs Rm from the upper triangle: rows free < slave come from U, the others from U^T.
        U_fs = U_f[:, ref_dofs]
        U_sf = U[ref_dofs][:, free_dofs]
        K_fs = U_fs + U_sf.T  # disjoint supports: an entry sits either above or below the diagonal
        U_ss = U[ref_dofs][:, ref_dofs]
        K_ss = symmetric_from_upper(U_ss)
        C_fr = sp.csr_matrix(K_fs @ Rm)
        K_rr = Rm.T @ (K_ss @ Rm)
        K_rr = 0.5 * (K_rr + K_rr.T)
        A = sp.bmat([[U_ff, C_fr], [None, sp.csr_matrix(np.triu(K_rr))]], format="csr")
        B = np.zeros((nf + 6, 6))
        B[nf:, :] = np.eye(6)
    else:
        A = sp.csr_matrix(U_ff)
        # Minimum-norm nodal forces with unit resultant wrench: f = R (R^T R)^-1 w.
        F = Rm @ np.linalg.solve(Rm.T @ Rm, np.eye(6))
        pos = np.searchsorted(free_dofs, ref_dofs)
        B = np.zeros((nf, 6))
        B[pos] = F
    A.sort_indices()
    timing["assemble"] = time.perf_counter() - t0

    report("factor")
    t0 = time.perf_counter()
    try:
        solve = factorizer(A)
    except Exception as exc:
        raise SolverError(f"factorization of the stiffness matrix failed ({exc}); "
                           "is the link clamped and connected?") from None
    timing["factor"] = time.perf_counter() - t0

    report("solve")
    t0 = time.perf_counter()
    X = np.asarray(solve(B)).reshape(A.shape[0], 6)
    if not np.all(np.isfinite(X)):
        raise SolverError("the linear solve returned non-finite values: the stiffness matrix is singular "
                           "(a part of the link is not connected to the clamp?)")
    u = np.zeros((3 * n_nodes, 6))
    u[free_dofs] = X[:nf]
    ref_twists = None
    if mode == "rigid":
        ref_twists = X[nf:]
        u[ref_dofs] = Rm @ ref_twists
    timing["solve"] = time.perf_counter() - t0

    return FeaSolution(
        points=p2.points, cells=p2.cells,
        displacements=u.T.reshape(6, n_nodes, 3),
        ref_nodes=ref_nodes, clamped_nodes=clamped, n_dofs=int(A.shape[0]),
        n_vertices=p2.n_vertices, frame=frame, mode=mode, timing=timing, ref_twists=ref_twists,
        solver={"factorizer": getattr(solve, "factorizer", getattr(factorizer, "__name__", "custom")),
                "fallback_reason": getattr(solve, "fallback_reason", None)},
    )
