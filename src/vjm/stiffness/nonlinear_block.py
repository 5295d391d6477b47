"""The bordered Newton system of one point solved by its block-arrow structure (numba).

The unknowns of :mod:`vjm.stiffness.nonlinear`'s Newton step are, per chain k, its springs' coordinates x_k
and the closure's multipliers lam_k, and the platform's pose u.  The matrix
``[[kd - Hs, -G^T], [G, 0]]`` couples a chain's (x_k, lam_k) only with themselves and with u:

    [B_1          E_1] [y_1]   [b_1]
    [     ...     ...] [...] = [...]
    [F_1  ...  A_uu  ] [y_u]   [b_u]

so each chain's block B_k (m_k + 6 square) is eliminated on its own, dense, with partial pivoting
among its rows, leaving its 6x6 contribution ``-F_k B_k^-1 E_k`` to the platform's Schur complement;
the 6x6 system gives y_u, and each chain's unknowns follow by back substitution.  The same row and
column equilibration as :func:`vjm.stiffness.nonlinear._solve` (units mix mm, rad, N, N mm) is applied first.
The exact solution of the same system, at the cost of the blocks (about a third of the full
elimination's work on the 3-PUU, and no index bookkeeping).  A chain block whose pivot is not
clearly nonzero (below ``PIVOT_MIN`` of its equilibrated entries, which are at most 1) returns
``False``: the caller solves the whole system by the general elimination instead (:func:`full_solve`:
threshold pivoting in the chains' order, zeros skipped).  :func:`factor` keeps the factorization, so
that :func:`apply` can solve later right-hand sides with it (the chord steps of
:mod:`vjm.stiffness.nonlinear_kernel`).
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: smallest accepted pivot of an equilibrated chain block (its entries are at most 1)
PIVOT_MIN = 1e-8


@njit(cache=True, nogil=True, error_model="numpy")
def _local(tab, k, nx, kd, G, Hs, L):  # pragma: no cover - compiled
    """Chain k's rows and columns (x_k, lam_k) and its coupling to u, in L (q + 6, q + 6)."""
    mk, col = tab[6], tab[8]
    m, c0, r0 = mk[k], col[k], 6 * k
    q = m + 6
    L[:q + 6, :q + 6] = 0.0
    for a in range(m):
        gi = c0 + a
        for t in range(m):
            L[a, t] = -Hs[gi, c0 + t]
        L[a, a] += kd[gi]
        for c in range(6):
            L[a, m + c] = -G[r0 + c, gi]
        for j in range(6):
            L[a, q + j] = -Hs[gi, nx + j]
            L[q + j, a] = -Hs[nx + j, gi]
    for c in range(6):
        for t in range(m):
            L[m + c, t] = G[r0 + c, c0 + t]
        for j in range(6):
            L[m + c, q + j] = G[r0 + c, nx + j]
            L[q + j, m + c] = -G[r0 + c, nx + j]


@njit(cache=True, nogil=True, error_model="numpy")
def _scales(tab, Ls, Auu, rs, cs):  # pragma: no cover - compiled
    """Row scales rs (nch, q + 6) and column scales cs (nch, q + 6) of every chain's local matrix, as
    nonlinear._solve equilibrates the whole matrix: the u rows' and columns' maxima over all chains."""
    mk = tab[6]
    nch = mk.size
    ru = np.zeros(6)
    for j in range(6):
        for t in range(6):
            ru[j] = max(ru[j], abs(Auu[j, t]))
    for k in range(nch):
        q = mk[k] + 6
        for r in range(q):
            big = 0.0
            for t in range(q + 6):
                big = max(big, abs(Ls[k, r, t]))
            rs[k, r] = 1.0 / max(big, 1e-300)
        for j in range(6):
            for t in range(q):
                ru[j] = max(ru[j], abs(Ls[k, q + j, t]))
    for j in range(6):
        ru[j] = 1.0 / max(ru[j], 1e-300)
    cu = np.zeros(6)
    for j in range(6):
        for t in range(6):
            cu[t] = max(cu[t], abs(Auu[j, t]) * ru[j])
    for k in range(nch):
        q = mk[k] + 6
        for j in range(6):
            rs[k, q + j] = ru[j]
        for t in range(q):
            big = 0.0
            for r in range(q + 6):
                big = max(big, abs(Ls[k, r, t]) * rs[k, r])
            cs[k, t] = 1.0 / max(big, 1e-300)
        for r in range(q):
            for j in range(6):
                cu[j] = max(cu[j], abs(Ls[k, r, q + j]) * rs[k, r])
    for k in range(nch):
        q = mk[k] + 6
        for j in range(6):
            cs[k, q + j] = 1.0 / max(cu[j], 1e-300)


