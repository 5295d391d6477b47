"""Compiled (numba) tool compliance and stiffness of a serial chain, one configuration at a time.

``C = sum_s J_s C_s J_s^T`` at the tool (world axes, at the tool point), then ``K = C^-1``: the
chain's product is walked factor by factor as in :func:`vjm.kinematics.chain._frame_product` (frames as 3x4
matrices), each joint or spring factor's axis and origin kept, and the Jacobian columns
(``e x (p_end - o), e`` for a rotation, ``e`` for a translation; a variable met twice adds its
columns) contracted with the springs' compliances -- the closed form of :func:`vjm.kinematics.chain.jacobian`.
The inverse is :func:`vjm.stiffness.linalg.psd_rank_inverse`'s: Jacobi scaling, unpivoted LDL^T, every pivot
above ``rtol``; a configuration where one is not is flagged, and the caller redoes it with the
rank-revealing numpy path (pseudo-inverse, rank).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..kinematics.ik_kernel import CONST, jacobian_columns
from ..kinematics.transforms import KINDS


def encode(chain):
    """The chain as arrays: kinds (nf,), var (nf,), coef (nf,), constants (nf, 3, 4)."""
    nf = len(chain.factors)
    kinds = np.empty(nf, dtype=np.int64)
    var = np.zeros(nf, dtype=np.int64)
    coef = np.ones(nf)
    T = np.zeros((nf, 3, 4))
    for i, f in enumerate(chain.factors):
        if f.kind == "const":
            kinds[i] = CONST
            T[i] = f.T[:3]
        else:
            kinds[i] = KINDS.index(f.kind)
            var[i], coef[i] = f.var, f.coef
    return kinds, var, coef, T


@njit(cache=True, nogil=True, error_model="numpy")
def factor_step(kinds, var, coef, T, v, f, F, E, O):  # pragma: no cover - compiled
    """Frame F (3, 4) times factor ``f`` at variable values ``v``; a joint or spring factor's axis and
    origin after it go to E[f], O[f] (the walk of both kernels: stiffness and self-weight)."""
    kd = kinds[f]
    if kd == CONST:
        for i in range(3):
            r0, r1, r2, r3 = F[i, 0], F[i, 1], F[i, 2], F[i, 3]
            for j in range(4):
                F[i, j] = r0 * T[f, 0, j] + r1 * T[f, 1, j] + r2 * T[f, 2, j]
            F[i, 3] += r3
        return
    a = coef[f] * v[var[f]]
    ax = kd % 3
    if a != 0.0:
        if kd >= 3:
            ii, jj = (ax + 1) % 3, (ax + 2) % 3
            c, s = np.cos(a), np.sin(a)
            for r in range(3):
                ci, cj = F[r, ii], F[r, jj]
                F[r, ii] = ci * c + cj * s
                F[r, jj] = cj * c - ci * s
        else:
            for r in range(3):
                F[r, 3] += F[r, ax] * a
    for r in range(3):
        E[f, r] = F[r, ax]
        O[f, r] = F[r, 3]


@njit(cache=True, nogil=True, error_model="numpy")
def _walk(kinds, var, coef, T, vt, k, F, E, O):  # pragma: no cover - compiled
    """Frames of configuration k: F the end frame (3, 4); E, O each factor's axis and origin."""
    for i in range(3):
        for j in range(4):
            F[i, j] = 1.0 if i == j else 0.0
    v = vt[:, k]
    for f in range(kinds.shape[0]):
        factor_step(kinds, var, coef, T, v, f, F, E, O)


