"""Conjugate gradients with multigrid preconditioners, and the memory estimate that chooses
between the iterative path and the direct factorization.

Factorizers in the sense of :mod:`linkfea.solvers.factorizers`: they take the upper triangle (CSR, SPD) and
return a :class:`~linkfea.solvers.factorizers.Factorization` whose ``convergence`` the solve fills in
(iterations and final relative residual per load case).

- :func:`cg_p1mg_factorizer` (``--solver iterative``): the 6 load cases in lockstep CG
  (:mod:`linkfea.solvers.krylov`) preconditioned by a V-cycle with Chebyshev smoothing on the P2
  system, its P1 Galerkin operator as the first coarse level (:mod:`linkfea.fem.coarse`) and pyamg
  smoothed aggregation with the rigid-body modes below (:mod:`linkfea.solvers.multigrid`).
  :func:`linkfea.fem.problem.solve_link` passes the coarse space
  (:func:`linkfea.solvers.factorizers.needs`).
- :func:`cg_amg_factorizer`: scipy's CG per load case with pyamg smoothed aggregation on the P2
  matrix itself (rigid-body modes as ``near_nullspace``); the earlier path, kept for the
  benchmarks' comparison and for callers that have only the matrix.

Why not a direct solver for everything: PARDISO's Cholesky factor of a 3D P2 problem grows
like n^(4/3); the sharp foot at 871,710 DOF peaked at 12.0 GB (docs/benchmarks.md).  CG with
AMG needs a few copies of the matrix.
"""
from __future__ import annotations

import logging
import os
import time
from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp

from ..runtime.errors import LinkFeaError, SolverError
from ..runtime.memory import available_memory
from .factorization import Factorization
from .sparse import symmetric_from_upper

log = logging.getLogger(__name__)

RTOL = 1e-8
"""Relative residual ``||b - A x|| / ||b||`` at which CG stops.  Measured on a 5k-DOF bar: the 6x6
agrees with the direct solve to 2e-7, 2e-8, 2e-9 at rtol 1e-6, 1e-7, 1e-8 (45-60 iterations at
1e-8, 20% fewer than at 1e-10), so 1e-8 keeps a wide margin under the 1e-6 the project asks.
The P1-multigrid path at 1e-8: 16-20 iterations on a 149k-DOF bar, 25-31 on the 170k-DOF foot,
6x6 within 5e-9 of the direct solve."""
MAXITER = 2000

DIRECT_PEAK_BYTES_AT = (871_710, 12.0e9)
"""Measured peak memory of the direct path: the sharp foot at 871,710 DOF, 12.0 GB
(docs/benchmarks.md).  The estimate scales it as n^(4/3), nested dissection's fill in 3D."""


def direct_peak_bytes(n_dofs: int) -> float:
    """Estimated peak memory (bytes) of assembling and factoring ``n_dofs`` with PARDISO."""
    n0, b0 = DIRECT_PEAK_BYTES_AT
    return b0 * (n_dofs / n0) ** (4.0 / 3.0)


ITERATIVE_PEAK_BYTES_PER_DOF = 4.1e3
"""Measured peak memory of the P1-multigrid path per DOF (the structured bar at 172,299 DOF:
0.71 GB, assembly included; docs/benchmarks.md); it grows linearly with the size."""


def iterative_peak_bytes(n_dofs: float) -> float:
    """Estimated peak memory (bytes) of assembling and solving ``n_dofs`` with the P1-multigrid CG."""
    return ITERATIVE_PEAK_BYTES_PER_DOF * n_dofs


def available_bytes() -> float:
    """Memory the solve may use: ``LINKFEA_MEMORY`` (GB) if set, else 60% of the memory available now."""
    env = os.environ.get("LINKFEA_MEMORY")
    if env:
        return float(env) * 1e9
    return 0.6 * available_memory()


MIN_ITERATIVE_DOFS = 150_000
"""Below this size ``auto`` always factors: a small link's result then does not depend on how much
memory the machine happens to have free (the two paths agree to 1e-9 on the 6x6 anyway)."""

ITERATIVE_FROM_DOFS = 250_000
"""From this size ``auto`` takes the iterative path even where the factorization would fit: measured
side by side (docs/benchmarks.md), P1-multigrid CG is as fast as PARDISO at 170k DOF on the sharp
foot (17.2 s against 18.2 s CPU, 1.26 GB against 1.96 GB peak) and 2x faster on a 149k-DOF bar
(5.3 s against 10.4 s CPU), and the factorization's cost grows faster with the size."""


def choose(n_dofs: int, budget: Optional[float] = None) -> str:
    """``"direct"`` below :data:`MIN_ITERATIVE_DOFS`; ``"iterative"`` from :data:`ITERATIVE_FROM_DOFS`
    or where the direct solver's estimated peak does not fit the budget; else ``"direct"``."""
    budget = available_bytes() if budget is None else budget
    if n_dofs < MIN_ITERATIVE_DOFS:
        return "direct"
    if n_dofs >= ITERATIVE_FROM_DOFS or direct_peak_bytes(n_dofs) > budget:
        return "iterative"
    return "direct"


