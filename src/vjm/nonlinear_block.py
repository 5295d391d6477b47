"""The bordered Newton system of one point solved by its block-arrow structure (numba).

The unknowns of :mod:`vjm.nonlinear`'s Newton step are, per chain k, its springs' coordinates x_k
and the closure's multipliers lam_k, and the platform's pose u.  The matrix
``[[kd - Hs, -G^T], [G, 0]]`` couples a chain's (x_k, lam_k) only with themselves and with u:

    [B_1          E_1] [y_1]   [b_1]
    [     ...     ...] [...] = [...]
    [F_1  ...  A_uu  ] [y_u]   [b_u]

so each chain's block B_k (m_k + 6 square) is eliminated on its own, dense, with partial pivoting
among its rows, leaving its 6x6 contribution ``-F_k B_k^-1 E_k`` to the platform's Schur complement;
the 6x6 system gives y_u, and each chain's unknowns follow by back substitution.  The same row and
column equilibration as :func:`vjm.nonlinear._solve` (units mix mm, rad, N, N mm) is applied first.
The exact solution of the same system, at the cost of the blocks (about a third of the full
elimination's work on the 3-PUU, and no index bookkeeping).  A chain block whose pivot is not
clearly nonzero (below ``PIVOT_MIN`` of its equilibrated entries, which are at most 1) returns
``False``: the caller solves the whole system by the general elimination instead.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: smallest accepted pivot of an equilibrated chain block (its entries are at most 1)
PIVOT_MIN = 1e-8


@njit(cache=True, nogil=True, error_model="numpy")
def _local(tab, k, nx, kd, G, Hs, b, L, bl):  # pragma: no cover - compiled
    """Chain k's rows and columns (x_k, lam_k) and its coupling to u, in L (q + 6, q + 6) and bl (q + 6)."""
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
        bl[a] = b[gi]
    for c in range(6):
        for t in range(m):
            L[m + c, t] = G[r0 + c, c0 + t]
        for j in range(6):
            L[m + c, q + j] = G[r0 + c, nx + j]
            L[q + j, m + c] = -G[r0 + c, nx + j]
        bl[m + c] = b[nx + 6 + r0 + c]
    for j in range(6):
        bl[q + j] = 0.0


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
def _eliminate(L, bl, q):  # pragma: no cover - compiled
    """Gaussian elimination of the first q columns of L (q + 6 square) with partial pivoting among its
    first q rows; the last six rows and columns become the Schur complement.  False if a pivot is below
    PIVOT_MIN."""
    n = q + 6
    for c in range(q):
        p, best = c, abs(L[c, c])
        for r in range(c + 1, q):
            if abs(L[r, c]) > best:
                p, best = r, abs(L[r, c])
        if not best >= PIVOT_MIN:
            return False
        if p != c:
            for t in range(n):
                L[c, t], L[p, t] = L[p, t], L[c, t]
            bl[c], bl[p] = bl[p], bl[c]
        inv = 1.0 / L[c, c]
        for r in range(c + 1, n):
            f = L[r, c] * inv
            if f != 0.0:
                for t in range(c + 1, n):
                    L[r, t] -= f * L[c, t]
                bl[r] -= f * bl[c]
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def solve(tab, nx, kd, G, Hs, b, y):  # pragma: no cover - compiled
    """y (nz,) with the bordered Newton matrix times y = b (nz,), by the chains' blocks and the platform's
    Schur complement; False (y untouched) when a chain block needs pivots outside it."""
    mk, col = tab[6], tab[8]
    nch = mk.size
    qmax = 0
    for k in range(nch):
        qmax = max(qmax, mk[k] + 6)
    Ls = np.empty((nch, qmax + 6, qmax + 6))
    bls = np.empty((nch, qmax + 6))
    for k in range(nch):
        _local(tab, k, nx, kd, G, Hs, b, Ls[k], bls[k])
    Auu = np.empty((6, 6))
    bu = np.empty(6)
    for i in range(6):
        bu[i] = b[nx + i]
        for j in range(6):
            Auu[i, j] = -Hs[nx + i, nx + j]
    rs, cs = np.ones((nch, qmax + 6)), np.ones((nch, qmax + 6))
    _scales(tab, Ls, Auu, rs, cs)
    S = np.empty((6, 6))
    for i in range(6):
        bu[i] *= rs[0, mk[0] + 6 + i]
        for j in range(6):
            S[i, j] = Auu[i, j] * rs[0, mk[0] + 6 + i] * cs[0, mk[0] + 6 + j]
    for k in range(nch):
        q = mk[k] + 6
        L, bl = Ls[k], bls[k]
        for r in range(q + 6):
            bl[r] *= rs[k, r]
            for t in range(q + 6):
                L[r, t] *= rs[k, r] * cs[k, t]
        if not _eliminate(L, bl, q):
            return False
        for i in range(6):
            bu[i] += bl[q + i]
            for j in range(6):
                S[i, j] += L[q + i, q + j]
    yu = np.empty(6)
    Sb = np.empty((6, 7))
    Sb[:, :6] = S
    Sb[:, 6] = bu
    if not _dense_solve(Sb, yu):
        return False
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
        y[nx + j] = yu[j] * cs[0, mk[0] + 6 + j]
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _dense_solve(Ab, x):  # pragma: no cover - compiled
    """x with A x = b for Ab = [A | b] (n, n + 1), partial pivoting; False if a pivot is exactly zero."""
    n = x.size
    for c in range(n):
        p, best = c, abs(Ab[c, c])
        for r in range(c + 1, n):
            if abs(Ab[r, c]) > best:
                p, best = r, abs(Ab[r, c])
        if best == 0.0:
            return False
        if p != c:
            for t in range(n + 1):
                Ab[c, t], Ab[p, t] = Ab[p, t], Ab[c, t]
        for r in range(c + 1, n):
            f = Ab[r, c] / Ab[c, c]
            for t in range(c, n + 1):
                Ab[r, t] -= f * Ab[c, t]
    for r in range(n - 1, -1, -1):
        s = Ab[r, n]
        for t in range(r + 1, n):
            s -= Ab[r, t] * x[t]
        x[r] = s / Ab[r, r]
    return True
