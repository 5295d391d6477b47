"""Invariants of the link compliance: reciprocity, frame covariance, block -> rigid limit."""
import dataclasses

import numpy as np
import pytest
from meshes import bar_link_mesh

from linkfea.fem.fit import compliance_from_solution
from linkfea.fem.problem import solve_link
from linkfea.mechanics.frames import Frame
from linkfea.runtime.errors import LinkFeaError


@pytest.fixture(scope="module")
def block_bar():
    """200 x 20 x 10 bar (coarse, 10 mm cells) with a 10 mm reference block beyond x = 200."""
    return bar_link_mesh(200.0, 20.0, 10.0, 20, 4, 2, block_length=10.0, nb=2)


def _scaled_diff(A, B):
    d = np.sqrt(np.diag(B))
    return np.linalg.norm((A - B) / np.outer(d, d))


def test_reciprocity_rigid_mode(block_bar, steel):
    """Maxwell-Betti: the raw (fitted, unsymmetrized) compliance is symmetric to solver precision."""
    c = compliance_from_solution(solve_link(block_bar, steel, mode="rigid"))
    assert c.symmetry_error < 1e-6
    assert c.fit_residual < 1e-10  # coupled nodes move rigidly by construction


def test_frame_change_is_the_adjoint_map(block_bar, steel):
    """Recomputing with the reference frame moved and rotated equals the adjoint transform of the tip result.

    In rigid mode the coupled nodes are the same whatever the reference point,
    so the two must agree to solver round-off (1e-8 relative).
    """
    sol = solve_link(block_bar, steel)
    tip = compliance_from_solution(sol)
    c, s = np.cos(0.5), np.sin(0.5)
    axes = np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, np.cos(0.3), np.sin(0.3)], [0.0, -np.sin(0.3), np.cos(0.3)]])
    other = Frame(np.array([150.0, 7.0, -4.0]), axes)
    moved = compliance_from_solution(solve_link(dataclasses.replace(block_bar, frame=other), steel))
    expected = tip.frame.compliance_to(tip.matrix, other)
    assert _scaled_diff(moved.matrix, expected) < 1e-8
    # The same result without a new solve: adjoint of the Compliance, or the fit done in the other frame.
    assert _scaled_diff(tip.to_frame(other).matrix, expected) < 1e-12
    assert _scaled_diff(compliance_from_solution(sol, other).matrix, expected) < 1e-9


def test_block_mode_converges_to_rigid_mode(block_bar, steel):
    """The paper's pseudo-rigid block tends to exact rigid coupling as its modulus ratio grows.

    The difference (diagonally scaled Frobenius norm) decreases monotonically
    over ratios 10, 100, 1000, 1e4 (roughly as 1/ratio) and is below 1e-4 at 1e4.
    """
    rigid = compliance_from_solution(solve_link(block_bar, steel, mode="rigid")).matrix
    diffs = []
    for ratio in (10.0, 100.0, 1000.0, 1e4):
        sol = solve_link(block_bar, steel, mode="block", block_ratio=ratio)
        c = compliance_from_solution(sol)
        assert c.symmetry_error < 1e-5
        diffs.append(_scaled_diff(c.matrix, rigid))
    assert all(a > b for a, b in zip(diffs, diffs[1:])), diffs
    assert diffs[-1] < 1e-4
    assert diffs[0] > 1e-3  # a soft block is visibly different: the test can fail


def test_block_mode_needs_block_cells(steel):
    mesh = bar_link_mesh(20.0, 4.0, 4.0, 2, 1, 1)
    with pytest.raises(LinkFeaError, match="block"):
        solve_link(mesh, steel, mode="block")
    with pytest.raises(LinkFeaError, match="mode"):
        solve_link(mesh, steel, mode="soft")


def test_overlapping_interfaces_are_an_error(steel):
    mesh = bar_link_mesh(20.0, 4.0, 4.0, 2, 1, 1)
    bad = dataclasses.replace(mesh, tip_facets=mesh.base_facets)
    with pytest.raises(LinkFeaError, match="overlap"):
        solve_link(bad, steel)


