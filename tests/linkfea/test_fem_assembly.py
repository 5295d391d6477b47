"""The vectorized P2 assembly and the P2 topology against scikit-fem and first principles."""
import numpy as np
import pytest
import skfem
from meshes import bar_link_mesh, box_mesh, skfem_dof_order
from skfem.models.elasticity import linear_elasticity

from linkfea.fem.p2 import assemble_upper, lame, p2_mesh
from linkfea.mechanics.frames import rigid_motion_matrix
from linkfea.runtime.errors import LinkFeaError
from linkfea.solvers.sparse import symmetric_from_upper


def _perturbed_box():
    pts, tets, _ = box_mesh(2.0, 1.0, 1.0, 2, 2, 1)
    rng = np.random.default_rng(1)
    inner = np.all((pts > pts.min(0) + 1e-9) & (pts < pts.max(0) - 1e-9), axis=1)
    pts = pts + 0.08 * rng.standard_normal(pts.shape) * (1 + inner[:, None])
    return pts, tets


def test_assembly_equals_skfem(steel):
    """Our P2 stiffness equals scikit-fem's ``linear_elasticity`` (ElementTetP2) on a distorted mesh.

    Both integrate the product of linear gradients exactly, so they must agree
    to round-off (1e-12 relative); DOFs are matched by their coordinates.
    """
    pts, tets = _perturbed_box()
    lam, mu = lame(steel)
    basis = skfem.Basis(skfem.MeshTet(pts.T, tets.T), skfem.ElementVector(skfem.ElementTetP2()), intorder=2)
    K_ref = skfem.asm(linear_elasticity(lam, mu), basis).toarray()

    p2 = p2_mesh(pts, tets)
    K = symmetric_from_upper(assemble_upper(p2, lam, mu)).toarray()
    ours = skfem_dof_order(p2.points, basis)
    assert len(np.unique(ours)) == K.shape[0]
    K_ours = K[np.ix_(ours, ours)]
    assert np.abs(K_ours - K_ref).max() <= 1e-12 * np.abs(K_ref).max()


def test_assembly_rigid_modes_and_block_scale(steel):
    """K annihilates the 6 rigid motions, is symmetric, and scaling E scales K (physics invariants)."""
    pts, tets = _perturbed_box()
    p2 = p2_mesh(pts, tets)
    lam, mu = lame(steel)
    U = assemble_upper(p2, lam, mu)
    K = symmetric_from_upper(U)
    Rm = rigid_motion_matrix(p2.points, [0.3, -0.2, 0.1], np.eye(3)).reshape(-1, 6)
    assert np.abs(K @ Rm).max() < 1e-9 * abs(K).max() * np.abs(Rm).max()
    U2 = assemble_upper(p2, lam, mu, scale=np.full(len(tets), 7.0))
    assert abs(U2 - 7.0 * U).max() < 1e-12 * abs(U2).max()
    assert np.all(K.diagonal() > 0)


def test_p2_topology_and_facets():
    """Edge nodes sit at midpoints; facet nodes of a triangle are its 3 vertices and 3 edge midpoints."""
    mesh = bar_link_mesh(4.0, 2.0, 2.0, 2, 1, 1)
    p2 = p2_mesh(mesh.points, mesh.tets)
    e = p2.edges
    assert np.allclose(p2.points[p2.n_vertices:], 0.5 * (p2.points[e[:, 0]] + p2.points[e[:, 1]]))
    nodes = p2.facet_nodes(mesh.base_facets)
    # base x = 0 face of a 1x1 grid of hexes: 2x2 vertices + 5 edges (4 sides + 1 diagonal) -> 9 nodes
    assert len(nodes) == 9 and np.allclose(p2.points[nodes, 0], 0.0)
    with pytest.raises(LinkFeaError):
        p2.facet_nodes(np.array([[0, 1, len(mesh.points) + 3]]))


def test_inverted_tet_is_an_error(steel):
    mesh = bar_link_mesh(4.0, 2.0, 2.0, 2, 1, 1)
    bad = mesh.tets.copy()
    bad[0] = bad[0][[1, 0, 2, 3]]
    p2 = p2_mesh(mesh.points, bad)
    with pytest.raises(LinkFeaError, match="negatively oriented"):
        assemble_upper(p2, *lame(steel))


def test_scikit_fem_owns_the_discretization(steel):
    """P2 nodes, numbering and locations are scikit-fem's: its vector basis's DOF 3 n + c sits at our
    node n, and the kernel equals ``skfem.asm`` entry by entry with no renumbering (block scale too)."""
    from linkfea.fem.p2 import assemble_upper_skfem

    pts, tets = _perturbed_box()
    p2 = p2_mesh(pts, tets)
    basis = skfem.Basis(p2.mesh, skfem.ElementVector(skfem.ElementTetP2()), intorder=2)
    locs = basis.doflocs.T
    assert np.abs(locs[0::3] - p2.points).max() < 1e-12 and np.array_equal(locs[0::3], locs[2::3])
    assert np.array_equal(basis.element_dofs[0::3].T // 3, p2.cells)
    lam, mu = lame(steel)
    scale = np.where(np.arange(len(tets)) % 3 == 0, 1000.0, 1.0)
    for s in (None, scale):
        K = assemble_upper(p2, lam, mu, s)
        K_ref = assemble_upper_skfem(p2, lam, mu, s)
        assert abs(K - K_ref).max() <= 1e-12 * abs(K_ref).max()


@pytest.mark.parametrize("mode", ["rigid", "block"])
def test_skfem_assembler_gives_the_same_compliance(steel, mode):
    """``--assembler skfem`` (scikit-fem's asm) and the kernel: the same 6x6 to round-off.

    The two stiffness matrices agree to 1e-12 of their largest entry (test above); the solve
    amplifies that by the condition number, which the 1000x stiffer block raises: measured
    about 5e-11 (rigid) and 7e-9 (block), hence 1e-9 and 1e-7."""
    from linkfea.fem.fit import compliance_from_solution
    from linkfea.fem.problem import solve_link

    mesh = bar_link_mesh(40.0, 6.0, 4.0, 8, 2, 2, block_length=4.0, nb=1) if mode == "block" else \
        bar_link_mesh(40.0, 6.0, 4.0, 8, 2, 2)
    a = solve_link(mesh, steel, mode=mode)
    b = solve_link(mesh, steel, mode=mode, assembler="skfem")
    assert a.solver.assembler == "kernel" and b.solver.assembler == "skfem"
    Ca, Cb = compliance_from_solution(a).matrix, compliance_from_solution(b).matrix
    d = np.sqrt(np.outer(np.diag(Ca), np.diag(Ca)))
    assert np.max(np.abs(Ca - Cb) / d) < (1e-9 if mode == "rigid" else 1e-7)