@njit(cache=True, nogil=True, error_model="numpy")
def _eliminate(L, q, piv):  # pragma: no cover - compiled
    """LU of the first q columns of L (q + 6 square), partial pivoting among its first q rows (row swaps in
    piv, multipliers below the diagonal); the last six rows and columns become the Schur complement.
    False if a pivot is below PIVOT_MIN."""
    n = q + 6
    for c in range(q):
        p, best = c, abs(L[c, c])
        for r in range(c + 1, q):
            if abs(L[r, c]) > best:
                p, best = r, abs(L[r, c])
        if not best >= PIVOT_MIN:
            return False
        piv[c] = p
        if p != c:
            for t in range(n):
                L[c, t], L[p, t] = L[p, t], L[c, t]
        inv = 1.0 / L[c, c]
        for r in range(c + 1, n):
            f = L[r, c] * inv
            L[r, c] = f
            if f != 0.0:
                for t in range(c + 1, n):
                    L[r, t] -= f * L[c, t]
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def workspace(tab):  # pragma: no cover - compiled
    """The arrays a factorization (:func:`factor`) is kept in."""
    mk = tab[6]
    nch, qmax = mk.size, int(mk.max()) + 6
    return (np.empty((nch, qmax + 6, qmax + 6)), np.empty((nch, qmax + 6)), np.empty((nch, qmax + 6)),
            np.empty((nch, qmax), np.int64), np.empty((6, 6)), np.empty(6, np.int64))


@njit(cache=True, nogil=True, error_model="numpy")
def factor(tab, nx, kd, G, Hs, ws):  # pragma: no cover - compiled
    """Factorizes the bordered Newton matrix by the chains' blocks and the platform's Schur complement
    into ws (see :func:`workspace`); False when a chain block needs pivots outside it."""
    Ls, rs, cs, piv, S, spiv = ws
    mk = tab[6]
    nch = mk.size
    Auu = np.empty((6, 6))
    for k in range(nch):
        _local(tab, k, nx, kd, G, Hs, Ls[k])
    for i in range(6):
        for j in range(6):
            Auu[i, j] = -Hs[nx + i, nx + j]
    _scales(tab, Ls, Auu, rs, cs)
    q0 = mk[0] + 6
    for i in range(6):
        for j in range(6):
            S[i, j] = Auu[i, j] * rs[0, q0 + i] * cs[0, q0 + j]
    for k in range(nch):
        q = mk[k] + 6
        L = Ls[k]
        for r in range(q + 6):
            for t in range(q + 6):
                L[r, t] *= rs[k, r] * cs[k, t]
        if not _eliminate(L, q, piv[k]):
            return False
        for i in range(6):
            for j in range(6):
                S[i, j] += L[q + i, q + j]
    return _lu6(S, spiv)


@njit(cache=True, nogil=True, error_model="numpy")
def apply(tab, nx, ws, b, y):  # pragma: no cover - compiled
    """y (nz,) with the factorized matrix (:func:`factor`) times y = b (nz,)."""
    Ls, rs, cs, piv, S, spiv = ws
    mk, col = tab[6], tab[8]
    nch = mk.size
    q0 = mk[0] + 6
    bu = np.empty(6)
    for i in range(6):
        bu[i] = b[nx + i] * rs[0, q0 + i]
    bls = np.empty((nch, Ls.shape[1]))
    for k in range(nch):
        m, q, c0, L, bl = mk[k], mk[k] + 6, col[k], Ls[k], bls[k]
        for a in range(m):
            bl[a] = b[c0 + a] * rs[k, a]
        for c in range(6):
            bl[m + c] = b[nx + 6 + 6 * k + c] * rs[k, m + c]
        for j in range(6):
            bl[q + j] = 0.0
        for c in range(q):  # the row swaps (whole rows were swapped in the factorization), then L
            p = piv[k, c]
            if p != c:
                bl[c], bl[p] = bl[p], bl[c]
        for c in range(q):
            for r in range(c + 1, q + 6):
                f = L[r, c]
                if f != 0.0:
                    bl[r] -= f * bl[c]
        for i in range(6):
            bu[i] += bl[q + i]
    yu = np.empty(6)
    _lu6_solve(S, spiv, bu, yu)
    for k in range(nch):
        m, q, c0, L, bl = mk[k], mk[k] + 6, col[k], Ls[k], bls[k]
        yl = np.empty(q)
        for r in range(q - 1, -1, -1):
            s = bl[r]
            for t in range(r + 1, q):
                s -= L[r, t] * yl[t]
            for j in range(6):
                s -= L[r, q + j] * yu[j]
            yl[r] = s / L[r, r]
        for a in range(m):
            y[c0 + a] = yl[a] * cs[k, a]
        for c in range(6):
            y[nx + 6 + 6 * k + c] = yl[m + c] * cs[k, m + c]
    for j in range(6):
        y[nx + j] = yu[j] * cs[0, q0 + j]


