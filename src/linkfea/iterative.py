"""Conjugate gradients with a smoothed-aggregation multigrid preconditioner (pyamg), and the
memory estimate that chooses between it and the direct factorization.

A factorizer in the sense of :mod:`linkfea.solvers`: it takes the upper triangle (CSR, SPD)
and returns ``solve(B)``.  Multigrid needs the near null space of the operator, the rigid-body
motions of the free nodes: :func:`linkfea.fem.solve_link` passes them as ``near_nullspace``
(a factorizer that sets ``wants_near_nullspace``).  The returned ``solve`` records its
convergence (iterations and final relative residual per load case) in ``convergence``.

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

from .errors import SolverError
from .p2 import symmetric_from_upper

log = logging.getLogger(__name__)

RTOL = 1e-8
"""Relative residual ``||b - A x|| / ||b||`` at which CG stops.  Measured on a 5k-DOF bar: the 6x6
agrees with the direct solve to 2e-7, 2e-8, 2e-9 at rtol 1e-6, 1e-7, 1e-8 (45-60 iterations at
1e-8, 20% fewer than at 1e-10), so 1e-8 keeps a wide margin under the 1e-6 the project asks."""
MAXITER = 2000

DIRECT_PEAK_BYTES_AT = (871_710, 12.0e9)
"""Measured peak memory of the direct path: the sharp foot at 871,710 DOF, 12.0 GB
(docs/benchmarks.md).  The estimate scales it as n^(4/3), nested dissection's fill in 3D."""


def direct_peak_bytes(n_dofs: int) -> float:
    """Estimated peak memory (bytes) of assembling and factoring ``n_dofs`` with PARDISO."""
    n0, b0 = DIRECT_PEAK_BYTES_AT
    return b0 * (n_dofs / n0) ** (4.0 / 3.0)


def available_bytes() -> float:
    """Memory the solve may use: ``LINKFEA_MEMORY`` (GB) if set, else 60% of MemAvailable."""
    env = os.environ.get("LINKFEA_MEMORY")
    if env:
        return float(env) * 1e9
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return 0.6 * float(line.split()[1]) * 1024
    except OSError:  # pragma: no cover (not Linux)
        pass
    return 8e9


MIN_ITERATIVE_DOFS = 300_000
"""Below this size ``auto`` always factors (about 3 GB at 300k DOF): a small link's result then does
not depend on how much memory the machine happens to have free."""


def choose(n_dofs: int, budget: Optional[float] = None) -> str:
    """``"direct"`` if the direct solver's estimated peak fits the budget (or the link is smaller
    than :data:`MIN_ITERATIVE_DOFS`), else ``"iterative"``."""
    budget = available_bytes() if budget is None else budget
    if n_dofs < MIN_ITERATIVE_DOFS or direct_peak_bytes(n_dofs) <= budget:
        return "direct"
    return "iterative"


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

    setattr(solve, "factorizer", "cg+amg")  # noqa: B010
    setattr(solve, "convergence", stats)  # noqa: B010
    return solve


setattr(cg_amg_factorizer, "wants_near_nullspace", True)  # noqa: B010
