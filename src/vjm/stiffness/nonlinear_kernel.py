"""Compiled per-point Newton steps of the bordered equilibrium of :mod:`vjm.stiffness.nonlinear`, by numba.

Along a path (:mod:`vjm.toolpath.equilibrium`) the batched numpy step spends its time in
the overhead of small array operations and in one stacked solve per batch.  These kernels
evaluate the *same* equations point by point in compiled loops: the chain products and the
joint twist matrices (:func:`vjm.stiffness.nonlinear._chain_kinematics`), the closure residual, its
gradient and the Hessian of ``lam . g`` (:func:`vjm.stiffness.nonlinear._linearize`), the bordered
Newton matrix and its equilibrated solve (:func:`vjm.stiffness.nonlinear._newton_step`,
:func:`vjm.stiffness.nonlinear._solve`) and the residual check
(:func:`vjm.toolpath.equilibrium.residual_ok`).  The numpy functions stay the reference
and the fallback (no numba, body loads); tests check that both give the same equilibria.  :func:`march`
runs them along a path: each point started from its neighbour's equilibrium (a given start corrected by
what its predecessors needed), chord steps with a kept factorization, Newton steps where those converge
slowly, the residual check.  The Hessian's terms are in :mod:`vjm.stiffness.nonlinear_hessian`.

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
from .nonlinear_hessian import _mm3, hessian_chain

CONST = 6


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
    (nx + 6, nx + 6) at the unknowns z = (x, u, lam) of one point (nonlinear._linearize).

    Compiled callers pass ``hess`` as ``np.bool_(...)``: numba compiles a function once per literal
    argument (``True``, ``False``, a non-contiguous ``Hs``), and these are the largest kernels to compile."""
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
            hessian_chain(k, m, nJ, c0, nx, lam, Rp, R0[k], D1, D2, F, X, dT, D, fixed, Hs)


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
def newton_step(tab, pt, z, W, P, kappa, kd, xr):  # pragma: no cover - compiled
    """The full-load Newton step dz of one point (nonlinear._newton_step with s = 1, nonlinear._solve:
    the same matrix, row and column equilibration); NaN where the matrix is singular.  Solved by the
    chains' blocks and the platform's Schur complement (vjm.stiffness.nonlinear_block), or where a chain block
    is (nearly) singular on its own, by the general elimination of the whole matrix."""
    nx, nz = kappa.size, z.size
    nc = nz - nx - 6
    g, G, Hs = np.empty(nc), np.empty((nc, nx + 6)), np.empty((nx + 6, nx + 6))
    linearize(tab, pt, z, P, np.bool_(True), g, G, Hs)
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
    linearize(tab, pt, z, P, np.bool_(False), g, G, np.empty((0, 0)))
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


@njit(cache=True, nogil=True, error_model="numpy")
def _start_from(tab, S, zp, zi, nx):  # pragma: no cover - compiled
    """Point i's start zi from its predecessor's state zp: the same chain-variable deformation (in
    point i's spring bases, least squares as equilibrium._to_x), platform pose and chain wrenches.
    A chain whose spring basis is the predecessor's (links and actuators of constant compliance)
    keeps its coordinates as they are: the least squares would return them."""
    mk, col = tab[6], tab[8]
    Sp, Si = S
    for k in range(mk.size):
        m, c0 = mk[k], col[k]
        if _same(Sp[k], Si[k], m):
            zi[c0:c0 + m] = zp[c0:c0 + m]
            continue
        nv = Si.shape[2]
        dv = np.zeros(nv)
        for a in range(m):
            for b in range(nv):
                dv[b] += zp[c0 + a] * Sp[k, a, b]
        _x_of(Si, k, m, dv, zi[c0:c0 + m])
    zi[nx:] = zp[nx:]


@njit(cache=True, nogil=True, error_model="numpy")
def _same(A, B, m):  # pragma: no cover - compiled
    """The first m rows of two spring bases are equal (exactly)."""
    for a in range(m):
        for b in range(A.shape[1]):
            if A[a, b] != B[a, b]:
                return False
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def to_x(tab, S, states, rows, vcol, z, nx):  # pragma: no cover - compiled
    """z[i] (x, u, lam) of the transferable states (chain-variable deformations, chain k's in columns
    vcol[k]:vcol[k + 1]; then u, lam) of points ``rows`` (equilibrium._to_x, point by point).  A chain
    whose spring basis is the previous row's reuses its least-squares operator ``(S S^T)^-1 S``."""
    mk, col = tab[6], tab[8]
    nv = S.shape[3]
    ks = 1 if S.shape[0] > 1 else 0  # one spring basis per point, or one for all
    ops = np.zeros((mk.size, S.shape[2], nv))
    have = np.zeros(mk.size, np.bool_)
    last = -1
    for i in rows:
        for k in range(mk.size):
            m, c0 = mk[k], col[k]
            dv = np.zeros(nv)
            dv[:vcol[k + 1] - vcol[k]] = states[i, vcol[k]:vcol[k + 1]]
            if last < 0 or not _same(S[last * ks, k], S[i * ks, k], m):
                have[k] = False
                _x_of(S[i * ks], k, m, dv, z[i, c0:c0 + m])
                continue
            if not have[k]:
                for b in range(nv):
                    e = np.zeros(nv)
                    e[b] = 1.0
                    _x_of(S[i * ks], k, m, e, ops[k, :m, b])
                have[k] = True
            for a in range(m):
                t = 0.0
                for b in range(nv):
                    t += ops[k, a, b] * dv[b]
                z[i, c0 + a] = t
        z[i, nx:] = states[i, vcol[mk.size]:]
        last = i


