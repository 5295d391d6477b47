"""Sparse factorizers of the reduced P2 stiffness: MKL PARDISO (SPD, upper triangle) and SuperLU.

A factorizer takes the upper triangle (CSR, symmetric positive definite) and returns a
:class:`~linkfea.solvers.factorization.Factorization`: ``solve(B)`` with what the result records of it (the factorizer's name, the
reason of a fallback, the iterative solvers' convergence, the automatic choice), which
:func:`linkfea.fem.problem.solve_link` copies into its :class:`~linkfea.solvers.factorization.SolverRecord`.  What a factorizer needs
besides the matrix (the P1 coarse space, the rigid-body modes) is said by :data:`NEEDS`.
"""
from __future__ import annotations

import logging
import warnings
from dataclasses import replace
from typing import Callable

import numpy as np
import scipy.sparse as sp

from .factorization import Factorization
from .sparse import symmetric_from_upper
from .sparse_mkl import point_pypardiso_at_mkl as _point_pypardiso_at_mkl

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------
# Solvers: a factorizer takes the upper triangle (CSR, SPD) and returns solve(B)
# --------------------------------------------------------------------------
_PARDISO = []  # one solver object per process

PARDISO_IPARM = {1: 1, 2: 3, 8: 0, 10: 8, 18: -1, 21: 1}
"""PARDISO controls (1-based, as in MKL's manual), MKL's defaults except ``iparm(8) = 0``: no
iterative refinement.  MKL's default runs two refinement steps after every solve (each a solve
and a product with the matrix, ~0.2 s on the foot's 63k DOF); on these SPD systems the
unrefined Cholesky solution already agrees with it to 3e-11 (relative, reference twists).
``iparm(1) = 1`` says the others are given: ``iparm(2) = 3`` parallel nested dissection
(METIS), ``iparm(10) = 8`` pivot perturbation 1e-8, ``iparm(18) = -1`` report the factor's
non-zeros, ``iparm(21) = 1`` Bunch-Kaufman pivoting (unused for SPD)."""


def pardiso_factorizer(U: sp.csr_matrix) -> Factorization:
    """Factor with MKL PARDISO, real symmetric positive definite (mtype=2), upper triangle."""
    _point_pypardiso_at_mkl()
    import pypardiso

    if not _PARDISO:
        _PARDISO.append(pypardiso.PyPardisoSolver(mtype=2))
    solver = _PARDISO[0]
    solver.set_matrix_type(2)
    for i, v in PARDISO_IPARM.items():
        solver.set_iparm(i, v)
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

    return Factorization(solve, "pardiso")


def scipy_factorizer(U: sp.csr_matrix) -> Factorization:
    """Factor with SuperLU on the full symmetric matrix (fallback; slower)."""
    from scipy.sparse.linalg import splu

    K = symmetric_from_upper(U).tocsc()
    lu = splu(K, permc_spec="MMD_AT_PLUS_A")

    def solve(B):
        return lu.solve(np.asarray(B, dtype=float))

    return Factorization(solve, "superlu")


def default_factorizer(U: sp.csr_matrix) -> Factorization:
    """PARDISO if available and successful, else SuperLU; a fallback is logged and recorded in the
    factorization's ``fallback_reason``."""
    try:
        return pardiso_factorizer(U)
    except ImportError as exc:  # pypardiso is not installed (e.g. not x86-64): the documented fallback
        reason = f"pypardiso not available ({exc})"
        log.info("PARDISO not used: %s; factoring with SuperLU", reason)
    except Exception as exc:  # PARDISO installed but failed: say so, loudly
        reason = f"PARDISO failed: {type(exc).__name__}: {exc}"
        log.warning("%s; falling back to SuperLU (slower)", reason)
        warnings.warn(f"{reason}; falling back to SuperLU", RuntimeWarning, stacklevel=2)
    return replace(scipy_factorizer(U), fallback_reason=reason)


def auto_factorizer(U: sp.csr_matrix, coarse=None, progress=None) -> Factorization:
    """The direct factorization if its estimated peak memory fits (:func:`linkfea.solvers.iterative.choose`),
    else CG with multigrid; the choice and its figures are recorded in the factorization's ``choice``."""
    from . import iterative

    n = U.shape[0]
    budget = iterative.available_bytes()
    kind = iterative.choose(n, budget)
    f = default_factorizer(U) if kind == "direct" else iterative.cg_p1mg_factorizer(U, coarse, progress=progress)
    return replace(f, choice={"chosen": kind, "estimated_direct_peak_gb": iterative.direct_peak_bytes(n) / 1e9,
                              "estimated_iterative_peak_gb": iterative.iterative_peak_bytes(n) / 1e9,
                              "budget_gb": budget / 1e9})


def needs(factorizer: Callable) -> str:
    """What ``factorizer`` takes besides the matrix: ``"coarse_space"`` (a function that builds the P1
    coarse space, and ``progress``), ``"near_nullspace"`` (the rigid-body modes, and ``progress``) or ``""``."""
    from .iterative import cg_amg_factorizer, cg_p1mg_factorizer

    if factorizer in (auto_factorizer, cg_p1mg_factorizer):
        return "coarse_space"
    return "near_nullspace" if factorizer is cg_amg_factorizer else ""


def factorizer_named(kind: str) -> Callable:
    """The factorizer of ``--solver``: ``auto`` (by the memory estimate), ``direct`` or ``iterative``."""
    from ..runtime.errors import LinkFeaError
    from .iterative import cg_p1mg_factorizer

    table = {"auto": auto_factorizer, "direct": default_factorizer, "iterative": cg_p1mg_factorizer}
    if kind not in table:
        raise LinkFeaError(f"unknown solver {kind!r}; use auto, direct or iterative")
    return table[kind]
