"""Quadratic-tetrahedron linear elasticity of a link under 6 unit wrenches.

The link mesh (:class:`linkfea.mesh.linkmesh.LinkMesh`) is promoted to 10-node
quadratic tets and assembled by :mod:`linkfea.fem.p2`; the system is factored by
:mod:`linkfea.solvers.factorizers`.  This module holds the boundary conditions, the
reference modes and the solve.

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

import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp

from ..mechanics.frames import Frame, rigid_motion_matrix
from ..mechanics.materials import Material
from ..options import BLOCK_RATIO, MODES
from ..runtime import checks
from ..runtime.errors import LinkFeaError, SolverError
from ..runtime.progress import or_quiet
from ..solvers.factorization import Factorization, SolverRecord
from ..solvers.factorizers import default_factorizer, needs
from ..solvers.sparse import symmetric_from_upper
from .coarse import p1_coarse_space
from .p2 import P2Mesh, assemble_upper, assemble_upper_skfem, lame, link_p2

ASSEMBLERS = {"kernel": assemble_upper, "skfem": assemble_upper_skfem}
"""Stiffness assemblies on scikit-fem's P2 discretization: the fast kernel and scikit-fem's own."""


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
    solver : SolverRecord
        The assembly and the factorizer that ran, with its fallback reason, convergence and choice.
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
    solver: Optional[SolverRecord] = None


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


def _check_connected(cells, n_nodes: int, clamped, ref_nodes) -> None:
    """SolverError unless every node is tied to the clamp through the elements (and the rigid
    reference, which ties the tip nodes together).

    A part that is not makes the stiffness matrix singular.  Left to the factorization, that
    shows only where round-off leaves an exact zero pivot: SuperLU may instead return finite
    values, so the graph decides, not the solver.
    """
    from scipy.sparse.csgraph import connected_components

    cells = np.asarray(cells)
    ground, ref = n_nodes, n_nodes + 1
    ref_nodes = np.asarray(ref_nodes, dtype=int)
    rows = np.concatenate([np.repeat(cells[:, 0], cells.shape[1]), np.full(len(clamped), ground),
                           np.full(len(ref_nodes), ref)])
    cols = np.concatenate([cells.ravel(), np.asarray(clamped, dtype=int), ref_nodes])
    G = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_nodes + 2, n_nodes + 2))
    _, label = connected_components(G, directed=False)
    loose = np.flatnonzero(label[:n_nodes] != label[ground])
    if loose.size:
        raise SolverError(f"the stiffness matrix is singular: {loose.size} of {n_nodes} mesh nodes are not "
                          "connected to the clamp (a part of the link is not connected to the clamp?)")


def solve_link(mesh, material: Material, mode: str = "rigid", block_ratio: float = 1000.0,
               solver: Optional[Callable] = None, progress: Optional[Callable[[str], None]] = None,
               assembler: str = "kernel") -> FeaSolution:
    """Solve the 6 unit-wrench load cases of a clamped link with P2 tets.

    Parameters
    ----------
    mesh : linkfea.mesh.linkmesh.LinkMesh
    material : Material
    mode : {"rigid", "block"}
        Exact rigid coupling (reduction ``P^T K P``) or the pseudo-rigid block.
    block_ratio : float
        Block stiffness multiplier in ``"block"`` mode.
    solver : callable, optional
        A factorizer ``solver(U) -> Factorization`` (:mod:`linkfea.solvers.factorizers`), where ``U`` is the
        upper triangle (CSR) of the SPD system; the factorization solves an (n, 6) right-hand side.
        Defaults to :func:`~linkfea.solvers.factorizers.default_factorizer` (PARDISO, else SuperLU).
        A factorizer that needs the P1 coarse space (the iterative solver,
        :func:`~linkfea.solvers.factorizers.needs`) also gets ``coarse``, a function that builds it
        (:func:`linkfea.fem.coarse.p1_coarse_space`), and ``progress``.
    progress : callable, optional
        Called with a stage name ("assemble", "factor", "solve") when it starts.
    assembler : {"kernel", "skfem"}
        The stiffness assembly: the vectorized kernel (:func:`linkfea.fem.p2.assemble_upper`,
        default) or scikit-fem's own ``asm(linear_elasticity)``, the slower reference
        (:func:`linkfea.fem.p2.assemble_upper_skfem`).  Both on scikit-fem's discretization.

    Returns
    -------
    FeaSolution
    """
    if mode not in MODES:
        raise LinkFeaError(f"unknown reference mode {mode!r}; use one of {', '.join(MODES)}")
    if assembler not in ASSEMBLERS:
        raise LinkFeaError(f"unknown assembler {assembler!r}; use one of {', '.join(ASSEMBLERS)}")
    block_ratio = checks.number(block_ratio, "block_ratio", BLOCK_RATIO)
    progress = or_quiet(progress)
    factorizer = solver or default_factorizer
    frame = mesh.frame
    block = _block_flags(mesh)
    timing = {}

    progress("assemble")
    t0 = time.perf_counter()
    p2 = link_p2(mesh)
    clamped, ref_nodes = interface_nodes(p2, mesh, mode)
    _check_connected(p2.cells, len(p2.points), clamped, ref_nodes if mode == "rigid" else ())
    lam0, mu0 = lame(material)
    scale = np.where(block, block_ratio, 1.0) if mode == "block" else None
    U = ASSEMBLERS[assembler](p2, lam0, mu0, scale)
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
    # The whole-mesh stiffness and its slices are copies of A's entries: free them before the solve
    # (about 3 copies of the matrix, the largest share of the iterative path's memory).
    del U, U_f, U_ff
    timing["assemble"] = time.perf_counter() - t0

    progress("factor")
    t0 = time.perf_counter()
    solve = _factor(factorizer, A, lambda: _near_nullspace(p2.points, free_dofs, frame, mode),
                    lambda: p1_coarse_space(p2, free_dofs, fixed, ref_nodes, frame, mode), progress)
    timing["factor"] = time.perf_counter() - t0

    progress("solve")
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
        solver=SolverRecord.of(assembler, solve),
    )


def _factor(factorizer, A, near_nullspace, coarse, progress) -> Factorization:
    """``factorizer(A)``, with the rigid-body modes or the P1 coarse space (a function that builds
    it, :func:`linkfea.fem.coarse.p1_coarse_space`) for a factorizer that wants them (multigrid)."""
    try:
        wants = needs(factorizer)
        if wants == "coarse_space":
            return factorizer(A, coarse=coarse, progress=progress)
        if wants == "near_nullspace":
            return factorizer(A, near_nullspace=near_nullspace(), progress=progress)
        return factorizer(A)
    except SolverError:
        raise
    except Exception as exc:
        raise SolverError(f"factorization of the stiffness matrix failed ({exc}); "
                          "is the link clamped and connected?") from None


def _near_nullspace(points, free_dofs, frame: Frame, mode: str) -> np.ndarray:
    """Rigid-body motions (n, 6) of the solved DOFs: the free nodes' displacements and, in rigid
    mode, the reference twist (the same twist), for the multigrid preconditioner."""
    R = rigid_motion_matrix(points, frame.origin, frame.axes).reshape(-1, 6)[free_dofs]
    return np.vstack([R, np.eye(6)]) if mode == "rigid" else R