@njit(cache=True, nogil=True, error_model="numpy")
def _x_of(Si, k, m, dv, x):  # pragma: no cover - compiled
    """x (m,) of chain k's spring basis Si[k] whose chain-variable deformation is dv, by least squares."""
    nv = Si.shape[2]
    A, r = np.empty((m, m)), np.zeros(m)  # the normal equations S S^T x = S dv, S's zeros skipped
    for a in range(m):
        for b in range(nv):
            if Si[k, a, b] != 0.0:
                r[a] += Si[k, a, b] * dv[b]
        for a2 in range(a, m):
            t = 0.0
            for b in range(nv):
                if Si[k, a, b] != 0.0:
                    t += Si[k, a, b] * Si[k, a2, b]
            A[a, a2] = t
            A[a2, a] = t
    x[:] = nonlinear_block.lu_solve(A, r)


#: chord steps (the kept factorization of an earlier point's Newton matrix) a point may take
CHORD = 4
#: a chord step must shrink the step before it by this factor, else the next step refactorizes
CHORD_RATE = 0.01
#: a point settled by a chord step is accepted when that step was below this fraction of the platform's
#: deflection: the error left is about the step times the contraction (CHORD_RATE or less), some 1e-7
#: of the deflection, against the compensation's 1e-4 (vjm.toolpath.compensate.REL_TOL); below the
#: residual check's own level (RTOL), so it costs no steps on the 3-PUU's paths
CHORD_ACCEPT = 1e-5


@njit(cache=True, nogil=True, error_model="numpy")
def _settle(tab, pt, zi, Wi, Pi, kap, kdi, xri, max_steps, lref, rtol, roundoff, ws, have,
            count, scratch):  # pragma: no cover - compiled
    """Steps zi to the point's equilibrium: chord steps with the factorization in ws (``have[0]``: one is
    there, from an earlier point), full Newton steps (refactorized, at most ``max_steps``) when there is
    none or a chord step converges slowly.  Accepted once a step was taken and the residual check passes
    (after a chord step, also a step below CHORD_ACCEPT of the deflection).  count: full, chord steps;
    scratch: :func:`_scratch`."""
    nx, nz = kap.size, zi.size
    g, G, Hs, b, dz, wl = scratch
    full_left, chord_left = max_steps, CHORD
    taken, last_chord, step, prev = 0, False, math.inf, math.inf
    while True:
        for q in range(nz):
            if not math.isfinite(zi[q]):
                return False
        linearize_ws(tab, pt, zi, Pi, np.bool_(False), g, G, Hs, wl)
        if taken > 0 and _check(g, G, zi, Wi, kap, xri, lref, rtol, roundoff):
            umax = 0.0
            for q in range(6):
                umax = max(umax, abs(zi[nx + q]))
            # linear convergence: the error left is below the last step (times the contraction)
            if not last_chord or step <= CHORD_ACCEPT * umax:
                return True
        if have[0] and chord_left > 0 and not (last_chord and step > CHORD_RATE * prev):
            _rhs(g, G, zi, Wi, kap, xri, b)
            nonlinear_block.apply(tab, nx, ws, b, dz)
            chord_left -= 1
            count[1] += 1
            last_chord = True
        else:
            if full_left == 0:
                return False
            linearize_ws(tab, pt, zi, Pi, np.bool_(True), g, G, Hs, wl)
            _rhs(g, G, zi, Wi, kap, xri, b)
            have[0] = nonlinear_block.factor(tab, nx, kdi, G, Hs, ws)
            if have[0]:
                nonlinear_block.apply(tab, nx, ws, b, dz)
            else:
                dz[:] = nonlinear_block.full_solve(tab, nx, kdi, G, Hs, b)
            full_left -= 1
            count[0] += 1
            last_chord = False
        prev, step = step, 0.0
        for q in range(nz):
            zi[q] += dz[q] if math.isfinite(dz[q]) else math.nan
        for q in range(6):
            step = max(step, abs(dz[nx + q]))
        taken += 1


@njit(cache=True, nogil=True, error_model="numpy")
def _scratch(tab, nx, nz, nv):  # pragma: no cover - compiled
    """The arrays :func:`_settle` works in: g, G, Hs, the right-hand side, the step, linearize_ws's."""
    nc = nz - nx - 6
    return (np.empty(nc), np.empty((nc, nx + 6)), np.empty((nx + 6, nx + 6)), np.empty(nz), np.empty(nz),
            workspace_lin(tab, nv))


