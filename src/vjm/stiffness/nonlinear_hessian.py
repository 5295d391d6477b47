"""Compiled (numba) Hessian of ``lam . g``, the closure's second derivatives weighted by the chain wrenches,
for one chain at one point (:func:`vjm.stiffness.nonlinear._linearize` with ``hessian``): the helper of
:func:`vjm.stiffness.nonlinear_kernel.linearize_ws`, compiled into it."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy")
def _mm3(A, B, out):  # pragma: no cover - compiled
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True, nogil=True, error_model="numpy")
def hessian_chain(k, m, nJ, c0, nx, lam, Rp, R0k, D1, D2, F, X, dT, D, fixed, Hs):  # pragma: no cover
    """Chain k's part of the Hessian of ``lam . g`` (nonlinear._linearize, ``hessian``)."""
    lp0, lp1, lp2 = lam[6 * k], lam[6 * k + 1], lam[6 * k + 2]
    l0, l1, l2 = 0.5 * lam[6 * k + 3], 0.5 * lam[6 * k + 4], 0.5 * lam[6 * k + 5]
    Sl = np.zeros((3, 3))
    Sl[0, 1], Sl[0, 2], Sl[1, 2] = -l2, l1, -l0
    Sl[1, 0], Sl[2, 0], Sl[2, 1] = l2, -l1, l0
    Lam = np.zeros((3, 4))
    _mm3(Sl, Rp, Lam[:, :3])
    Lam[0, 3], Lam[1, 3], Lam[2, 3] = lp0, lp1, lp2
    # Q[f, h] = <Lam, X_f X_h T> = sum_ik X_f[i, k] (Lam dT_h^T)[i, k], for f <= h
    Y = np.zeros((nJ, 3, 4))
    for h in range(nJ):
        for i in range(3):
            for q in range(4):
                Y[h, i, q] = Lam[i, 0] * dT[h, q, 0] + Lam[i, 1] * dT[h, q, 1] + Lam[i, 2] * dT[h, q, 2] \
                    + Lam[i, 3] * dT[h, q, 3]
    Hf = np.empty((nJ, nJ))
    for f in range(nJ):
        for h in range(f, nJ):
            s = 0.0
            for i in range(3):
                for q in range(4):
                    s += X[f, i, q] * Y[h, i, q]
            Hf[f, h] = s
            Hf[h, f] = s
    Dm = np.zeros((m, nJ))
    for a in range(m):
        if not fixed[c0 + a]:
            for j in range(nJ):
                Dm[a, j] = D[k, a, j]
    _dhd(Dm, Hf, c0, Hs)
    tmp, SlD1 = np.empty((3, 3)), np.empty((3, 3, 3))
    for i in range(3):
        _mm3(Sl, D1[i], tmp)
        _mm3(tmp, R0k, SlD1[i])
    Hxp = np.zeros((nJ, 3))
    for f in range(nJ):
        for i in range(3):
            s = 0.0
            for j in range(3):
                for q in range(3):
                    s += SlD1[i, j, q] * dT[f, j, q]
            Hxp[f, i] = s
    for a in range(m):
        h0 = h1 = h2 = 0.0
        for f in range(nJ):
            d = Dm[a, f]
            if d != 0.0:
                h0 += d * Hxp[f, 0]
                h1 += d * Hxp[f, 1]
                h2 += d * Hxp[f, 2]
        Hs[c0 + a, nx + 3], Hs[c0 + a, nx + 4], Hs[c0 + a, nx + 5] = h0, h1, h2
        Hs[nx + 3, c0 + a], Hs[nx + 4, c0 + a], Hs[nx + 5, c0 + a] = h0, h1, h2
    _hessian_phi(Sl, D2, R0k, F, nx, Hs)


@njit(cache=True, nogil=True, error_model="numpy")
def _dhd(Dm, Hf, c0, Hs):  # pragma: no cover - compiled
    """Hs[c0:c0 + m, c0:c0 + m] = Dm Hf Dm^T, the zeros of the spring bases Dm skipped."""
    m, nJ = Dm.shape
    DH = np.zeros((m, nJ))
    for a in range(m):
        for j in range(nJ):
            d = Dm[a, j]
            if d != 0.0:
                for h in range(nJ):
                    DH[a, h] += d * Hf[j, h]
    for a in range(m):
        for b in range(a, m):
            s = 0.0
            for h in range(nJ):
                d = Dm[b, h]
                if d != 0.0:
                    s += DH[a, h] * d
            Hs[c0 + a, c0 + b] = s
            Hs[c0 + b, c0 + a] = s


@njit(cache=True, nogil=True, error_model="numpy")
def _hessian_phi(Sl, D2, R0k, F, nx, Hs):  # pragma: no cover - compiled
    """A chain's part of the platform rotation's block of the Hessian."""
    tmp, M = np.empty((3, 3)), np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            _mm3(Sl, D2[i, j], tmp)
            _mm3(tmp, R0k, M)
            s = 0.0
            for a in range(3):
                for b in range(3):
                    s += M[a, b] * F[a, b]
            Hs[nx + 3 + i, nx + 3 + j] += s
