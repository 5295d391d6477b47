"""The P1 coarse space under the P2 problem: a prolongation from linear (vertex) fields.

A P1 field on the same tets is a P2 field whose edge nodes carry the mean of their two end
vertices (per displacement component): the P2 space contains the P1 space, so the Galerkin
operator ``P^T K P`` of the solved system is the P1 stiffness (exactly, on straight cells), a
sparse operator with 1/8 of the unknowns on which smoothed aggregation builds a real hierarchy.

The solved system of :func:`linkfea.fem.problem.solve_link` is not the whole P2 space: clamped nodes are
removed and, in rigid mode, the reference nodes follow the 6-DOF reference twist (the
reduction ``P^T K P`` of the rigid coupling), appended as the last 6 unknowns.  The coarse
space does the same: its unknowns are the displacements of the vertices that are neither
clamped nor (rigid mode) coupled, plus the twist; a clamped vertex contributes zero to its
edges and a coupled vertex the rigid motion of the twist.

On a curved cell (second-order geometry) the edge node is off the midpoint and the coarse space
is the P1 space of the reference cell: still a subspace of the P2 space (the Galerkin operator
stays exact and SPD), only the rigid motions are no longer exactly in it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..mechanics.frames import Frame, rigid_motion_matrix
from .p2 import P2Mesh


@dataclass(frozen=True)
class CoarseSpace:
    """A prolongation ``P`` (n_solved, n_coarse) and the coarse rigid-body modes (n_coarse, 6).

    ``P @ near_nullspace`` is the rigid motion of the solved DOFs wherever no clamped vertex
    is involved (tests/linkfea/test_coarse.py).
    """

    P: sp.csr_matrix
    near_nullspace: np.ndarray


def p1_interpolation(p2: P2Mesh) -> sp.csr_matrix:
    """Node-level interpolation (N, n_vertices) of P1 vertex values to the P2 nodes: vertices
    keep their value, edge node ``n_vertices + e`` takes the mean of edge ``e``'s two ends."""
    nv, ne = p2.n_vertices, len(p2.edges)
    rows = np.concatenate([np.arange(nv), np.repeat(nv + np.arange(ne), 2)])
    cols = np.concatenate([np.arange(nv), p2.edges.ravel()])
    vals = np.concatenate([np.ones(nv), np.full(2 * ne, 0.5)])
    return sp.csr_matrix((vals, (rows, cols)), shape=(nv + ne, nv))


def p1_coarse_space(p2: P2Mesh, free_dofs: np.ndarray, fixed_nodes: np.ndarray, ref_nodes: np.ndarray,
                    frame: Frame, mode: str) -> CoarseSpace:
    """The P1 coarse space of the system solved by :func:`linkfea.fem.problem.solve_link`.

    Parameters
    ----------
    free_dofs : the solved P2 DOFs (``3 node + component``), sorted.
    fixed_nodes : bool (N,), nodes not among the solved DOFs (clamped; coupled in rigid mode).
    ref_nodes : the coupled nodes (rigid mode: they follow the reference twist).
    mode : ``"rigid"`` (the 6 twist DOFs are the last unknowns, fine and coarse) or ``"block"``.
    """
    nv = p2.n_vertices
    fixed_v = np.asarray(fixed_nodes[:nv], dtype=bool)
    free_v = np.flatnonzero(~fixed_v)
    nfc = 3 * len(free_v)
    # Vertex DOFs (3 nv) from the coarse unknowns: the free vertices, then the twist (rigid mode).
    n_c = nfc + (6 if mode == "rigid" else 0)
    rows = [(3 * free_v[:, None] + np.arange(3)).ravel()]
    cols = [np.arange(nfc)]
    vals = [np.ones(nfc)]
    if mode == "rigid":
        ref_v = np.asarray(ref_nodes)[np.asarray(ref_nodes) < nv]
        Rm = rigid_motion_matrix(p2.points[ref_v], frame.origin, frame.axes)  # (k, 3, 6)
        rows.append(np.repeat((3 * ref_v[:, None] + np.arange(3)).ravel(), 6))
        cols.append(np.tile(nfc + np.arange(6), 3 * len(ref_v)))
        vals.append(Rm.ravel())
    C = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * nv, n_c))
    Ivec = sp.kron(p1_interpolation(p2), sp.identity(3, format="csr"), format="csr")  # DOF 3 n + c
    P = (Ivec[free_dofs] @ C).tocsr()
    B = rigid_motion_matrix(p2.points[free_v], frame.origin, frame.axes).reshape(-1, 6)
    if mode == "rigid":
        P = sp.vstack([P, sp.csr_matrix((np.ones(6), (np.arange(6), nfc + np.arange(6))), shape=(6, n_c))],
                      format="csr")
        B = np.vstack([B, np.eye(6)])
    P.eliminate_zeros()
    P.sort_indices()
    return CoarseSpace(P, B)