@njit(cache=True, nogil=True, error_model="numpy")
def _inverse(C, K, rtol):  # pragma: no cover - compiled
    """K = C^-1 by Jacobi scaling and unpivoted LDL^T; False if a pivot is not above rtol."""
    d = np.empty(6)
    for i in range(6):
        d[i] = np.sqrt(C[i, i]) if C[i, i] > 0.0 else 1.0
    A = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            A[i, j] = C[i, j] / (d[i] * d[j])
    L = np.eye(6)
    D = np.empty(6)
    for j in range(6):
        s = A[j, j]
        for m in range(j):
            s -= L[j, m] * L[j, m] * D[m]
        if not s > rtol:
            return False
        D[j] = s
        for i in range(j + 1, 6):
            t = A[i, j]
            for m in range(j):
                t -= L[i, m] * L[j, m] * D[m]
            L[i, j] = t / s
    # inverse of L (unit lower), then A^-1 = L^-T D^-1 L^-1
    Li = np.eye(6)
    for j in range(6):
        for i in range(j + 1, 6):
            t = 0.0
            for m in range(j, i):
                t -= L[i, m] * Li[m, j]
            Li[i, j] = t
    for i in range(6):
        for j in range(i, 6):
            t = 0.0
            for m in range(j, 6):
                t += Li[m, i] * Li[m, j] / D[m]
            K[i, j] = t / (d[i] * d[j])
            K[j, i] = K[i, j]
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _max_eig3(C, o):  # pragma: no cover - compiled
    """Largest eigenvalue of the symmetric 3x3 block ``C[o:o+3, o:o+3]``: :func:`vjm.stiffness.linalg.sym3_max_eig`'s
    closed form (trigonometric)."""
    q = (C[o, o] + C[o + 1, o + 1] + C[o + 2, o + 2]) / 3.0
    a01, a02, a12 = C[o, o + 1], C[o, o + 2], C[o + 1, o + 2]
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    b0, b1, b2 = C[o, o] - q, C[o + 1, o + 1] - q, C[o + 2, o + 2] - q
    p = np.sqrt((b0 * b0 + b1 * b1 + b2 * b2 + 2.0 * p1) / 6.0)
    if not p > 0.0:
        return q
    det = (b0 * (b1 * b2 - a12 * a12) - a01 * (a01 * b2 - a12 * a02) + a02 * (a01 * a12 - b1 * a02)) / p ** 3
    r = min(max(det / 2.0, -1.0), 1.0)
    return q + 2.0 * p * np.cos(np.arccos(r) / 3.0)


@njit(cache=True, nogil=True, error_model="numpy")
def stiffness_kernel(kinds, var, coef, T, vt, s1, c1, s6, c6, rtol, C, K, ok, pts, R, ct, cr):  # pragma: no cover
    """Fill C, K (n, 6, 6), ok (n,) (K inverted here), tool points pts (n, 3), orientations R (n, 3, 3) and
    the largest eigenvalues ct, cr (n,) of C's translational and rotational blocks.

    vt (n_vars, n): variable values; s1 (m1,) the 1-dof springs' variables with compliances c1 (m1, n);
    s6 (m6, 6) the 6-dof springs' variables with compliances c6 (m6, 6, 6)."""
    nf = kinds.shape[0]
    F = np.zeros((3, 4))
    E = np.zeros((nf, 3))
    O = np.zeros((nf, 3))
    J = np.zeros((vt.shape[0], 6))
    Z = np.zeros((6, 6))
    Y = np.zeros((6, 6))
    for k in range(vt.shape[1]):
        _walk(kinds, var, coef, T, vt, k, F, E, O)
        jacobian_columns(kinds, var, coef, F, E, O, J)
        Ck = C[k]
        Ck[:, :] = 0.0
        for m in range(s1.shape[0]):
            v = s1[m]
            c = c1[m, k]
            for i in range(6):
                ci = c * J[v, i]
                for j in range(6):
                    Ck[i, j] += ci * J[v, j]
        for m in range(s6.shape[0]):
            for a in range(6):
                Z[a] = J[s6[m, a]]
            for a in range(6):  # Y = C_s Z: (6 spring coordinates, 6 twist components)
                for j in range(6):
                    t = 0.0
                    for b in range(6):
                        t += c6[m, a, b] * Z[b, j]
                    Y[a, j] = t
            for i in range(6):
                for j in range(6):
                    t = 0.0
                    for a in range(6):
                        t += Z[a, i] * Y[a, j]
                    Ck[i, j] += t
        for i in range(6):
            for j in range(i + 1, 6):
                h = 0.5 * (Ck[i, j] + Ck[j, i])
                Ck[i, j] = h
                Ck[j, i] = h
        ok[k] = _inverse(Ck, K[k], rtol)
        ct[k] = _max_eig3(Ck, 0)
        cr[k] = _max_eig3(Ck, 3)
        for i in range(3):
            pts[k, i] = F[i, 3]
            for j in range(3):
                R[k, i, j] = F[i, j]