def cg_p1mg_factorizer(U: sp.csr_matrix, coarse=None, rtol: float = RTOL,
                       progress: Optional[Callable[[str], None]] = None):
    """CG on the 6 load cases in lockstep, preconditioned by the P2 / P1 / smoothed-aggregation V-cycle.

    ``coarse`` is a :class:`linkfea.fem.coarse.CoarseSpace` or a function that returns one (built
    only here, when the iterative path is taken).
    """
    from .krylov import cg_columns
    from .multigrid import p1_sa_hierarchy

    say = progress or (lambda msg: None)
    if coarse is None:
        raise SolverError("the iterative solver needs the P1 coarse space of the link (solve through solve_link)")
    t0 = time.perf_counter()
    U = sp.csr_matrix(U)
    U.sort_indices()
    n = U.shape[0]
    say(f"solve: multigrid setup ({n:,} DOF)")
    space = coarse() if callable(coarse) else coarse
    try:
        h = p1_sa_hierarchy(U, space.P, space.near_nullspace)
    except LinkFeaError:
        raise
    except (ValueError, ArithmeticError, RuntimeError, np.linalg.LinAlgError) as exc:
        # pyamg's and SuperLU's errors on a degenerate hierarchy: the package's error type, one line
        raise SolverError(f"the multigrid setup failed on {n:,} DOF ({type(exc).__name__}: {exc}); "
                          "use the direct solver (--solver direct)") from exc
    A = h.levels[0].A
    setup = time.perf_counter() - t0
    stats: dict = {"method": "CG on the load cases in lockstep; V-cycle: Chebyshev on P2, P1 Galerkin level, "
                             "pyamg smoothed aggregation (rigid-body modes)",
                   "rtol": rtol, "levels": len(h.sizes), "level_sizes": h.sizes,
                   "operator_complexity": h.operator_complexity(), "setup_seconds": setup,
                   "iterations": [], "relative_residual": []}
    log.info("multigrid: %d levels %s, setup %.1f s", len(h.sizes), h.sizes, setup)

    def solve(Bmat):
        Bmat = np.asarray(Bmat, dtype=float).reshape(n, -1)
        try:
            r = cg_columns(A, Bmat, h.cycle, rtol, MAXITER, progress=say)
        except LinkFeaError:
            raise
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            raise SolverError(f"the multigrid CG failed on {n:,} DOF ({type(exc).__name__}: {exc}); "
                              "use the direct solver (--solver direct)") from exc
        stats.update(iterations=r.iterations, relative_residual=r.relative_residual, solve_seconds=r.seconds,
                     history=r.history)
        bad = [k for k, res in enumerate(r.relative_residual) if res > 1e3 * rtol]
        if bad:
            k = bad[0]
            raise SolverError(f"CG did not converge on load case {k + 1} ({r.iterations[k]} iterations, relative "
                              f"residual {r.relative_residual[k]:.2e}); use the direct solver (--solver direct)")
        return r.X

    return Factorization(solve, "cg+p1mg", convergence=stats)


def cg_amg_factorizer(U: sp.csr_matrix, near_nullspace: Optional[np.ndarray] = None,
                      rtol: float = RTOL, progress: Optional[Callable[[str], None]] = None):
    """Preconditioned CG (pyamg smoothed aggregation with the rigid-body modes) for each column."""
    import pyamg
    from scipy.sparse.linalg import cg

    A = symmetric_from_upper(U).tocsr()
    n = A.shape[0]
    B = None if near_nullspace is None else np.asarray(near_nullspace, dtype=float).reshape(n, -1)
    t0 = time.perf_counter()
    ml = pyamg.smoothed_aggregation_solver(A, B=B, symmetry="hermitian", strength="symmetric",
                                           smooth=("energy", {"krylov": "cg", "maxiter": 2, "degree": 1}),
                                           max_coarse=1000, keep=False)
    setup = time.perf_counter() - t0
    M = ml.aspreconditioner(cycle="V")
    stats: dict = {"method": "CG, pyamg smoothed aggregation (rigid-body modes)", "rtol": rtol,
                   "levels": len(ml.levels), "operator_complexity": float(ml.operator_complexity()),
                   "setup_seconds": setup, "iterations": [], "relative_residual": []}

    def solve(Bmat):
        Bmat = np.asarray(Bmat, dtype=float).reshape(n, -1)
        X = np.zeros_like(Bmat)
        t_start = time.perf_counter()
        for k in range(Bmat.shape[1]):
            b = Bmat[:, k]
            nb = float(np.linalg.norm(b))
            if nb == 0.0:
                stats["iterations"].append(0)
                stats["relative_residual"].append(0.0)
                continue
            count = [0]

            def step(_xk, count=count, k=k):
                count[0] += 1
                if progress is not None and count[0] % 10 == 0:
                    # Time left from the cases done so far (the cases take similar iteration counts).
                    left = ""
                    if k:
                        done = (k + min(count[0] / max(max(stats["iterations"]), 1), 0.95)) / Bmat.shape[1]
                        elapsed = time.perf_counter() - t_start
                        left = f", about {elapsed * (1.0 - done) / done:.0f} s left"
                    progress(f"solve: load case {k + 1}/{Bmat.shape[1]}, CG iteration {count[0]}{left}")

            x, info = cg(A, b, rtol=rtol, atol=0.0, maxiter=MAXITER, M=M, callback=step)
            res = float(np.linalg.norm(b - A @ x) / nb)
            stats["iterations"].append(count[0])
            stats["relative_residual"].append(res)
            if info != 0 and res > 1e3 * rtol:
                raise SolverError(f"CG did not converge on load case {k + 1} ({count[0]} iterations, relative "
                                  f"residual {res:.2e}); use the direct solver (--solver direct)")
            X[:, k] = x
        return X

    return Factorization(solve, "cg+amg", convergence=stats)
