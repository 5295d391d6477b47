"""A symmetric multigrid V-cycle that works on blocks of right-hand sides (the 6 load cases).

Level 0 is the P2 system, level 1 its P1 Galerkin operator (:mod:`linkfea.fem.coarse`), the levels
below are pyamg's smoothed aggregation of the P1 operator with the rigid-body modes; the
coarsest is factored.  Every level smooths with a Chebyshev polynomial in the Jacobi-
scaled operator: only matrix products with (n, k) blocks (one pass over the matrix serves all
load cases), no triangular sweeps, and the same polynomial before and after the coarse
correction, so the cycle is a symmetric positive definite preconditioner and CG stays valid.

Cost of one cycle on a level with a smoother of degree ``d``: ``2 d`` products with its matrix
(the residual after pre-smoothing comes out of the Chebyshev recurrence; none is computed for
a stopping test).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import List, Optional

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

CHEBYSHEV_DEGREE = 2
"""Smoother degree on every level; a cycle costs ``2 d`` products with the P2 matrix, CG one more.
Measured (lockstep CG to 1e-8, rigid mode): the structured 98k-DOF bar takes 27, 21, 19 iterations
at degree 1, 2, 3 (81, 105, 133 products; CG 5.1, 7.1, 7.6 s); the sharp foot's unstructured,
curved 170k-DOF mesh 51 and 31 iterations at degree 1 and 2 (153 and 155 products, 13.9 and
13.0 s CPU).  Degree 2: as fast on the real part, and fewer iterations where the mesh is harder."""
AGGREGATION_DEGREE = 6
"""Smoother degree on the aggregation levels below P1 (small: more smoothing is cheap there).  Where
the hierarchy has two aggregation levels (links of about 1M DOF and more), degree 2 there made the
coarse correction weak: forced on the 170k-DOF foot, 58 CG iterations at degree 2, 41 at 6, 38 at
12 (31 with the first aggregation level solved exactly); on the 149k-DOF bar 50 and 40 (CPU 9.6 and
8.8 s)."""
SMOOTHING_RANGE = 30.0
"""The Chebyshev polynomial damps the eigenvalues of ``D^-1 A`` in [lmax / 30, lmax]: the upper
part of the spectrum, which the coarse level cannot represent (the usual ratio for elasticity)."""
MAX_COARSE = 600
"""The aggregation stops once at most this many node blocks are left (pyamg counts block rows: 6 DOFs
each below P1, one per rigid-body mode); the coarsest level, a few thousand DOFs, is factored (sparse
LU).  Measured on the 170k-DOF foot: one more aggregation level (2,754 -> 84 DOFs) doubles the CG
iterations (58 against 31); the LU solves of the 2,754-DOF level cost about 10% of the CG time."""


@dataclass
class Level:
    """One level: its operator ``A`` (full symmetric), inverse diagonal, the largest eigenvalue
    of ``D^-1 A`` (an upper estimate) and the prolongation ``P`` to it from the next coarser level."""

    A: sp.spmatrix
    dinv: np.ndarray
    lmax: float
    P: Optional[sp.csr_matrix] = None
    R: Optional[sp.csr_matrix] = None


def _norm(v: np.ndarray) -> float:
    # einsum, not BLAS: no thread pool to wait for on a busy machine.
    return float(np.sqrt(np.einsum("i,i->", v, v)))


def largest_eigenvalue(A, dinv: np.ndarray, steps: int = 15, seed: int = 0) -> float:
    """Upper estimate of the largest eigenvalue of ``D^-1 A``: Lanczos on ``D^-1/2 A D^-1/2``, the
    largest Ritz value plus its residual bound (a Ritz value is below the eigenvalue it approaches)."""
    s = np.sqrt(dinv)
    n = A.shape[0]
    steps = min(steps, n)
    v = np.random.default_rng(seed).standard_normal(n)
    v /= _norm(v)
    alpha, beta = np.zeros(steps), np.zeros(steps)
    v_prev, b_prev = np.zeros(n), 0.0
    for k in range(steps):
        w = s * (A @ (s * v)) - b_prev * v_prev
        alpha[k] = float(np.einsum("i,i->", v, w))
        w -= alpha[k] * v
        beta[k] = _norm(w)
        if beta[k] <= 1e-12 * abs(alpha[k]) or k == steps - 1:
            steps = k + 1
            break
        v_prev, v, b_prev = v, w / beta[k], beta[k]
    theta, vecs = la.eigh_tridiagonal(alpha[:steps], beta[:steps - 1])
    return float(theta[-1] + abs(beta[steps - 1] * vecs[-1, -1]))


def _level(A) -> Level:
    d = np.asarray(A.diagonal(), dtype=float)
    dinv = (1.0 / d)[:, None]
    return Level(A, dinv, largest_eigenvalue(A, dinv[:, 0]))


def chebyshev(level: Level, res: np.ndarray, X: Optional[np.ndarray], degree: int, want_residual: bool):
    """``X + q(D^-1 A) D^-1 res`` (Chebyshev on [lmax / SMOOTHING_RANGE, lmax]) and, if asked, its residual.

    ``res`` is the residual of ``X`` (``X`` None: zero); ``X`` is updated in place, ``res`` is not.
    ``degree - 1`` products with ``A``, one more for the residual; the block updates reuse their
    arrays (these (n, 6) passes are most of a cycle's time besides the products).
    """
    hi = level.lmax
    lo = hi / SMOOTHING_RANGE
    theta, delta = 0.5 * (hi + lo), 0.5 * (hi - lo)
    sigma = theta / delta
    rho = 1.0 / sigma
    D = res * (level.dinv / theta)
    if X is None:
        X = D.copy()
    else:
        X += D
    tmp = np.empty_like(D) if degree > 1 else None
    for _ in range(1, degree):
        AD = level.A @ D
        res = np.subtract(res, AD, out=AD)  # a new array: the caller's res is left alone
        rho_new = 1.0 / (2.0 * sigma - rho)
        D *= rho_new * rho
        D += np.multiply(res, level.dinv * (2.0 * rho_new / delta), out=tmp)
        X += D
        rho = rho_new
    if want_residual:
        AD = level.A @ D
        res = np.subtract(res, AD, out=AD)
    return X, res


class Hierarchy:
    """The levels and the dense Cholesky factor of the coarsest operator; ``cycle(B)`` applies
    one V-cycle (a symmetric positive definite approximation of ``A^-1``) to a block ``B`` (n, k)."""

    def __init__(self, operators: List, prolongations: List[sp.csr_matrix], degree: int = CHEBYSHEV_DEGREE):
        self.levels = [_level(A) for A in operators[:-1]]
        for lev, P in zip(self.levels, prolongations):
            lev.P, lev.R = sp.csr_matrix(P), sp.csr_matrix(P.T)
        # The coarsest level by a sparse LU: no multithreaded BLAS, whose threads wait for a core on a busy machine.
        self.coarse = spla.splu(sp.csc_matrix(operators[-1]))
        self.sizes = [int(A.shape[0]) for A in operators]
        self.degree = degree

    def cycle(self, B: np.ndarray, k: int = 0) -> np.ndarray:
        if k == len(self.levels):
            return self.coarse.solve(np.asarray(B))
        lev = self.levels[k]
        degree = self.degree if k < 2 else AGGREGATION_DEGREE
        X, res = chebyshev(lev, B, None, degree, want_residual=True)
        E = lev.P @ self.cycle(lev.R @ res, k + 1)
        X += E
        res -= lev.A @ E  # res is the smoother's own array
        X, _ = chebyshev(lev, res, X, degree, want_residual=False)
        return X

    def operator_complexity(self) -> float:
        """Stored entries of all the levels' operators over the finest one's (the fine level's upper
        triangle counted as the full matrix)."""
        nnz = [2 * lev.A.nnz - lev.A.shape[0] if k == 0 else lev.A.nnz for k, lev in enumerate(self.levels)]
        return float(sum(nnz) / nnz[0]) if nnz else 1.0


def galerkin_from_upper(U: sp.csr_matrix, P: sp.csr_matrix) -> sp.csr_matrix:
    """``P^T A P`` for the symmetric ``A`` given by its upper triangle ``U``: ``Q + Q^T - P^T D P``
    with ``Q = P^T U P`` (no full copy of ``A``)."""
    Q = (P.T @ (U @ P)).tocsr()
    D = sp.diags(np.asarray(U.diagonal(), dtype=float))
    Ac = (Q + Q.T - P.T @ (D @ P)).tocsr()
    Ac.sort_indices()
    return Ac


def p1_sa_hierarchy(U: sp.csr_matrix, P1: sp.csr_matrix, B1: np.ndarray, degree: Optional[int] = None) -> Hierarchy:
    """Level 0 the P2 system (upper triangle ``U``), level 1 its P1 Galerkin operator, then pyamg
    smoothed aggregation of the P1 operator with its rigid-body modes ``B1`` (node blocks of 3
    DOFs) down to :data:`MAX_COARSE`.  Products through MKL where available (:mod:`linkfea.solvers.sparse_mkl`)."""
    import pyamg

    from .sparse_mkl import operator

    Ac = galerkin_from_upper(U, P1)
    ops, pros = [operator(U, symmetric_upper=True), operator(Ac)], [P1]
    ml = None
    if Ac.shape[0] > MAX_COARSE:
        Ab = Ac.tobsr(blocksize=(3, 3)) if Ac.shape[0] % 3 == 0 else Ac
        ml = pyamg.smoothed_aggregation_solver(Ab, B=B1, symmetry="hermitian", strength="symmetric",
                                               smooth=("jacobi", {"omega": 4.0 / 3.0, "weighting": "local"}), max_coarse=MAX_COARSE,
                                               keep=False)
    if ml is not None and len(ml.levels) > 1:
        for lev in ml.levels[1:-1]:
            ops.append(operator(lev.A.tocsr()))
        for lev in ml.levels[:-1]:
            pros.append(lev.P.tocsr())
        ops.append(ml.levels[-1].A)
    else:
        # Nothing to aggregate (pyamg counts 3-DOF blocks against MAX_COARSE, so a P1 level of up to
        # 3 MAX_COARSE DOFs gives it one level): the P1 level is the coarsest and is factored.
        ops[-1] = Ac
    return Hierarchy(ops, pros, CHEBYSHEV_DEGREE if degree is None else degree)
