"""Mesh convergence: observed order and Richardson error estimate from 3 mesh sizes.

For a result ``f(h) = f0 + c h^p`` computed on three sizes ``h1 > h2 > h3``
the observed order ``p`` solves

    (f1 - f2) / (f2 - f3) = (h1^p - h2^p) / (h2^p - h3^p)

(for a constant ratio ``r = h1/h2 = h2/h3`` this is ``p = ln((f1-f2)/(f2-f3)) / ln r``),
and the extrapolated value is ``f0 = f3 + (f3 - f2) / ((h2/h3)^p - 1)``.  The
Richardson estimate of the error of the finest result is ``|f0 - f3| / |f0|``
(Roache, *Verification and Validation in Computational Science and
Engineering*, 1998).

Non-monotone data (the differences change sign) have no observed order: the
entry is flagged and its error is estimated conservatively as the last change
``|f3 - f2| / |f3|``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..runtime.errors import LinkFeaError

P_MIN, P_MAX = 0.1, 12.0


@dataclass(frozen=True)
class Richardson:
    """Richardson analysis of a result on three meshes.

    Attributes
    ----------
    h : ndarray (3,)
        Mesh sizes, coarse to fine.
    order : ndarray
        Observed order per entry (NaN where the data are not monotone or an entry does not change).
    extrapolated : ndarray
        Extrapolated value per entry (the finest value where no order exists).
    error : ndarray
        Relative error estimate of the finest result per entry.
    monotone : ndarray of bool
        Where the three values converge monotonically.
    order_diagonal : float
        Median observed order over the principal diagonal (or over all entries of a vector/scalar).
    error_diagonal : float
        Largest relative error estimate over the principal diagonal.
    note : str
        Empty, or what was unusual (non-monotone entries, order outside [0.1, 12]).
    """

    h: np.ndarray
    order: np.ndarray
    extrapolated: np.ndarray
    error: np.ndarray
    monotone: np.ndarray
    order_diagonal: float
    error_diagonal: float
    note: str = ""


def _ratio_function(p, h1, h2, h3):
    return (h1**p - h2**p) / (h2**p - h3**p)


def _solve_order(rho, h1, h2, h3):
    """Order p with _ratio_function(p) = rho, by bisection (the function increases with p)."""
    lo, hi = P_MIN, P_MAX
    flo, fhi = _ratio_function(lo, h1, h2, h3), _ratio_function(hi, h1, h2, h3)
    if rho <= flo:
        return lo, True
    if rho >= fhi:
        return hi, True
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if _ratio_function(mid, h1, h2, h3) < rho:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12:
            break
    return 0.5 * (lo + hi), False


def richardson(h_values, results) -> Richardson:
    """Observed order, extrapolated value and error estimate from 3 mesh sizes.

    Parameters
    ----------
    h_values : sequence of 3 floats
        Characteristic mesh sizes (any order; they are sorted coarse to fine).
    results : sequence of 3 arrays (same shape) or floats
        The result on each mesh, e.g. 6x6 compliance matrices.

    Returns
    -------
    Richardson
    """
    h = np.asarray(h_values, dtype=float)
    if h.shape != (3,) or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise LinkFeaError(f"richardson needs 3 positive mesh sizes, got {h_values}")
    if len(np.unique(h)) != 3:
        raise LinkFeaError(f"richardson needs 3 distinct mesh sizes, got {h_values}")
    F = np.asarray([np.asarray(r, dtype=float) for r in results])
    if F.shape[0] != 3:
        raise LinkFeaError(f"richardson needs 3 results, got {F.shape[0]}")
    if not np.all(np.isfinite(F)):
        raise LinkFeaError("richardson: results must be finite")
    order_idx = np.argsort(-h)
    h = h[order_idx]
    F = F[order_idx]
    h1, h2, h3 = h
    shape = F.shape[1:]
    f1, f2, f3 = F.reshape(3, -1)
    d12, d23 = f1 - f2, f2 - f3
    tiny = np.finfo(float).tiny
    scale = np.maximum(np.abs(F).reshape(3, -1).max(axis=0), tiny)
    still = (np.abs(d12) <= 1e-13 * scale) & (np.abs(d23) <= 1e-13 * scale)
    converging = d12 * d23 > 0
    monotone = converging | still
    p = np.full(f3.shape, np.nan)
    f0 = f3.copy()
    clipped = False
    for k in np.flatnonzero(converging):  # a handful of entries: no hot path
        p[k], clip = _solve_order(d12[k] / d23[k], h1, h2, h3)
        clipped |= clip
        f0[k] = f3[k] + (f3[k] - f2[k]) / ((h2 / h3) ** p[k] - 1.0)
    err = np.abs(f0 - f3) / np.maximum(np.abs(f0), tiny)
    bad = ~monotone
    err = np.where(bad, np.abs(d23) / np.maximum(np.abs(f3), tiny), err)
    p, f0, err, monotone, bad = (x.reshape(shape) for x in (p, f0, err, monotone, bad))

    if len(shape) == 2 and shape[0] == shape[1]:
        diag_p, diag_err = np.diagonal(p), np.diagonal(err)
    else:
        diag_p, diag_err = np.ravel(p), np.ravel(err)
    finite = diag_p[np.isfinite(diag_p)]
    notes = []
    if bad.any():
        notes.append(f"{int(np.sum(bad))} entries do not converge monotonically (error taken as the last change)")
    if clipped:
        notes.append(f"observed order outside [{P_MIN}, {P_MAX}] for some entries (clipped)")
    return Richardson(
        h=h, order=p, extrapolated=f0, error=err, monotone=np.asarray(monotone),
        order_diagonal=float(np.median(finite)) if finite.size else float("nan"),
        error_diagonal=float(np.max(diag_err)),
        note="; ".join(notes),
    )
