"""Conjugate gradients on several right-hand sides at once (the 6 load cases), one shared preconditioner.

Each column is its own CG (its own step lengths, its own stopping test ``||r_k|| <= rtol ||b_k||``)
but the columns move in lockstep, so every product with the matrix and every preconditioner
application serve all the unconverged columns in one pass over the matrix.  A column that has
converged leaves the block.  The residual is the recurrence's: no extra product per iteration;
one true residual per column is computed at the end, for the record.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, List, Optional

import numpy as np


@dataclass(frozen=True)
class CGResult:
    """Solutions (n, k), iterations per column, final true relative residuals, and the largest
    recurrence relative residual after each iteration (the convergence history)."""

    X: np.ndarray
    iterations: List[int]
    relative_residual: List[float]
    history: List[float] = field(default_factory=list)
    seconds: float = 0.0


def _coldot(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    # einsum, not BLAS: no thread pool to wait for on a busy machine, one pass over both blocks.
    return np.einsum("ij,ij->j", X, Y)


def time_left(history: List[float], rtol: float, seconds_per_iteration: float, window: int = 8) -> Optional[float]:
    """Seconds to reach ``rtol`` at the convergence rate of the last ``window`` iterations (None: too early)."""
    if len(history) < 3 or history[-1] <= 0.0:
        return None
    a = history[max(0, len(history) - 1 - window)]
    steps = len(history) - 1 - max(0, len(history) - 1 - window)
    rate = (math.log(history[-1]) - math.log(a)) / steps if a > 0 else 0.0
    if rate >= 0.0:
        return None
    return max(0.0, (math.log(rtol) - math.log(history[-1])) / rate) * seconds_per_iteration


def cg_columns(A, B: np.ndarray, M: Callable[[np.ndarray], np.ndarray], rtol: float, maxiter: int,
               progress: Optional[Callable[[str], None]] = None, every: float = 2.0) -> CGResult:
    """Preconditioned CG for each column of ``B`` (n, k), ``M`` applied to blocks.

    ``progress`` gets a line (iteration, largest relative residual, estimated time left) at most
    every ``every`` seconds.
    """
    t0 = time.perf_counter()
    B = np.ascontiguousarray(B, dtype=float)
    n, k = B.shape
    X = np.zeros((n, k))
    bnorm = np.sqrt(_coldot(B, B))
    iters = [0] * k
    active = np.flatnonzero(bnorm > 0.0)
    history: List[float] = []
    if len(active):
        R = B[:, active].copy()
        Xa = np.zeros_like(R)
        Z = M(R)
        Pd = Z.copy()
        rz = _coldot(R, Z)
        last = t0
        for it in range(1, maxiter + 1):
            Q = A @ Pd
            alpha = rz / _coldot(Pd, Q)
            Xa += Pd * alpha
            R -= Q * alpha
            rel = np.sqrt(_coldot(R, R)) / bnorm[active]
            history.append(float(rel.max()))
            done = rel <= rtol
            if done.any() or it == maxiter:
                for j in np.flatnonzero(done | (it == maxiter)):
                    X[:, active[j]] = Xa[:, j]
                    iters[active[j]] = it
                keep = ~done
                if it == maxiter or not keep.any():
                    break
                active, R, Xa, Pd, rz = active[keep], R[:, keep].copy(), Xa[:, keep].copy(), Pd[:, keep].copy(), rz[keep]
            Z = M(R)
            rz_new = _coldot(R, Z)
            Pd *= rz_new / rz
            Pd += Z
            rz = rz_new
            now = time.perf_counter()
            if progress is not None and now - last >= every:
                last = now
                left = time_left(history, rtol, (now - t0) / it)
                tail = "" if left is None else f", about {left:.0f} s left"
                progress(f"solve: CG iteration {it}, {len(active)} of {k} load cases left, "
                         f"residual {history[-1]:.1e} (target {rtol:.0e}){tail}")
    res = B - A @ X
    rel_true = [float(v) for v in np.sqrt(_coldot(res, res)) / np.where(bnorm > 0, bnorm, 1.0)]
    return CGResult(X, iters, rel_true, history, time.perf_counter() - t0)

