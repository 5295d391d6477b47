"""The P1 coarse space under the P2 problem (linkfea.fem.coarse): P1 fields reproduced on the P2 nodes,
the Galerkin operator against scikit-fem's own P1 stiffness, the rigid-body modes in the coarse space."""
import numpy as np
import pytest
import scipy.sparse as sp
from meshes import bar_link_mesh

from linkfea.fem.coarse import p1_coarse_space, p1_interpolation
from linkfea.fem.p2 import assemble_upper, lame, link_p2
from linkfea.fem.problem import _near_nullspace, interface_nodes
from linkfea.mechanics.frames import rigid_motion_matrix
from linkfea.solvers.sparse import symmetric_from_upper


@pytest.fixture(scope="module")
def bar():
    mesh = bar_link_mesh(30.0, 8.0, 6.0, 5, 2, 2, block_length=6.0, nb=1)
    return mesh, link_p2(mesh)


def _p1_at_p2_nodes(p2, u_vertices):
    """The P1 function of vertex values ``u_vertices`` (nv, 3) at every P2 node, from the node's
    barycentric coordinates in a cell that holds it (computed from the coordinates, not the edge table)."""
    out = np.full((len(p2.points), 3), np.nan)
    for cell in p2.cells:
        V = p2.points[cell[:4]]
        T = np.vstack([V.T, np.ones(4)])  # 4 x 4: [x; 1] per vertex
        lam = np.linalg.solve(T, np.vstack([p2.points[cell].T, np.ones(10)]))  # (4, 10)
        out[cell] = lam.T @ u_vertices[cell[:4]]
    return out


def test_the_interpolation_reproduces_p1_fields_on_the_p2_nodes(bar):
    _, p2 = bar
    u = np.random.default_rng(1).standard_normal((p2.n_vertices, 3))
    I = p1_interpolation(p2)
    np.testing.assert_allclose(I @ u, _p1_at_p2_nodes(p2, u), rtol=0, atol=1e-12)


@pytest.mark.parametrize("mode", ["rigid", "block"])
def test_the_constrained_prolongation_is_the_p1_field_on_the_solved_dofs(bar, mode):
    """A coarse vector (free vertex values, twist) prolongs to the P1 field that is zero on the clamp
    and (rigid mode) the twist's rigid motion on the coupled vertices."""
    mesh, p2 = bar
    clamped, ref = interface_nodes(p2, mesh, mode)
    fixed = np.zeros(len(p2.points), dtype=bool)
    fixed[clamped] = True
    if mode == "rigid":
        fixed[ref] = True
    free_dofs = np.flatnonzero(np.repeat(~fixed, 3))
    space = p1_coarse_space(p2, free_dofs, fixed, ref, mesh.frame, mode)
    rng = np.random.default_rng(2)
    nv = p2.n_vertices
    u = rng.standard_normal((nv, 3))
    u[clamped[clamped < nv]] = 0.0
    twist = rng.standard_normal(6)
    if mode == "rigid":
        rv = ref[ref < nv]
        u[rv] = rigid_motion_matrix(p2.points[rv], mesh.frame.origin, mesh.frame.axes) @ twist
    free_v = np.flatnonzero(~fixed[:nv])
    coarse = np.concatenate([u[free_v].ravel()] + ([twist] if mode == "rigid" else []))
    fine = space.P @ coarse
    expect = _p1_at_p2_nodes(p2, u).ravel()[free_dofs]
    np.testing.assert_allclose(fine[:len(free_dofs)], expect, rtol=0, atol=1e-12)
    if mode == "rigid":
        np.testing.assert_allclose(fine[len(free_dofs):], twist, rtol=0, atol=1e-15)
    # The rigid-body modes are in the coarse space: P B_c is the fine rigid motion away from the clamp.
    B = _near_nullspace(p2.points, free_dofs, mesh.frame, mode)
    away = ~np.isin(p2.cells, clamped).any(axis=1)
    nodes = np.unique(p2.cells[away])
    rows = np.flatnonzero(np.isin(free_dofs // 3, nodes))
    if mode == "rigid":
        rows = np.concatenate([rows, len(free_dofs) + np.arange(6)])
    assert len(rows) > len(free_dofs) // 3
    np.testing.assert_allclose((space.P @ space.near_nullspace)[rows], B[rows], rtol=0, atol=1e-11)


def test_the_galerkin_operator_is_the_p1_stiffness(bar, steel):
    """``I^T K_P2 I`` equals scikit-fem's P1 elasticity stiffness, whose kernel is the rigid-body motions."""
    import skfem
    from skfem.models.elasticity import linear_elasticity

    _, p2 = bar
    lam, mu = lame(steel)
    K2 = symmetric_from_upper(assemble_upper(p2, lam, mu))
    Iv = sp.kron(p1_interpolation(p2), sp.identity(3), format="csr")
    K1 = (Iv.T @ K2 @ Iv).toarray()
    basis = skfem.Basis(p2.mesh, skfem.ElementVector(skfem.ElementTetP1()))
    ref = skfem.asm(linear_elasticity(lam, mu), basis).toarray()  # DOF 3 n + c, as ours
    assert np.max(np.abs(K1 - ref)) < 1e-9 * np.max(np.abs(ref))
    R = rigid_motion_matrix(p2.points[:p2.n_vertices], [1.0, 2.0, 3.0], np.eye(3)).reshape(-1, 6)
    assert np.max(np.abs(K1 @ R)) < 1e-9 * np.max(np.abs(ref)) * np.max(np.abs(R))