@njit(cache=True, nogil=True, error_model="numpy")
def _lu6(S, spiv):  # pragma: no cover - compiled
    """LU of the 6x6 S in place, partial pivoting (swaps in spiv); False if a pivot is exactly zero."""
    for c in range(6):
        p, best = c, abs(S[c, c])
        for r in range(c + 1, 6):
            if abs(S[r, c]) > best:
                p, best = r, abs(S[r, c])
        if best == 0.0:
            return False
        spiv[c] = p
        if p != c:
            for t in range(6):
                S[c, t], S[p, t] = S[p, t], S[c, t]
        for r in range(c + 1, 6):
            f = S[r, c] / S[c, c]
            S[r, c] = f
            for t in range(c + 1, 6):
                S[r, t] -= f * S[c, t]
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _lu6_solve(S, spiv, bu, yu):  # pragma: no cover - compiled
    """yu with S yu = bu from the LU of :func:`_lu6` (bu is overwritten)."""
    for c in range(6):
        p = spiv[c]
        if p != c:
            bu[c], bu[p] = bu[p], bu[c]
    for c in range(6):
        for r in range(c + 1, 6):
            bu[r] -= S[r, c] * bu[c]
    for r in range(5, -1, -1):
        s = bu[r]
        for t in range(r + 1, 6):
            s -= S[r, t] * yu[t]
        yu[r] = s / S[r, r]


@njit(cache=True, nogil=True, error_model="numpy")
def order(tab, nx, nz):  # pragma: no cover - compiled
    """Unknowns chain by chain (springs, then the closure's multipliers), the platform pose last: the
    bordered matrix is then block-arrow shaped and its elimination stays within a chain's block."""
    perm = np.empty(nz, np.int64)
    q = 0
    mk, col = tab[6], tab[8]
    for k in range(mk.size):
        for a in range(mk[k]):
            perm[q] = col[k] + a
            q += 1
        for a in range(6):
            perm[q] = nx + 6 + 6 * k + a
            q += 1
    for a in range(6):
        perm[q + a] = nx + a
    return perm


@njit(cache=True, nogil=True, error_model="numpy")
def full_solve(tab, nx, kd, G, Hs, b):  # pragma: no cover - compiled
    """The bordered system [[kd - Hs, -G^T], [G, 0]] y = b by the equilibrated general elimination."""
    nz = b.size
    nc = nz - nx - 6
    A = np.zeros((nz, nz))
    for i in range(nx + 6):
        for j in range(nx + 6):
            A[i, j] = -Hs[i, j]
        for c in range(nc):
            A[i, nx + 6 + c] = -G[c, i]
            A[nx + 6 + c, i] = G[c, i]
    for i in range(nx):
        A[i, i] += kd[i]
    perm = order(tab, nx, nz)
    Ap = np.empty((nz, nz))
    bp = np.empty(nz)
    cs = np.zeros(nz)
    for i in range(nz):
        pi = perm[i]
        big = 0.0
        for j in range(nz):
            big = max(big, abs(A[pi, j]))
        rs = 1.0 / max(big, 1e-300)
        bp[i] = b[pi] * rs
        for j in range(nz):
            v = A[pi, perm[j]] * rs
            Ap[i, j] = v
            cs[j] = max(cs[j], abs(v))
    for j in range(nz):
        cs[j] = 1.0 / max(cs[j], 1e-300)
    for i in range(nz):
        for j in range(nz):
            Ap[i, j] *= cs[j]
    yp = lu_solve(Ap, bp)
    y = np.empty(nz)
    for i in range(nz):
        y[perm[i]] = yp[i] * cs[i]
    return y


@njit(cache=True, nogil=True, error_model="numpy")
def lu_solve(A, b, tau=0.1):  # pragma: no cover - compiled
    """x with A x = b by Gaussian elimination (A and b are overwritten); NaN if A is singular.

    Threshold partial pivoting: the first row (in the given order) whose entry is at least ``tau``
    of the column's largest; entries that are zero are skipped, so a block-structured matrix is
    eliminated at the cost of its blocks."""
    n = b.size
    nzc = np.empty(n, np.int64)
    for c in range(n):
        best = 0.0
        for r in range(c, n):
            best = max(best, abs(A[r, c]))
        if best == 0.0:
            return np.full(n, np.nan)
        p = c
        while abs(A[p, c]) < tau * best:
            p += 1
        if p != c:
            for q in range(n):
                A[c, q], A[p, q] = A[p, q], A[c, q]
            b[c], b[p] = b[p], b[c]
        cnt = 0
        for q in range(c + 1, n):
            if A[c, q] != 0.0:
                nzc[cnt] = q
                cnt += 1
        inv = 1.0 / A[c, c]
        for r in range(c + 1, n):
            f = A[r, c] * inv
            if f != 0.0:
                for t in range(cnt):
                    q = nzc[t]
                    A[r, q] -= f * A[c, q]
                b[r] -= f * b[c]
    x = np.empty(n)
    for r in range(n - 1, -1, -1):
        s = b[r]
        for q in range(r + 1, n):
            s -= A[r, q] * x[q]
        x[r] = s / A[r, r]
    return x