@njit(cache=True, nogil=True, error_model="numpy")
def march(tab, v0, R0, S, D, fixed, kappa, kd, xr, W, P, trivial, z, pos, end, given, max_steps,
          lref, rtol, roundoff, ok, steps):  # pragma: no cover - compiled
    """Runs of consecutive points, each from ``pos[r]`` to ``end[r]`` (exclusive): every point starts
    from its predecessor's equilibrium (extrapolated from the two before it where the wrench changes
    linearly), or where ``given[i]`` from z as given, corrected by what the predecessor's settling
    changed in its own given start (:func:`_shift_given`), then settles
    (:func:`_settle`: chord steps with the factorization of an earlier point of the run, full Newton
    steps where needed, the residual check).  A run stops at a point that fails (``pos[r]`` is left
    there, ``ok`` False) for the caller's reference solve; ``steps[r]``: full Newton and chord steps."""
    nx = kappa.shape[1]
    ks = 1 if S.shape[0] > 1 else 0  # S and D per point, or one for all
    ws = nonlinear_block.workspace(tab)
    scratch = _scratch(tab, nx, z.shape[1], v0.shape[2])
    have = np.zeros(1, np.bool_)
    z2 = np.empty(z.shape[1])
    zs, c1, c2 = np.empty(z.shape[1]), np.empty(z.shape[1]), np.empty(z.shape[1])  # given start, corrections
    for r in range(pos.size):
        i = pos[r]
        have[0] = False
        settled = 0  # consecutive points settled just before i in this run
        while i < end[r]:
            if trivial[i]:
                z[i] = 0.0
                ok[i] = True
                i += 1
                settled = 0
                continue
            if not given[i]:
                _start_from(tab, (S[(i - 1) * ks], S[i * ks]), z[i - 1], z[i], nx)
                if settled >= 2 and _steady(W[i - 2], W[i - 1], W[i]):
                    _start_from(tab, (S[(i - 2) * ks], S[i * ks]), z[i - 2], z2, nx)
                    for q in range(z2.size):  # linear extrapolation of the two settled predecessors
                        z[i, q] += z[i, q] - z2[q]
            else:
                zs[:] = z[i]
                if settled >= 1 and given[i - 1]:
                    lin = settled >= 2 and given[i - 2] and _steady(W[i - 2], W[i - 1], W[i])
                    _shift_given(tab, (S[(i - 2) * ks], S[(i - 1) * ks], S[i * ks]), c1, c2, lin, z[i],
                                 nx)
            for q in range(nx):  # a coordinate rigid at this point stays at rest (no step moves it)
                if fixed[i, q]:
                    z[i, q] = xr[i, q]
            pt = (v0[i], R0[i], S[i * ks], D[i * ks], fixed[i])
            ok[i] = _settle(tab, pt, z[i], W[i], P[i], kappa[i], kd[i], xr[i], max_steps, lref, rtol, roundoff,
                            ws, have, steps[r], scratch)
            if not ok[i]:
                break
            if given[i]:
                c2[:] = c1
                for q in range(zs.size):
                    c1[q] = z[i, q] - zs[q]
            i += 1
            settled += 1
        pos[r] = i


@njit(cache=True, nogil=True, error_model="numpy")
def _shift_given(tab, S3, c1, c2, lin, zi, nx):  # pragma: no cover - compiled
    """Point i's given start zi plus the correction settling made to its predecessor's given start, c1,
    or (``lin``) the corrections c2, c1 of the two before it extrapolated linearly, ``2 c1 - c2``.

    The compensation's checks start each point from the deflection's equilibrium at the programmed
    pose, while the commanded pose differs from it by the deflection: that start is off by the
    equilibrium's change over a deflection (~1e-3 of it on the 3-PUU), which varies slowly along the
    path.  S3: the spring bases of points i - 2, i - 1, i; a chain whose basis changed between them
    keeps its spring coordinates as given."""
    mk, col = tab[6], tab[8]
    Sa, Sb, Si = S3
    for k in range(mk.size):
        m, c0 = mk[k], col[k]
        if _same(Sb[k], Si[k], m):
            two = lin and _same(Sa[k], Sb[k], m)
            for a in range(c0, c0 + m):
                zi[a] += 2.0 * c1[a] - c2[a] if two else c1[a]
    for q in range(nx, zi.size):
        zi[q] += 2.0 * c1[q] - c2[q] if lin else c1[q]


@njit(cache=True, nogil=True, error_model="numpy")
def _steady(Wa, Wb, Wc):  # pragma: no cover - compiled
    """The wrenches of three consecutive points lie on a line to 1e-3 of their size (no corner of the
    path's force between them): the equilibrium is extrapolated from the two earlier points."""
    big = dev = 0.0
    for q in range(Wc.size):
        big = max(big, abs(Wa[q]), abs(Wb[q]), abs(Wc[q]))
        dev = max(dev, abs(Wa[q] - 2.0 * Wb[q] + Wc[q]))
    return dev <= 1e-3 * big
