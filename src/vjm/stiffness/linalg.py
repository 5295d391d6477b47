"""Small dense linear algebra vectorised over a leading batch axis.

LAPACK's batched routines loop over the stack in C one small matrix at a
time (about 7 us per 6x4 SVD here); for 6x6 matrices it is much faster to
loop over the 6 indices in Python and vectorise over the poses.  Only
poses that come close to rank deficiency are sent to LAPACK's SVD.
"""
from __future__ import annotations

import numpy as np

#: relative singular-value threshold below which a direction counts as lost
RANK_RTOL = 1e-9
#: pivots below this ratio are re-examined by a full SVD
GRAY_ZONE = 1e-5
#: below this lower bound of sigma_min / sigma_max (or relative pivot) the fast
#: closed forms hand a pose over to the rank-revealing path
FAST_RTOL = 1e-7


def cholesky(A: np.ndarray) -> np.ndarray:
    """Lower Cholesky factors of SPD matrices (n, m, m); pivots are clamped > 0 (never raises)."""
    n, m, _ = A.shape
    L = np.zeros_like(A)
    floor = 1e-300 + 1e-15 * np.max(np.abs(np.diagonal(A, axis1=1, axis2=2)), axis=1)
    for j in range(m):
        d = A[:, j, j] - np.einsum("nk,nk->n", L[:, j, :j], L[:, j, :j])
        d = np.sqrt(np.maximum(d, floor))
        L[:, j, j] = d
        if j + 1 < m:
            L[:, j + 1:, j] = (A[:, j + 1:, j] - np.einsum("nik,nk->ni", L[:, j + 1:, :j], L[:, j, :j])) / d[:, None]
    return L


def lower_inverse(L: np.ndarray) -> np.ndarray:
    """Inverse of lower-triangular matrices (n, m, m) by forward substitution."""
    n, m, _ = L.shape
    X = np.zeros_like(L)
    for i in range(m):
        rhs = -np.einsum("nk,nkj->nj", L[:, i, :i], X[:, :i, :])
        rhs[:, i] += 1.0
        X[:, i, :] = rhs / L[:, i, i][:, None]
    return X


