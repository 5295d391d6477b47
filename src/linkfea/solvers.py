"""Sparse factorizers of the reduced P2 stiffness: MKL PARDISO (SPD, upper triangle) and SuperLU.

A factorizer takes the upper triangle (CSR, symmetric positive definite) and returns
``solve(B)``; the returned function carries ``factorizer`` (its name) and, after a fallback,
``fallback_reason``, which :func:`linkfea.fem.solve_link` records.
"""
from __future__ import annotations

import logging
import warnings
from typing import Callable

import numpy as np
import scipy.sparse as sp

from .p2 import symmetric_from_upper

log = logging.getLogger(__name__)


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

    setattr(solve, "factorizer", "pardiso")  # noqa: B010  (read back by solve_link)
    return solve


def scipy_factorizer(U: sp.csr_matrix) -> Callable[[np.ndarray], np.ndarray]:
    """Factor with SuperLU on the full symmetric matrix (fallback; slower)."""
    from scipy.sparse.linalg import splu

    K = symmetric_from_upper(U).tocsc()
    lu = splu(K, permc_spec="MMD_AT_PLUS_A")

    def solve(B):
        return lu.solve(np.asarray(B, dtype=float))

    setattr(solve, "factorizer", "superlu")  # noqa: B010
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
    setattr(solve, "fallback_reason", reason)  # noqa: B010
    return solve
