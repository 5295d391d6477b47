"""Compiled (numba) stiffness of a parallel machine, pose by pose over a block: the map's fast path.

The same arithmetic as the batched numpy path (:func:`vjm.stiffness.chain_stiffness_frames` and
:func:`vjm.stiffness.assemble_soa`), one pose at a time in compiled loops, so that the small
6x6 work stays in registers and cache instead of some hundred array operations per block:

One call of :func:`machine_block` per block of poses does every chain and the assembly, the
machine's K kept in the lanes between them (no pass through an (n, 6, 6) array):

* per chain: the end frame and Jacobian in one pass over the factors
  (:func:`vjm.kinematics.ik_kernel._end_and_jacobian`, the shared helper), the wrench basis ``N`` of the
  passive joints by Householder QR and its conditioning bound, ``M = sum_s Z_s C_s Z_s^T`` with
  ``Z_s = N^T J_s``, its Cholesky inverse and relative pivot, ``K_i = N M^-1 N^T`` added to the
  machine's K in the chains' order (the numpy path's sum, to the bit);
* per machine: the Jacobi-scaled unpivoted LDL^T of K, its rank decision (every pivot above
  ``rtol``), ``C = K^-1`` and the closed-form largest eigenvalues of its blocks (k_tran, k_rot).

A pose where a chain's bound or pivot falls below ``FAST_RTOL``, or where K is not invertible,
is flagged; the caller redoes it with the numpy path (rank-revealing bordered solve, SVD,
pseudo-inverse), so both paths make the same rank and invertibility decisions.  ``cache=True``
keeps the machine code on disk: the first process after an install compiles it (about 20 s of
CPU, docs/benchmarks.md), later ones load it.  The helpers called in the per-chain loop are
inlined (``inline="always"``: some 1.25x on the kernel against calls with their array arguments);
the factorisations called once per chain or block stay calls, which keeps the compile shorter; :mod:`vjm.stiffness` imports this module only for blocks of
``KERNEL_FROM`` poses or more.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..kinematics import ik_kernel

#: the chain walk of the compiled IK, inlined here (its own dispatcher stays a call in the IK)
_end_and_jacobian = njit(error_model="numpy", inline="always")(ik_kernel._end_and_jacobian.py_func)

#: poses computed side by side: every per-pose quantity is a vector of LANES values, so the short
#: dependent sums of 6x6 algebra run as independent chains over poses instead of one latency
#: chain.  (Not SIMD: numba's LLVM leaves its SLP vectoriser off, and a lane count known only at
#: run time, which the loop vectoriser takes, was slower; 4 or 16 lanes: within the noise.)
LANES = 8

@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _householder(A, k, R, beta, nx, w):  # pragma: no cover - compiled
    """Householder QR of the rows A[:k] (6 long, LANES): the vectors in place of A, R (k, k)."""
    for j in range(k):
        nx[:] = 0.0
        for i in range(j, 6):
            for q in range(LANES):
                nx[q] += A[j, i, q] * A[j, i, q]
        for q in range(LANES):
            x = math.sqrt(nx[q])
            v0 = A[j, j, q]
            alpha = -x if v0 >= 0 else x
            # beta = 2 / |v|^2; a zero column gives v = 0, so a huge beta is harmless
            beta[j, q] = 1.0 / max(x * (x + abs(v0)), 1e-300)
            A[j, j, q] = v0 - alpha
            R[j, j, q] = alpha
        for c in range(j + 1, k):
            _reflect(A, c, A, j, beta, w)
            for q in range(LANES):
                R[j, c, q] = A[c, j, q]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _reflect(X, a, V, j, beta, w):  # pragma: no cover - compiled
    """Row a of X (6, LANES) times the reflection of vector j of V (entries j..5)."""
    w[:] = 0.0
    for i in range(j, 6):
        for q in range(LANES):
            w[q] += X[a, i, q] * V[j, i, q]
    for q in range(LANES):
        w[q] *= beta[j, q]
    for i in range(j, 6):
        for q in range(LANES):
            X[a, i, q] -= w[q] * V[j, i, q]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _wrench_basis(A, k, N, R, Ri, beta, bound, nx, w):  # pragma: no cover - compiled
    """Orthonormal basis N (6-k, 6, LANES) of the complement of the rows A[:k] (overwritten), and
    the lower bound ``1 / (||R^-1||_F ||R||_F)`` of sigma_min / sigma_max per lane (NaN or 0 for a
    zero column), as vjm.stiffness._wrench_basis."""
    _householder(A, k, R, beta, nx, w)
    for a in range(6 - k):                    # N = H_0 ... H_{k-1} [0; I]
        for i in range(6):
            for q in range(LANES):
                N[a, i, q] = 1.0 if i == k + a else 0.0
        for j in range(k - 1, -1, -1):
            _reflect(N, a, A, j, beta, w)
    if k == 0:
        bound[:] = math.inf
        return
    for i in range(k - 1, -1, -1):            # R^-1, back substitution
        for q in range(LANES):
            Ri[i, i, q] = 1.0 / R[i, i, q]
        for j in range(i + 1, k):
            w[:] = 0.0
            for c in range(i + 1, j + 1):
                for q in range(LANES):
                    w[q] += R[i, c, q] * Ri[c, j, q]
            for q in range(LANES):
                Ri[i, j, q] = -w[q] * Ri[i, i, q]
    nx[:] = 0.0
    w[:] = 0.0
    for i in range(k):
        for j in range(i, k):
            for q in range(LANES):
                nx[q] += R[i, j, q] * R[i, j, q]
                w[q] += Ri[i, j, q] * Ri[i, j, q]
    for q in range(LANES):
        bound[q] = 1.0 / math.sqrt(w[q] * nx[q])


@njit(cache=True, nogil=True, error_model="numpy")
def _cholesky(M, m, L, piv, t):  # pragma: no cover - compiled
    """Lower Cholesky factor L of M (m, m, LANES) and the smallest relative pivot min_j d_j / M_jj
    per lane (-1 where a diagonal entry is not positive), as vjm.stiffness.linalg.spd_inverse."""
    piv[:] = math.inf
    for j in range(m):
        for q in range(LANES):
            t[q] = M[j, j, q]
        for c in range(j):
            for q in range(LANES):
                t[q] -= L[j, c, q] * L[j, c, q]
        for q in range(LANES):
            mjj = M[j, j, q]
            rel = t[q] / (mjj if mjj > 0 else 1.0)
            piv[q] = min(piv[q], rel if mjj > 0 else -1.0)
            L[j, j, q] = math.sqrt(t[q] if rel > 1e-300 else 1.0)
        for i in range(j + 1, m):
            for q in range(LANES):
                t[q] = M[i, j, q]
            for c in range(j):
                for q in range(LANES):
                    t[q] -= L[i, c, q] * L[j, c, q]
            for q in range(LANES):
                L[i, j, q] = t[q] / L[j, j, q]


@njit(cache=True, nogil=True, error_model="numpy")
def _spd_inverse(M, m, Mi, L, piv, t):  # pragma: no cover - compiled
    """Mi = M^-1 (m, m, LANES) by Cholesky, and its relative pivot (:func:`_cholesky`)."""
    _cholesky(M, m, L, piv, t)
    # X = L^-1 into the upper triangle of Mi (Mi[j, i] holds X[i, j]), then M^-1 = X^T X
    for i in range(m):
        for q in range(LANES):
            Mi[i, i, q] = 1.0 / L[i, i, q]
        for j in range(i):
            t[:] = 0.0
            for c in range(j, i):
                for q in range(LANES):
                    t[q] += L[i, c, q] * Mi[j, c, q]
            for q in range(LANES):
                Mi[j, i, q] = -t[q] * Mi[i, i, q]
    for i in range(m):
        for j in range(i, m):
            t[:] = 0.0
            for c in range(j, m):
                for q in range(LANES):
                    t[q] += Mi[i, c, q] * Mi[j, c, q]
            for q in range(LANES):
                L[i, j, q] = t[q]
    for i in range(m):
        for j in range(i, m):
            for q in range(LANES):
                Mi[i, j, q] = L[i, j, q]
                Mi[j, i, q] = L[i, j, q]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _gather(code, var, coef, T, values, v0, v1, passive, svar, p0, nl, pts, F, E, O, J, A, Jl):  # pragma: no cover
    """Jacobians of poses p0 .. p0 + nl - 1 (a short group repeats pose p0) of one chain into the
    lanes: passive rows A, spring rows Jl; returns the largest closure gap (mm, NaN if one is NaN)."""
    gap = 0.0
    for q in range(LANES):
        p = p0 + q if q < nl else p0
        _end_and_jacobian(code, var, coef, T, values[p, v0:v1], F, E, O, J)
        if q < nl:
            for i in range(3):
                e = abs(F[i, 3] - pts[p, i])
                gap = e if (e > gap or math.isnan(e)) and not math.isnan(gap) else gap
        for j in range(passive.shape[0]):
            for i in range(6):
                A[j, i, q] = J[passive[j], i]
        for c in range(svar.shape[0]):
            for i in range(6):
                Jl[c, i, q] = J[svar[c], i]
    return gap


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _spring_sum(N, m, Jl, nd, sb, s0, s1, off, cb, Z, Y, M, t):  # pragma: no cover - compiled
    """M = sum_s Z_s C_s Z_s^T (m, m, LANES) over the springs s0 .. s1 - 1, Z = N^T J_s
    (vjm.stiffness._reduced_stiffness); spring s is the rows sb[s] - sb[s0] ... of Jl."""
    for a in range(m):
        for c in range(nd):
            t[:] = 0.0
            for i in range(6):
                for q in range(LANES):
                    t[q] += N[a, i, q] * Jl[c, i, q]
            for q in range(LANES):
                Z[a, c, q] = t[q]
    M[:m, :m, :] = 0.0
    for s in range(s0, s1):
        o, d, co = sb[s] - sb[s0], sb[s + 1] - sb[s], off[s]
        for a in range(m):                    # Y = Z_s C_s
            for e in range(d):
                t[:] = 0.0
                for c in range(d):
                    for q in range(LANES):
                        t[q] += Z[a, o + c, q] * cb[co + c * d + e, q]
                for q in range(LANES):
                    Y[a, e, q] = t[q]
        for a in range(m):                    # M += Y Z_s^T
            for b in range(m):
                t[:] = 0.0
                for e in range(d):
                    for q in range(LANES):
                        t[q] += Y[a, e, q] * Z[b, o + e, q]
                for q in range(LANES):
                    M[a, b, q] += t[q]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _add_projected(Mi, N, m, Kl, W, t):  # pragma: no cover - compiled
    """Kl += N^T M^-1 N (symmetrised), (6, 6, LANES)."""
    for b in range(m):                        # W = M^-1 N
        for i in range(6):
            t[:] = 0.0
            for a in range(m):
                for q in range(LANES):
                    t[q] += Mi[b, a, q] * N[a, i, q]
            for q in range(LANES):
                W[b, i, q] = t[q]
    for i in range(6):
        for j in range(i, 6):
            t[:] = 0.0
            for b in range(m):
                for q in range(LANES):
                    t[q] += W[b, i, q] * N[b, j, q] + W[b, j, q] * N[b, i, q]
            for q in range(LANES):
                h = 0.5 * t[q]
                Kl[i, j, q] += h
                if j != i:
                    Kl[j, i, q] += h


@njit(cache=True, nogil=True, error_model="numpy")
def _sym3_max_eig(a00, a11, a22, a01, a02, a12):  # pragma: no cover - compiled
    """Largest eigenvalue of a symmetric 3x3 matrix, closed form (vjm.stiffness.linalg.sym3_max_eig_soa)."""
    q = (a00 + a11 + a22) / 3.0
    p1 = a01 ** 2 + a02 ** 2 + a12 ** 2
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p2 = b00 ** 2 + b11 ** 2 + b22 ** 2 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    if not p > 0:
        return q
    det = (b00 * (b11 * b22 - a12 ** 2) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02)) / p ** 3
    r = min(max(det / 2.0, -1.0), 1.0)
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0)


@njit(cache=True, nogil=True, error_model="numpy")
def _ldl(Kl, rtol, L, D, Dinv, di, LD, r, t):  # pragma: no cover - compiled
    """Jacobi scaling ``di`` and unpivoted LDL^T of the symmetrised Kl (6, 6, LANES), as
    vjm.stiffness.linalg.psd_rank_inverse_soa; r counts the pivots above rtol, Dinv is 0 for the others."""
    for i in range(6):
        for q in range(LANES):
            d = math.sqrt(max(Kl[i, i, q], 0.0))
            di[i, q] = 1.0 / (d if d > 0 else 1.0)
    r[:] = 0
    for j in range(6):
        for q in range(LANES):
            t[q] = Kl[j, j, q] * di[j, q] * di[j, q]
        for c in range(j):
            for q in range(LANES):
                LD[c, q] = L[j, c, q] * D[c, q]
                t[q] -= L[j, c, q] * LD[c, q]
        for q in range(LANES):
            D[j, q] = t[q]
            good = t[q] > rtol
            r[q] += good
            Dinv[j, q] = 1.0 / t[q] if good else 0.0
        for i in range(j + 1, 6):
            for q in range(LANES):
                t[q] = (Kl[i, j, q] + Kl[j, i, q]) * (0.5 * di[j, q] * di[i, q])
            for c in range(j):
                for q in range(LANES):
                    t[q] -= L[i, c, q] * LD[c, q]
            for q in range(LANES):
                L[i, j, q] = t[q] * Dinv[j, q]


@njit(cache=True, nogil=True, error_model="numpy")
def _ldl_inverse(L, Dinv, di, X, Cl, t):  # pragma: no cover - compiled
    """Cl = D^-1/2 X^T D^-1 X D^-1/2 with X = L^-1 (unit lower), all (6, 6, LANES)."""
    for i in range(6):
        for q in range(LANES):
            X[i, i, q] = 1.0
        for j in range(i):
            t[:] = 0.0
            for c in range(j, i):
                for q in range(LANES):
                    t[q] += L[i, c, q] * X[c, j, q]
            for q in range(LANES):
                X[i, j, q] = -t[q]
    for i in range(6):
        for j in range(i, 6):
            t[:] = 0.0
            for c in range(j, 6):
                for q in range(LANES):
                    t[q] += X[c, i, q] * X[c, j, q] * Dinv[c, q]
            for q in range(LANES):
                Cl[i, j, q] = t[q] * di[i, q] * di[j, q]


@njit(cache=True, nogil=True, error_model="numpy")
def machine_block(code, var, coef, T, fo, values, vo, passive, po, svar, sb, sr, off, cfix, cpose, pts,
                  fast_rtol, rtol, K, C, rank, inv, kt, kr, flag, gaps):  # pragma: no cover - compiled
    """The machine's stiffness at every pose of a block, chain sum and inverse in one pass.

    Chain c is the factors ``fo[c]:fo[c+1]`` of ``code, var, coef, T`` (vjm.kinematics.ik.encode),
    the columns ``vo[c]:vo[c+1]`` of ``values`` (n, ...) and the passive variables
    ``passive[po[c]:po[c+1]]`` (chain-local numbers); its springs are ``sr[c]:sr[c+1]``, spring s
    spanning the chain-local variables ``svar[sb[s]:sb[s+1]]`` with its compliance (d*d values,
    row-major) at ``off[s]`` of the buffer ``cfix`` (constant) followed by a row of ``cpose`` (n, ...).
    Writes K, C = K^-1 (n, 6, 6), rank, inv, k_tran, k_rot as vjm.stiffness.assemble_soa where K is
    invertible (elsewhere rank counts the LDL^T pivots above ``rtol``: the caller redoes C), sets
    ``flag`` where a chain's fast closed form is not safe (the caller redoes the pose), and
    ``gaps[c]`` to chain c's largest closure gap (mm, NaN if one is NaN).
    Poses go LANES at a time; a short last group repeats its first pose (results not kept)."""
    n = values.shape[0]
    nc = fo.shape[0] - 1
    nfmax, nvmax, ndmax = 1, 1, 1
    for c in range(nc):
        nfmax = max(nfmax, fo[c + 1] - fo[c])
        nvmax = max(nvmax, vo[c + 1] - vo[c])
        ndmax = max(ndmax, sb[sr[c + 1]] - sb[sr[c]])
    F, E, O, J = np.empty((3, 4)), np.empty((nfmax, 3)), np.empty((nfmax, 3)), np.empty((nvmax, 6))
    Jl, A = np.empty((ndmax, 6, LANES)), np.empty((6, 6, LANES))
    R, Ri = np.zeros((6, 6, LANES)), np.zeros((6, 6, LANES))
    beta, bound, piv = np.empty((6, LANES)), np.empty(LANES), np.empty(LANES)
    t, w = np.empty(LANES), np.empty(LANES)
    N, Z, Y = np.empty((6, 6, LANES)), np.empty((6, ndmax, LANES)), np.empty((6, 6, LANES))
    M, Mi, Lc, W = np.empty((6, 6, LANES)), np.empty((6, 6, LANES)), np.empty((6, 6, LANES)), np.empty((6, 6, LANES))
    Kl, L, X, Cl = np.empty((6, 6, LANES)), np.zeros((6, 6, LANES)), np.zeros((6, 6, LANES)), np.empty((6, 6, LANES))
    D, Dinv, di, LD = np.empty((6, LANES)), np.empty((6, LANES)), np.empty((6, LANES)), np.empty((6, LANES))
    r = np.empty(LANES, dtype=np.int64)
    # every spring's compliance in one buffer: the constant ones once, the per-pose ones per lane
    nfix = cfix.shape[0]
    cb = np.empty((nfix + cpose.shape[1], LANES))
    for c in range(nfix):
        cb[c, :] = cfix[c]
    gaps[:] = 0.0
    for p0 in range(0, n, LANES):
        nl = min(LANES, n - p0)
        for q in range(LANES):
            p = p0 + q if q < nl else p0
            for c in range(cpose.shape[1]):
                cb[nfix + c, q] = cpose[p, c]
        Kl[:] = 0.0
        for c in range(nc):
            f0, f1, ps = fo[c], fo[c + 1], passive[po[c]:po[c + 1]]
            k = ps.shape[0]
            m = 6 - k
            g = _gather(code[f0:f1], var[f0:f1], coef[f0:f1], T[f0:f1], values, vo[c], vo[c + 1], ps,
                        svar[sb[sr[c]]:sb[sr[c + 1]]], p0, nl, pts, F, E, O, J, A, Jl)
            gaps[c] = g if (g > gaps[c] or math.isnan(g)) and not math.isnan(gaps[c]) else gaps[c]
            _wrench_basis(A, k, N, R, Ri, beta, bound, t, w)
            _spring_sum(N, m, Jl, sb[sr[c + 1]] - sb[sr[c]], sb, sr[c], sr[c + 1], off, cb, Z, Y, M, t)
            if m:
                _spd_inverse(M, m, Mi, Lc, piv, t)
            else:
                piv[:] = 1.0
            for q in range(nl):
                if not (bound[q] > fast_rtol and piv[q] > fast_rtol):
                    flag[p0 + q] = True
            _add_projected(Mi, N, m, Kl, W, t)
        _assemble_lanes(Kl, rtol, p0, nl, K, C, rank, inv, kt, kr, L, D, Dinv, di, LD, r, t, X, Cl)


@njit(cache=True, nogil=True, error_model="numpy")
def _assemble_lanes(Kl, rtol, p0, nl, K, C, rank, inv, kt, kr, L, D, Dinv, di, LD, r, t, X,
                    Cl):  # pragma: no cover - compiled
    """K, C = K^-1, rank, invertible, k_tran, k_rot of the lanes q < nl into the poses p0 + q."""
    _ldl(Kl, rtol, L, D, Dinv, di, LD, r, t)
    _ldl_inverse(L, Dinv, di, X, Cl, t)
    for q in range(nl):
        p = p0 + q
        for i in range(6):
            for j in range(6):
                K[p, i, j] = Kl[i, j, q]
        rank[p] = r[q]
        inv[p] = r[q] == 6
        if r[q] < 6:
            kt[p] = math.inf
            kr[p] = math.inf
            continue
        for i in range(6):
            for j in range(i, 6):
                C[p, i, j] = Cl[i, j, q]
                C[p, j, i] = Cl[i, j, q]
        kt[p] = _sym3_max_eig(Cl[0, 0, q], Cl[1, 1, q], Cl[2, 2, q], Cl[0, 1, q], Cl[0, 2, q], Cl[1, 2, q])
        kr[p] = _sym3_max_eig(Cl[3, 3, q], Cl[4, 4, q], Cl[5, 5, q], Cl[3, 4, q], Cl[3, 5, q], Cl[4, 5, q])
