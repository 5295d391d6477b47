"""Structured tetrahedral meshes of boxes for FEA validation (no mesher needed).

A box ``[0, L] x [-w/2, w/2] x [-h/2, h/2]`` (width along y, height along z)
is divided into hexahedra, each split into 6 tetrahedra around its main
diagonal (Kuhn split, conforming because every hex is split the same way).
An optional pseudo-rigid block continues the bar from ``x = L`` to
``x = L + block_length``.  Base facets are the triangles on ``x = 0``, tip
facets those on ``x = L``; the frame sits at ``(L, 0, 0)`` with CAD axes.
"""
from __future__ import annotations

import itertools

import numpy as np

from linkfea.mechanics.frames import Frame
from linkfea.mesh.linkmesh import LinkMesh

_FACES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])


def _kuhn_tets():
    """6 tets of the unit cube, as corner indices ``i + 2 j + 4 k``."""
    tets = []
    for perm in itertools.permutations(range(3)):
        c = np.zeros(3, dtype=int)
        verts = [0]
        for ax in perm:
            c[ax] = 1
            verts.append(int(c[0] + 2 * c[1] + 4 * c[2]))
        tets.append(verts)
    return np.array(tets)


def _plane_facets(points, tets, x0, tol=1e-9):
    faces = np.sort(tets[:, _FACES].reshape(-1, 3), axis=1)
    on = np.all(np.abs(points[faces, 0] - x0) < tol, axis=1)
    return np.unique(faces[on], axis=0)


def box_mesh(L, w, h, nx, ny, nz, block_length=0.0, nb=0):
    """Points and positively oriented tets of the box (plus block), and the block flag per tet."""
    xs = np.linspace(0.0, L, nx + 1)
    if nb:
        xs = np.concatenate([xs, np.linspace(L, L + block_length, nb + 1)[1:]])
    ys = np.linspace(-w / 2, w / 2, ny + 1)
    zs = np.linspace(-h / 2, h / 2, nz + 1)
    X, Y, Z = np.meshgrid(xs, ys, zs, indexing="ij")
    points = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    Nx, Ny, Nz = len(xs), len(ys), len(zs)
    vid = np.arange(len(points)).reshape(Nx, Ny, Nz)
    i, j, k = np.meshgrid(np.arange(Nx - 1), np.arange(Ny - 1), np.arange(Nz - 1), indexing="ij")
    corners = np.stack([vid[i + a, j + b, k + c] for c in (0, 1) for b in (0, 1) for a in (0, 1)], axis=-1)
    corners = corners.reshape(-1, 8)
    tets = corners[:, _kuhn_tets()].reshape(-1, 4)
    P = points[tets]
    det = np.einsum("ij,ij->i", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), P[:, 3] - P[:, 0])
    tets[det < 0] = tets[det < 0][:, [0, 2, 1, 3]]
    block = points[tets].mean(axis=1)[:, 0] > L
    return points, tets, block


def bar_link_mesh(L, w, h, nx, ny, nz, block_length=0.0, nb=0, frame=None) -> LinkMesh:
    """A :class:`LinkMesh` of a bar clamped at ``x = 0`` with its tip interface at ``x = L``."""
    points, tets, block = box_mesh(L, w, h, nx, ny, nz, block_length, nb)
    return LinkMesh(
        points=points, tets=tets, block=block,
        base_facets=_plane_facets(points, tets, 0.0),
        tip_facets=_plane_facets(points, tets, L),
        frame=frame or Frame(np.array([L, 0.0, 0.0]), np.eye(3)),
        edge_length=float(max(L / nx, w / ny, h / nz)),
    )


def skfem_dof_order(points, basis) -> np.ndarray:
    """Index of each DOF of a scikit-fem P2 vector ``basis`` in the kernel's numbering
    (3 per node of ``points``, node order), matched by coordinates (checked to 1e-12)."""
    from scipy.spatial import cKDTree

    dist, node = cKDTree(points).query(basis.doflocs.T)
    assert dist.max() < 1e-12
    comp = np.empty(basis.N, dtype=int)
    comp[basis.nodal_dofs] = np.arange(3)[:, None]
    comp[basis.edge_dofs] = np.arange(3)[:, None]
    return 3 * node + comp