def test_scipy_fallback_solver_agrees(steel):
    """The SuperLU fallback gives the same compliance as PARDISO (injectable solver).

    Skips only where pypardiso is not installed; an installed PARDISO that fails is a failure."""
    from linkfea.solvers.factorizers import pardiso_factorizer, scipy_factorizer

    pytest.importorskip("pypardiso")
    mesh = bar_link_mesh(40.0, 6.0, 4.0, 8, 2, 2)
    sa = solve_link(mesh, steel, solver=scipy_factorizer)
    sb = solve_link(mesh, steel, solver=pardiso_factorizer)
    assert sa.solver.factorizer == "superlu" and sb.solver.factorizer == "pardiso"
    a, b = compliance_from_solution(sa).matrix, compliance_from_solution(sb).matrix
    assert _scaled_diff(a, b) < 1e-9


def test_default_solver_is_recorded_and_a_fallback_is_said(steel, monkeypatch, caplog):
    """The default factorizer records what ran; a failing PARDISO falls back to SuperLU with a
    warning (logged and as a RuntimeWarning) and the reason in FeaSolution.solver."""
    import logging

    import linkfea.solvers.factorizers as solvers

    mesh = bar_link_mesh(40.0, 6.0, 4.0, 8, 2, 2)
    try:
        import pypardiso  # noqa: F401
        expected = "pardiso"
    except ImportError:
        expected = "superlu"
    ok = solve_link(mesh, steel)
    assert ok.solver.factorizer == expected

    def broken(U):
        raise RuntimeError("PARDISO error -3 (simulated)")

    monkeypatch.setattr(solvers, "pardiso_factorizer", broken)
    with caplog.at_level(logging.WARNING, logger="linkfea.solvers.factorizers"), pytest.warns(RuntimeWarning, match="SuperLU"):
        fb = solve_link(mesh, steel)
    assert fb.solver.factorizer == "superlu"
    assert "error -3" in fb.solver.fallback_reason
    assert any("falling back to SuperLU" in r.getMessage() for r in caplog.records)
    assert _scaled_diff(compliance_from_solution(fb).matrix, compliance_from_solution(ok).matrix) < 1e-9


def test_solution_contents_and_progress(steel):
    """Clamped nodes do not move, coupled nodes move rigidly, stages are reported in order."""
    from linkfea.fem.fit import fit_rigid_motion

    mesh = bar_link_mesh(40.0, 6.0, 4.0, 8, 2, 2)
    stages = []
    sol = solve_link(mesh, steel, progress=stages.append)
    assert stages == ["assemble", "factor", "solve"]
    assert set(sol.timing) == {"assemble", "factor", "solve"}
    assert sol.displacements.shape == (6, len(sol.points), 3)
    assert np.allclose(sol.points[:sol.n_vertices], mesh.points)
    assert np.all(sol.displacements[:, sol.clamped_nodes] == 0.0)
    assert np.allclose(sol.points[sol.clamped_nodes, 0], 0.0)
    # Unit Fx stretches the bar: tip moves +x by about L / (E A).
    twists, res = fit_rigid_motion(sol.points[sol.ref_nodes], sol.displacements[:, sol.ref_nodes],
                                   mesh.frame.origin)
    assert np.all(res < 1e-10)
    assert np.allclose(twists.T, sol.ref_twists, rtol=1e-10, atol=1e-16)
    assert twists[0, 0] == pytest.approx(40.0 / (steel.E * 24.0), rel=0.02)


def test_floating_part_is_a_clear_error(steel):
    """A piece not connected to the clamp makes K singular: LinkFeaError naming the likely cause."""
    mesh = bar_link_mesh(40.0, 6.0, 4.0, 8, 2, 2)
    n = len(mesh.points)
    far = np.array([[100.0, 0, 0], [101.0, 0, 0], [100.0, 1, 0], [100.0, 0, 1]])
    bad = dataclasses.replace(mesh, points=np.vstack([mesh.points, far]),
                              tets=np.vstack([mesh.tets, [[n, n + 1, n + 2, n + 3]]]),
                              block=np.r_[mesh.block, False])
    with pytest.raises(LinkFeaError, match="clamped and connected|singular"):
        solve_link(bad, steel)