def range_basis(A: np.ndarray, rtol: float = RANK_RTOL) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal basis of the column space of ``A`` (n, m, k), rank-revealing.

    Pivoted modified Gram-Schmidt (a rank-revealing QR) vectorised over
    poses; where a pivot falls below ``GRAY_ZONE`` times the largest column
    norm the pose is redone with a full SVD, and the rank is the number of
    singular values above ``rtol * s_max`` (the seed's SVD treatment of
    singular postures, section 2.4).

    Returns
    -------
    Q : (n, m, k) with the first ``rank`` columns orthonormal, the rest zero
    rank : (n,) int
    """
    n, m, k = A.shape
    R = np.array(A, dtype=float, copy=True)
    scale = np.max(np.linalg.norm(R, axis=1), axis=1) if k else np.zeros(n)
    scale = np.where(scale > 0, scale, 1.0)
    Q = np.zeros((n, m, k))
    rank = np.zeros(n, dtype=int)
    minpiv = np.full(n, np.inf)
    ar = np.arange(n)
    for j in range(k):
        nrm = np.linalg.norm(R, axis=1)
        piv = np.argmax(nrm, axis=1)
        cn = nrm[ar, piv]
        col = R[ar, :, piv]
        keep = cn > rtol * scale
        q = np.where(keep[:, None], col / np.where(keep, cn, 1.0)[:, None], 0.0)
        Q[:, :, j] = q
        R -= q[:, :, None] * np.einsum("ni,nij->nj", q, R)[:, None, :]
        rank += keep
        minpiv = np.minimum(minpiv, cn / scale)
    # one re-orthogonalisation pass against round-off ("twice is enough")
    for j in range(1, k):
        qj = Q[:, :, j]
        qj = qj - np.einsum("nij,nj->ni", Q[:, :, :j], np.einsum("nij,ni->nj", Q[:, :, :j], qj))
        nr = np.linalg.norm(qj, axis=1)
        Q[:, :, j] = np.where(nr[:, None] > 0.5, qj / np.where(nr > 0, nr, 1.0)[:, None], 0.0)
    gray = np.nonzero(minpiv < GRAY_ZONE)[0]
    if gray.size:
        U, s, _ = np.linalg.svd(A[gray], full_matrices=False)
        r = np.sum(s > rtol * np.maximum(s[:, :1], 1e-300), axis=1)
        Q[gray] = U * (np.arange(k)[None, :] < r[:, None])[:, None, :]
        rank[gray] = r
    return Q, rank


def psd_rank_inverse(K: np.ndarray, rtol: float = 1e-10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rank and inverse of symmetric positive semi-definite matrices (n, m, m).

    The rank is that of the Jacobi-scaled matrix ``D K D`` (``D = diag(K)^-1/2``),
    which makes it independent of the mixed units (N/mm, N mm/rad).

    Returns
    -------
    C : (n, m, m) inverse where ``rank == m``, Moore-Penrose pseudo-inverse elsewhere
    rank : (n,) int
    invertible : (n,) bool
    """
    n, m, _ = K.shape
    d = np.sqrt(np.clip(np.diagonal(K, axis1=1, axis2=2), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    Ks = K / d[:, :, None] / d[:, None, :]
    Ks = 0.5 * (Ks + np.swapaxes(Ks, 1, 2))
    # LDL^T without pivoting; a vanishing pivot marks a lost direction
    L = np.zeros_like(Ks)
    D = np.zeros((n, m))
    for j in range(m):
        dj = Ks[:, j, j] - np.einsum("nk,nk,nk->n", L[:, j, :j], L[:, j, :j], D[:, :j])
        D[:, j] = dj
        L[:, j, j] = 1.0
        ok = dj > rtol
        if j + 1 < m:
            num = Ks[:, j + 1:, j] - np.einsum("nik,nk,nk->ni", L[:, j + 1:, :j], L[:, j, :j], D[:, :j])
            L[:, j + 1:, j] = np.where(ok[:, None], num / np.where(ok, dj, 1.0)[:, None], 0.0)
    rank = np.sum(D > rtol, axis=1)
    invertible = rank == m
    C = np.zeros_like(K)
    good = np.nonzero(invertible)[0]
    if good.size:
        Li = lower_inverse(L[good])  # unit lower: inverse is unit lower too
        Cs = np.einsum("nki,nk,nkj->nij", Li, 1.0 / D[good], Li)
        C[good] = Cs / d[good][:, :, None] / d[good][:, None, :]
    bad = np.nonzero(~invertible)[0]
    if bad.size:
        Cs = np.linalg.pinv(Ks[bad], rcond=rtol, hermitian=True)
        C[bad] = Cs / d[bad][:, :, None] / d[bad][:, None, :]
        eig = np.linalg.eigvalsh(Ks[bad])
        rank[bad] = np.sum(eig > rtol * np.maximum(eig[:, -1:], 1e-300), axis=1)
    return C, rank, invertible


def sym3_max_eig(A: np.ndarray) -> np.ndarray:
    """Largest eigenvalue of symmetric 3x3 matrices (n, 3, 3), closed form (trigonometric)."""
    a = 0.5 * (A + np.swapaxes(A, 1, 2))
    q = np.trace(a, axis1=1, axis2=2) / 3.0
    p1 = a[:, 0, 1] ** 2 + a[:, 0, 2] ** 2 + a[:, 1, 2] ** 2
    p2 = (a[:, 0, 0] - q) ** 2 + (a[:, 1, 1] - q) ** 2 + (a[:, 2, 2] - q) ** 2 + 2.0 * p1
    p = np.sqrt(p2 / 6.0)
    psafe = np.where(p > 0, p, 1.0)
    B = (a - q[:, None, None] * np.eye(3)) / psafe[:, None, None]
    r = np.clip(np.linalg.det(B) / 2.0, -1.0, 1.0)
    phi = np.arccos(r) / 3.0
    return np.where(p > 0, q + 2.0 * p * np.cos(phi), q)


# -- pose axis last ("structure of arrays"): (m, m, n), contiguous over poses ----

def upper_inverse(R: np.ndarray) -> np.ndarray:
    """Inverse of upper-triangular matrices stored as (k, k, n), by back substitution."""
    k = R.shape[0]
    X = np.zeros_like(R)
    for i in range(k - 1, -1, -1):
        X[i, i] = 1.0 / R[i, i]
        if i + 1 < k:
            X[i, i + 1:] = -np.einsum("ln,ljn->jn", R[i, i + 1:], X[i + 1:, i + 1:]) * X[i, i]
    return X


def spd_inverse(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of symmetric positive-definite matrices (m, m, n) by Cholesky, and the
    smallest relative pivot ``min_j d_j / M_jj`` (n,) (small or negative: not safely SPD;
    the inverse is then garbage-free but meaningless and must be replaced by the caller)."""
    m, _, n = M.shape
    if m == 0:
        return np.zeros((0, 0, n)), np.ones(n)
    if m == 2:  # closed form, same pivots as below
        a, b, c = M[0, 0], M[1, 0], M[1, 1]
        a_ok = a > 0
        d1 = c - b * (b / np.where(a_ok, a, 1.0))
        piv = np.where(a_ok & (c > 0), np.minimum(1.0, d1 / np.where(c > 0, c, 1.0)), -1.0)
        det = np.where(piv > 1e-300, a * d1, 1.0)
        out = np.empty_like(M)
        out[0, 0] = c / det
        out[1, 1] = a / det
        out[0, 1] = out[1, 0] = -b / det
        return out, piv
    L = np.zeros_like(M)
    piv = np.full(n, np.inf)
    for j in range(m):
        d = M[j, j] - np.einsum("kn,kn->n", L[j, :j], L[j, :j])
        rel = d / np.where(M[j, j] > 0, M[j, j], 1.0)
        piv = np.minimum(piv, np.where(M[j, j] > 0, rel, -1.0))
        d = np.sqrt(np.where(rel > 1e-300, d, 1.0))
        L[j, j] = d
        if j + 1 < m:
            L[j + 1:, j] = (M[j + 1:, j] - np.einsum("ikn,kn->in", L[j + 1:, :j], L[j, :j])) / d
    # L^-1 by forward substitution, then M^-1 = L^-T L^-1
    X = np.zeros_like(M)
    for i in range(m):
        X[i, i] = 1.0 / L[i, i]
        if i:
            X[i, :i] = -np.einsum("kn,kjn->jn", L[i, :i], X[:i, :i]) * X[i, i]
    return np.einsum("kin,kjn->ijn", X, X), piv


def psd_rank_inverse_soa(K: np.ndarray, rtol: float = 1e-10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`psd_rank_inverse` with the pose axis last: K (m, m, n) -> C (m, m, n), rank, invertible.

    Same Jacobi scaling and unpivoted LDL^T (so the same rank decision); the
    inverse ``D^-1/2 L^-T D^-1 L^-1 D^-1/2`` is formed for every pose at once
    and the few non-invertible poses are redone by :func:`psd_rank_inverse`
    (pseudo-inverse, eigenvalue rank).
    """
    m, _, n = K.shape
    d = np.sqrt(np.clip(np.diagonal(K).T, 0.0, None))  # (m, n)
    d = np.where(d > 0, d, 1.0)
    di = 1.0 / d
    L = np.zeros_like(K)
    D = np.zeros((m, n))
    for j in range(m):
        # column j of the Jacobi-scaled, symmetrised K (only the lower triangle is read)
        LD = L[j, :j] * D[:j]
        dj = K[j, j] * di[j] * di[j] - np.einsum("kn,kn->n", L[j, :j], LD)
        D[j] = dj
        L[j, j] = 1.0
        if j + 1 < m:
            ok = dj > rtol
            col = (K[j + 1:, j] + K[j, j + 1:]) * (0.5 * di[j] * di[j + 1:])
            num = col - np.einsum("ikn,kn->in", L[j + 1:, :j], LD)
            L[j + 1:, j] = num * np.where(ok, 1.0 / np.where(ok, dj, 1.0), 0.0)
    good = D > rtol
    rank = np.sum(good, axis=0)
    invertible = rank == m
    # unit lower inverse by forward substitution
    X = np.zeros_like(L)
    for i in range(m):
        X[i, i] = 1.0
        if i:
            X[i, :i] = -np.einsum("kn,kjn->jn", L[i, :i], X[:i, :i])
    Y = X / np.where(good, D, 1.0)[:, None]
    # C = X^T D^-1 X; X is unit lower, so C[:, j] only needs rows k >= j
    C = np.empty_like(X)
    for j in range(m):
        C[:j + 1, j] = np.einsum("kin,kn->in", Y[j:, :j + 1], X[j:, j])
        C[j, :j] = C[:j, j]
    C *= di[:, None] * di[None, :]
    bad = np.nonzero(~invertible)[0]
    if bad.size:
        Cb, rank[bad], _ = psd_rank_inverse(np.ascontiguousarray(K[:, :, bad].transpose(2, 0, 1)), rtol)
        C[:, :, bad] = Cb.transpose(1, 2, 0)
    return C, rank, invertible


def sym3_max_eig_soa(A: np.ndarray) -> np.ndarray:
    """:func:`sym3_max_eig` with the pose axis last: A (3, 3, n) -> (n,)."""
    a = 0.5 * (A + A.transpose(1, 0, 2))
    q = (a[0, 0] + a[1, 1] + a[2, 2]) / 3.0
    p1 = a[0, 1] ** 2 + a[0, 2] ** 2 + a[1, 2] ** 2
    b00, b11, b22 = a[0, 0] - q, a[1, 1] - q, a[2, 2] - q
    p2 = b00 ** 2 + b11 ** 2 + b22 ** 2 + 2.0 * p1
    p = np.sqrt(p2 / 6.0)
    psafe = np.where(p > 0, p, 1.0)
    # det(B) of B = (a - q I) / p, symmetric
    det = (b00 * (b11 * b22 - a[1, 2] ** 2) - a[0, 1] * (a[0, 1] * b22 - a[1, 2] * a[0, 2])
           + a[0, 2] * (a[0, 1] * a[1, 2] - b11 * a[0, 2])) / psafe ** 3
    r = np.clip(det / 2.0, -1.0, 1.0)
    phi = np.arccos(r) / 3.0
    return np.where(p > 0, q + 2.0 * p * np.cos(phi), q)
