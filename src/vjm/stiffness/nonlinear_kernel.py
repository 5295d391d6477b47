"""Compiled per-point Newton steps of the bordered equilibrium of :mod:`vjm.stiffness.nonlinear`, by numba.

Along a path (:mod:`vjm.toolpath.equilibrium`) the batched numpy step spends its time in
the overhead of small array operations and in one stacked solve per batch.  These kernels
evaluate the *same* equations point by point in compiled loops: the chain products and the
joint twist matrices (:func:`vjm.stiffness.nonlinear._chain_kinematics`), the closure residual, its
gradient and the Hessian of ``lam . g`` (:func:`vjm.stiffness.nonlinear._linearize`), the bordered
Newton matrix and its equilibrated solve (:func:`vjm.stiffness.nonlinear._newton_step`,
:func:`vjm.stiffness.nonlinear._solve`) and the residual check
(:func:`vjm.toolpath.equilibrium.residual_ok`).  The numpy functions stay the reference
and the fallback (no numba, body loads); tests check that both give the same equilibria.  The runs of
points along a path that use them are in :mod:`vjm.stiffness.march_kernel`.

Layout (see :func:`vjm.toolpath.equilibrium._Packed`): per chain a factor table (code
0-5: tx ty tz rx ry rz, 6: a constant; variable; coefficient; 4x4 constant; the factor's
joint index or -1) padded to the longest chain, and per point the chain data of
``nonlinear._ChainData`` padded likewise.  ``cache=True``: a process compiles once (some
seconds, on first use only), later ones load the machine code from disk.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import nonlinear_block

CONST = 6


@njit(cache=True, nogil=True, error_model="numpy")
def _mm3(A, B, out):  # pragma: no cover - compiled
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True, nogil=True, error_model="numpy")
def _platform_rotation(phi, R, D1, D2, second, A, Gm, tmp):  # pragma: no cover - compiled
    """``Rx Ry Rz`` and its first and (``second``) second derivatives (nonlinear.platform_rotation);
    A (3, 3, 3, 3), Gm and tmp (3, 3) are scratch."""
    A[:] = 0.0  # A[i, k]: factor i times its generator to the power k
    for i in range(3):
        c, s = math.cos(phi[i]), math.sin(phi[i])
        a, b = ((1, 2), (2, 0), (0, 1))[i]
        A[i, 0, i, i] = 1.0
        A[i, 0, a, a] = c
        A[i, 0, b, b] = c
        A[i, 0, a, b] = -s
        A[i, 0, b, a] = s
        Gm[:] = 0.0
        Gm[a, b] = -1.0
        Gm[b, a] = 1.0
        _mm3(A[i, 0], Gm, A[i, 1])
        if second:
            _mm3(A[i, 1], Gm, A[i, 2])
    for i in range(3):
        if second:
            for j in range(3):  # the derivative orders of the three factors
                o0, o1, o2 = int(i == 0) + int(j == 0), int(i == 1) + int(j == 1), int(i == 2) + int(j == 2)
                _mm3(A[0, o0], A[1, o1], tmp)
                _mm3(tmp, A[2, o2], D2[i, j])
        _mm3(A[0, int(i == 0)], A[1, int(i == 1)], tmp)
        _mm3(tmp, A[2, int(i == 2)], D1[i])
    _mm3(A[0, 0], A[1, 0], tmp)
    _mm3(tmp, A[2, 0], R)


@njit(cache=True, nogil=True, error_model="numpy")
def _chain(code, var, coef, Tc, jof, nf, v, F, X, tmp):  # pragma: no cover - compiled
    """End frame F (4, 4) and world twist matrices X (nJ, 4, 4) of one chain at variables v; tmp (4, 4)
    is scratch."""
    F[:] = 0.0
    for i in range(4):
        F[i, i] = 1.0
    for f in range(nf):
        c = code[f]
        if c == CONST:
            for r in range(4):
                for k in range(4):
                    tmp[r, k] = F[r, 0] * Tc[f, 0, k] + F[r, 1] * Tc[f, 1, k] + F[r, 2] * Tc[f, 2, k] \
                        + F[r, 3] * Tc[f, 3, k]
            F[:] = tmp
            continue
        a = coef[f] * v[var[f]]
        ax = c % 3
        if c < 3:
            for r in range(3):
                F[r, 3] = F[r, 3] + F[r, ax] * a
        else:
            cs, sn = math.cos(a), math.sin(a)
            i, j = ((1, 2), (2, 0), (0, 1))[ax]
            for r in range(3):
                fi, fj = F[r, i], F[r, j]
                F[r, i] = fi * cs + fj * sn
                F[r, j] = fj * cs - fi * sn
        jj = jof[f]
        Xj = X[jj]
        Xj[:] = 0.0
        e0, e1, e2 = F[0, ax], F[1, ax], F[2, ax]
        if c >= 3:  # a revolute factor: omega = e, v = o x e
            Xj[0, 1], Xj[0, 2], Xj[1, 2] = -e2, e1, -e0
            Xj[1, 0], Xj[2, 0], Xj[2, 1] = e2, -e1, e0
            o0, o1, o2 = F[0, 3], F[1, 3], F[2, 3]
            Xj[0, 3] = o1 * e2 - o2 * e1
            Xj[1, 3] = o2 * e0 - o0 * e2
            Xj[2, 3] = o0 * e1 - o1 * e0
        else:
            Xj[0, 3], Xj[1, 3], Xj[2, 3] = e0, e1, e2


@njit(cache=True, nogil=True, error_model="numpy")
def _vee_into(M, out, k):  # pragma: no cover - compiled
    out[k] = 0.5 * (M[2, 1] - M[1, 2])
    out[k + 1] = 0.5 * (M[0, 2] - M[2, 0])
    out[k + 2] = 0.5 * (M[1, 0] - M[0, 1])


@njit(cache=True, nogil=True, error_model="numpy")
def workspace_lin(tab, nv):  # pragma: no cover - compiled
    """Scratch arrays of :func:`linearize_ws` for the chains of ``tab`` with ``nv`` (padded) chain
    variables (allocated once per run of points)."""
    nJmax = max(1, tab[7].max())
    return (np.empty((3, 3)), np.empty((3, 3, 3)), np.empty((3, 3, 3, 3)), np.empty((3, 3, 3, 3)),
            np.empty((3, 3)), np.empty((4, 4)), np.zeros((nJmax, 4, 4)), np.zeros((nJmax, 4, 4)),
            np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)),
            np.empty(nv), np.empty((nJmax, 6)), np.empty((4, 4)), np.empty((3, 3)))


@njit(cache=True, nogil=True, error_model="numpy")
def linearize(tab, pt, z, P, hess, g, G, Hs):  # pragma: no cover - compiled
    """Closure residual g (nc,), gradient G (nc, nx + 6) and (``hess``) the Hessian Hs of ``lam . g``
    (nx + 6, nx + 6) at the unknowns z = (x, u, lam) of one point (nonlinear._linearize)."""
    linearize_ws(tab, pt, z, P, hess, g, G, Hs, workspace_lin(tab, pt[0].shape[1]))


@njit(cache=True, nogil=True, error_model="numpy")
def linearize_ws(tab, pt, z, P, hess, g, G, Hs, ws):  # pragma: no cover - compiled
    """:func:`linearize` with the scratch arrays ``ws`` of :func:`workspace_lin`.

    The gradient's rotation rows of joint j are ``vee(X_j F_3 Rp^T) = vee(w_j^ M)`` with the closure's
    ``M = F_3 Rp^T``, which is ``(tr(M) I - M) w_j / 2`` (w_j the joint's world axis; zero for a
    prismatic joint): no product of 3x3 matrices per joint.  The Hessian needs the products X_j F."""
    code, var, coef, Tc, jof, nf, mk, nJk, col = tab
    v0, R0, S, D, fixed = pt
    nch = code.shape[0]
    nx = G.shape[1] - 6
    u = z[nx:nx + 6]
    lam = z[nx + 6:]
    Rxyz, D1, D2, A3, Gm, F, X, dT, Rp, RpT, tmp, M, tmpT, v, Gf, tmp4, Nm = ws
    _platform_rotation(u[3:], Rxyz, D1, D2, hess, A3, Gm, tmp)
    g[:] = 0.0
    G[:] = 0.0
    if hess:
        Hs[:] = 0.0
    for k in range(nch):
        m, nJ, c0, r0 = mk[k], nJk[k], col[k], 6 * k
        nv = v0.shape[1]
        for b in range(nv):
            v[b] = v0[k, b]
        for a in range(m):
            xa = z[c0 + a]
            for b in range(nv):
                v[b] += xa * S[k, a, b]
        _chain(code[k], var[k], coef[k], Tc[k], jof[k], nf[k], v, F, X, tmp4)
        _mm3(Rxyz, R0[k], Rp)
        RpT[:] = Rp.T
        for i in range(3):
            g[r0 + i] = F[i, 3] - (P[i] + u[i])
        _mm3(F[:3, :3], RpT, M)
        _vee_into(M, g, r0 + 3)
        tr = M[0, 0] + M[1, 1] + M[2, 2]
        for i in range(3):
            for q in range(3):
                Nm[i, q] = 0.5 * ((tr if i == q else 0.0) - M[i, q])
        for j in range(nJ):  # X_j F's last column and vee(X_j F_3 Rp^T); the last rows of X_j are zero
            Xj = X[j]
            for r in range(3):
                Gf[j, r] = Xj[r, 0] * F[0, 3] + Xj[r, 1] * F[1, 3] + Xj[r, 2] * F[2, 3] + Xj[r, 3]
            w0, w1, w2 = Xj[2, 1], Xj[0, 2], Xj[1, 0]
            for r in range(3):
                Gf[j, 3 + r] = Nm[r, 0] * w0 + Nm[r, 1] * w1 + Nm[r, 2] * w2
        if hess:
            for j in range(nJ):  # X_j F; the last rows of X_j and of X_j F are zero, F's is (0, 0, 0, 1)
                for r in range(3):
                    for q in range(3):
                        dT[j, r, q] = X[j, r, 0] * F[0, q] + X[j, r, 1] * F[1, q] + X[j, r, 2] * F[2, q]
                    dT[j, r, 3] = Gf[j, r]
        _spring_columns(D[k], fixed, m, nJ, c0, r0, Gf, G)
        for i in range(3):
            G[r0 + i, nx + i] = -1.0
            _mm3(D1[i], R0[k], tmp)
            tmpT[:] = tmp.T
            _mm3(F[:3, :3], tmpT, M)
            _vee_into(M, G[r0 + 3:r0 + 6, nx + 3 + i], 0)
        if hess:
            _hessian_chain(k, m, nJ, c0, nx, lam, Rp, R0[k], D1, D2, F, X, dT, D, fixed, Hs)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _spring_columns(Dk, fixed, m, nJ, c0, r0, Gf, G):  # pragma: no cover - compiled
    """Chain rows r0.. of G's spring columns c0..: G = D Gf, the zeros of the spring bases D skipped
    (exact: 0 * finite adds 0)."""
    for a in range(m):
        if fixed[c0 + a]:
            continue
        g0 = g1 = g2 = g3 = g4 = g5 = 0.0
        for j in range(nJ):
            d = Dk[a, j]
            if d != 0.0:
                g0 += d * Gf[j, 0]
                g1 += d * Gf[j, 1]
                g2 += d * Gf[j, 2]
                g3 += d * Gf[j, 3]
                g4 += d * Gf[j, 4]
                g5 += d * Gf[j, 5]
        G[r0, c0 + a], G[r0 + 1, c0 + a], G[r0 + 2, c0 + a] = g0, g1, g2
        G[r0 + 3, c0 + a], G[r0 + 4, c0 + a], G[r0 + 5, c0 + a] = g3, g4, g5


@njit(cache=True, nogil=True, error_model="numpy")
def _hessian_chain(k, m, nJ, c0, nx, lam, Rp, R0k, D1, D2, F, X, dT, D, fixed, Hs):  # pragma: no cover
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


@njit(cache=True, nogil=True, error_model="numpy")
def newton_step(tab, pt, z, W, P, kappa, kd, xr):  # pragma: no cover - compiled
    """The full-load Newton step dz of one point (nonlinear._newton_step with s = 1, nonlinear._solve:
    the same matrix, row and column equilibration); NaN where the matrix is singular.  Solved by the
    chains' blocks and the platform's Schur complement (vjm.stiffness.nonlinear_block), or where a chain block
    is (nearly) singular on its own, by the general elimination of the whole matrix."""
    nx, nz = kappa.size, z.size
    nc = nz - nx - 6
    g, G, Hs = np.empty(nc), np.empty((nc, nx + 6)), np.empty((nx + 6, nx + 6))
    linearize(tab, pt, z, P, True, g, G, Hs)
    b = np.empty(nz)
    _rhs(g, G, z, W, kappa, xr, b)
    y = np.empty(nz)
    ws = nonlinear_block.workspace(tab)
    if nonlinear_block.factor(tab, nx, kd, G, Hs, ws):
        nonlinear_block.apply(tab, nx, ws, b, y)
        return y
    return nonlinear_block.full_solve(tab, nx, kd, G, Hs, b)


@njit(cache=True, nogil=True, error_model="numpy")
def _rhs(g, G, z, W, kappa, xr, b):  # pragma: no cover - compiled
    """Minus the equations' residual at z (springs, platform, closure): the Newton step's right-hand side."""
    nx, nz = kappa.size, z.size
    nc = nz - nx - 6
    for i in range(nx + 6):
        s = 0.0
        for c in range(nc):
            s += G[c, i] * z[nx + 6 + c]
        b[i] = -(kappa[i] * (z[i] - xr[i]) - s) if i < nx else -(-W[i - nx] - s)
    for c in range(nc):
        b[nx + 6 + c] = -g[c]


@njit(cache=True, nogil=True, error_model="numpy")
def residual_ok(tab, pt, z, W, P, kappa, xr, lref, rtol, roundoff):  # pragma: no cover - compiled
    """The equilibrium equations hold at z to ``rtol`` of each block's scale
    (vjm.toolpath.equilibrium.residual_ok, one point)."""
    for i in range(z.size):
        if not math.isfinite(z[i]):
            return False
    nx, nz = kappa.size, z.size
    nc = nz - nx - 6
    g, G = np.empty(nc), np.empty((nc, nx + 6))
    linearize(tab, pt, z, P, False, g, G, G[:0, :0])
    return _check(g, G, z, W, kappa, xr, lref, rtol, roundoff)


@njit(cache=True, nogil=True, error_model="numpy")
def _check(g, G, z, W, kappa, xr, lref, rtol, roundoff):  # pragma: no cover - compiled
    """residual_ok from the closure residual g and gradient G at z."""
    nx, nz = kappa.size, z.size
    nc = nz - nx - 6
    for i in range(z.size):
        if not math.isfinite(z[i]):
            return False
    lam = z[nx + 6:]
    Gl = np.zeros(nx + 6)
    for c in range(nc):
        lc = lam[c]
        for i in range(nx + 6):
            Gl[i] += G[c, i] * lc
    afs = agl = arx = 0.0
    for i in range(nx):
        fs = kappa[i] * (z[i] - xr[i])
        afs, agl, arx = max(afs, abs(fs)), max(agl, abs(Gl[i])), max(arx, abs(fs - Gl[i]))
    if not arx <= rtol * max(afs, agl):
        return False
    f_scale = max(abs(W[0]), abs(W[1]), abs(W[2])) + max(abs(W[3]), abs(W[4]), abs(W[5])) / lref
    lmax = 0.0
    for k in range(nc // 6):
        for i in range(3):
            lmax = max(lmax, abs(lam[6 * k + i]))
    f_scale += lmax
    ru_f = ru_m = 0.0
    for i in range(3):
        ru_f = max(ru_f, abs(-W[i] - Gl[nx + i]))
        ru_m = max(ru_m, abs(-W[3 + i] - Gl[nx + 3 + i]))
    if not (ru_f <= rtol * f_scale and ru_m <= rtol * f_scale * lref):
        return False
    gp = gr = up = ur = 0.0
    for k in range(nc // 6):
        for i in range(3):
            gp, gr = max(gp, abs(g[6 * k + i])), max(gr, abs(g[6 * k + 3 + i]))
    for i in range(3):
        up, ur = max(up, abs(z[nx + i])), max(ur, abs(z[nx + 3 + i]))
    return gp <= rtol * up + roundoff * lref and gr <= rtol * ur + roundoff
