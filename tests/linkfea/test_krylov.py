"""Lockstep CG over several right-hand sides (linkfea.solvers.krylov) and the multigrid cycle's symmetry."""
import numpy as np
import pytest
import scipy.sparse as sp

from linkfea.solvers.krylov import cg_columns, time_left
from linkfea.solvers.multigrid import Hierarchy, largest_eigenvalue


def _laplacian(n):
    T = sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    return (sp.kron(T, sp.identity(n)) + sp.kron(sp.identity(n), T)).tocsr()


def test_lockstep_cg_solves_each_column_to_its_own_tolerance():
    A = _laplacian(20)
    rng = np.random.default_rng(0)
    B = rng.standard_normal((A.shape[0], 4)) * np.array([1.0, 1e-6, 0.0, 1e3])  # scales differ; one is zero
    msgs = []
    r = cg_columns(A, B, lambda R: R / 4.0, rtol=1e-10, maxiter=1000, progress=msgs.append, every=0.0)
    X = np.linalg.solve(A.toarray(), B)
    for j in (0, 1, 3):
        assert np.linalg.norm(r.X[:, j] - X[:, j]) <= 1e-8 * np.linalg.norm(X[:, j])
        assert 0 < r.iterations[j] < 1000 and r.relative_residual[j] < 1e-9
    assert r.iterations[2] == 0 and not r.X[:, 2].any()
    assert any("CG iteration" in m and "s left" in m for m in msgs)
    assert time_left([1.0, 0.1, 0.01], 1e-8, 2.0) == pytest.approx(6 * 2.0)  # one decade per iteration, six to go


def test_the_v_cycle_is_a_symmetric_positive_definite_operator():
    """CG needs a symmetric preconditioner: the cycle's matrix M satisfies M = M^T, M > 0."""
    A = _laplacian(12)
    n = A.shape[0]
    # Coarse space: pairs of neighbouring nodes in one direction (piecewise constant).
    P = sp.kron(sp.identity(12), sp.kron(sp.identity(6), np.ones((2, 1)))).tocsr()
    Ac = (P.T @ A @ P).tocsr()
    h = Hierarchy([A, Ac], [P])
    M = h.cycle(np.eye(n))
    assert np.max(np.abs(M - M.T)) < 1e-12 * np.max(np.abs(M))
    assert np.linalg.eigvalsh(0.5 * (M + M.T)).min() > 0
    lmax = np.linalg.eigvalsh(A.toarray() / 4.0).max()
    assert lmax <= largest_eigenvalue(A, np.full(n, 0.25)) <= 1.1 * lmax
