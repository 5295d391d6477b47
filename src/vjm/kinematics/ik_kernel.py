"""Compiled per-pose kernels of the numeric inverse kinematics (:mod:`vjm.kinematics.ik`), by numba.

On batches of a few thousand poses the numpy path of :mod:`vjm.kinematics.ik` spends
most of its time in the overhead of small array operations (a chain of ten
factors is some hundred of them per Newton iteration).  These kernels run the
same arithmetic pose by pose in compiled loops: the chain product and its
Jacobian in one pass over the factors (eq. 3-5 as in
:func:`vjm.kinematics.chain._frame_product`), the residual, the Cholesky solve of the
normal equations and the step and stopping rules of :func:`vjm.kinematics.ik.newton`, so
both paths take the same steps and agree to round-off.

A chain is passed as arrays (see :func:`vjm.kinematics.ik.encode`): per factor a code
(0-5: tx ty tz rx ry rz, 6: a constant), the variable, the coefficient and the
4x4 constant.  ``cache=True`` keeps the machine code on disk: a process
compiles once (a few seconds), later ones load it.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

CONST = 6


@njit(cache=True, error_model="numpy")
def jacobian_columns(code, var, coef, F, E, O, J):  # pragma: no cover - compiled
    """Jacobian columns J (n_vars, 6) from the factors' axes E and origins O, at the end point F[:, 3]:
    ``e x (p_end - o), e`` for a rotation, ``e`` for a translation; a variable met twice adds its columns."""
    o0, o1, o2 = F[0, 3], F[1, 3], F[2, 3]
    for k in range(J.shape[0]):
        for b in range(6):
            J[k, b] = 0.0
    for f in range(code.size):
        c = code[f]
        if c == CONST:
            continue
        k, cf = var[f], coef[f]
        e0, e1, e2 = E[f, 0], E[f, 1], E[f, 2]
        if c >= 3:
            d0, d1, d2 = o0 - O[f, 0], o1 - O[f, 1], o2 - O[f, 2]
            J[k, 0] += cf * (e1 * d2 - e2 * d1)
            J[k, 1] += cf * (e2 * d0 - e0 * d2)
            J[k, 2] += cf * (e0 * d1 - e1 * d0)
            J[k, 3] += cf * e0
            J[k, 4] += cf * e1
            J[k, 5] += cf * e2
        else:
            J[k, 0] += cf * e0
            J[k, 1] += cf * e1
            J[k, 2] += cf * e2


@njit(cache=True, error_model="numpy")
def _end_and_jacobian(code, var, coef, T, v, F, E, O, J):  # pragma: no cover - compiled
    """End frame ``F`` (3, 4: columns x y z o) and Jacobian ``J`` (k, 6) of the chain at values ``v`` (k,).

    ``E``, ``O`` (n_factors, 3) receive each joint factor's axis and origin after it.  The frame
    is held in scalars (registers) while the factors are multiplied in."""
    x0, x1, x2 = 1.0, 0.0, 0.0
    y0, y1, y2 = 0.0, 1.0, 0.0
    z0, z1, z2 = 0.0, 0.0, 1.0
    o0, o1, o2 = 0.0, 0.0, 0.0
    for f in range(code.size):
        c = code[f]
        if c == CONST:
            t = T[f]
            o0 = o0 + t[0, 3] * x0 + t[1, 3] * y0 + t[2, 3] * z0
            o1 = o1 + t[0, 3] * x1 + t[1, 3] * y1 + t[2, 3] * z1
            o2 = o2 + t[0, 3] * x2 + t[1, 3] * y2 + t[2, 3] * z2
            x0, y0, z0 = (t[0, 0] * x0 + t[1, 0] * y0 + t[2, 0] * z0, t[0, 1] * x0 + t[1, 1] * y0 + t[2, 1] * z0,
                          t[0, 2] * x0 + t[1, 2] * y0 + t[2, 2] * z0)
            x1, y1, z1 = (t[0, 0] * x1 + t[1, 0] * y1 + t[2, 0] * z1, t[0, 1] * x1 + t[1, 1] * y1 + t[2, 1] * z1,
                          t[0, 2] * x1 + t[1, 2] * y1 + t[2, 2] * z1)
            x2, y2, z2 = (t[0, 0] * x2 + t[1, 0] * y2 + t[2, 0] * z2, t[0, 1] * x2 + t[1, 1] * y2 + t[2, 1] * z2,
                          t[0, 2] * x2 + t[1, 2] * y2 + t[2, 2] * z2)
            continue
        a = coef[f] * v[var[f]]
        if c >= 3 and a != 0.0:
            # right-multiplying by a rotation turns the two columns of its plane (transforms.elementary)
            cs, sn = math.cos(a), math.sin(a)
            if c == 3:
                y0, z0 = y0 * cs + z0 * sn, z0 * cs - y0 * sn
                y1, z1 = y1 * cs + z1 * sn, z1 * cs - y1 * sn
                y2, z2 = y2 * cs + z2 * sn, z2 * cs - y2 * sn
            elif c == 4:
                z0, x0 = z0 * cs + x0 * sn, x0 * cs - z0 * sn
                z1, x1 = z1 * cs + x1 * sn, x1 * cs - z1 * sn
                z2, x2 = z2 * cs + x2 * sn, x2 * cs - z2 * sn
            else:
                x0, y0 = x0 * cs + y0 * sn, y0 * cs - x0 * sn
                x1, y1 = x1 * cs + y1 * sn, y1 * cs - x1 * sn
                x2, y2 = x2 * cs + y2 * sn, y2 * cs - x2 * sn
        elif c == 0:
            o0, o1, o2 = o0 + x0 * a, o1 + x1 * a, o2 + x2 * a
        elif c == 1:
            o0, o1, o2 = o0 + y0 * a, o1 + y1 * a, o2 + y2 * a
        elif c == 2:
            o0, o1, o2 = o0 + z0 * a, o1 + z1 * a, o2 + z2 * a
        ax = c % 3
        if ax == 0:
            E[f, 0], E[f, 1], E[f, 2] = x0, x1, x2
        elif ax == 1:
            E[f, 0], E[f, 1], E[f, 2] = y0, y1, y2
        else:
            E[f, 0], E[f, 1], E[f, 2] = z0, z1, z2
        O[f, 0], O[f, 1], O[f, 2] = o0, o1, o2
    F[0, 0], F[1, 0], F[2, 0] = x0, x1, x2
    F[0, 1], F[1, 1], F[2, 1] = y0, y1, y2
    F[0, 2], F[1, 2], F[2, 2] = z0, z1, z2
    F[0, 3], F[1, 3], F[2, 3] = o0, o1, o2
    jacobian_columns(code, var, coef, F, E, O, J)


@njit(cache=True, error_model="numpy")
def _residual(F, R, p, i, ell, r):  # pragma: no cover - compiled
    """Closure residual ``r`` (6,) = (position error, ell * vee(R_end R_target^T)) of pose ``i``
    against targets R (3, 3, n), p (3, n); returns the error max(|dp|, ell |vee|) (NaN propagates)."""
    r0, r1, r2 = F[0, 3] - p[0, i], F[1, 3] - p[1, i], F[2, 3] - p[2, i]
    # (R_end R_target^T)[a, b] = row a of R_end . row b of R_target
    a00, a01, a02 = R[0, 0, i], R[0, 1, i], R[0, 2, i]
    a10, a11, a12 = R[1, 0, i], R[1, 1, i], R[1, 2, i]
    a20, a21, a22 = R[2, 0, i], R[2, 1, i], R[2, 2, i]
    m21 = F[2, 0] * a10 + F[2, 1] * a11 + F[2, 2] * a12
    m12 = F[1, 0] * a20 + F[1, 1] * a21 + F[1, 2] * a22
    m02 = F[0, 0] * a20 + F[0, 1] * a21 + F[0, 2] * a22
    m20 = F[2, 0] * a00 + F[2, 1] * a01 + F[2, 2] * a02
    m10 = F[1, 0] * a00 + F[1, 1] * a01 + F[1, 2] * a02
    m01 = F[0, 0] * a10 + F[0, 1] * a11 + F[0, 2] * a12
    er0, er1, er2 = 0.5 * (m21 - m12), 0.5 * (m02 - m20), 0.5 * (m10 - m01)
    r[0], r[1], r[2] = r0, r1, r2
    r[3], r[4], r[5] = ell * er0, ell * er1, ell * er2
    e = max(max(abs(r0), abs(r1), abs(r2)), ell * max(abs(er0), abs(er1), abs(er2)))
    if math.isnan(r0 + r1 + r2 + er0 + er1 + er2):
        return math.nan
    return e


@njit(cache=True, error_model="numpy")
def _normal_solve(A, r, L, x):  # pragma: no cover - compiled
    """``x`` (k,): least-squares solution of ``A^T x = r`` for A (k, 6), by the normal equations
    ``A A^T x = A r`` and Cholesky (a relative 1e-12 on the diagonal), as vjm.kinematics.ik._normal_solve
    (the diagonal of ``L`` holds its inverse)."""
    k = A.shape[0]
    for j in range(k):
        d = A[j, 0] * A[j, 0]
        for c in range(1, 6):
            d += A[j, c] * A[j, c]
        d *= 1.0 + 1e-12
        for m in range(j):
            d -= L[j, m] * L[j, m]
        inv = 1.0 / math.sqrt(d if (d > 1e-300 or math.isnan(d)) else 1e-300)
        L[j, j] = inv
        for i in range(j + 1, k):
            c2 = A[i, 0] * A[j, 0]
            for c in range(1, 6):
                c2 += A[i, c] * A[j, c]
            for m in range(j):
                c2 -= L[i, m] * L[j, m]
            L[i, j] = c2 * inv
    for i in range(k):
        y = A[i, 0] * r[0]
        for c in range(1, 6):
            y += A[i, c] * r[c]
        for m in range(i):
            y -= L[i, m] * x[m]
        x[i] = y * L[i, i]
    for i in range(k - 1, -1, -1):
        y = x[i]
        for m in range(i + 1, k):
            y = y - L[m, i] * x[m]
        x[i] = y * L[i, i]


@njit(cache=True, error_model="numpy")
def newton(code, var, coef, T, vt, R, p, ell, lim, max_iter, close_tol, stall_tol, predict_tol,
           ok, err):  # pragma: no cover - compiled
    """Newton on the closure of every pose, in place: values ``vt`` (k, n), converged ``ok`` (n,),
    error ``err`` (n,) mm.  Same stopping and step rules as :func:`vjm.kinematics.ik.newton`."""
    k, n = vt.shape
    nf = code.size
    F = np.empty((3, 4))
    E = np.empty((nf, 3))
    O = np.empty((nf, 3))
    J = np.empty((k, 6))
    L = np.empty((k, k))
    r = np.empty(6)
    x = np.empty(k)
    v = np.empty(k)
    for i in range(n):
        for a in range(k):
            v[a] = vt[a, i]
        ok[i] = False
        err[i] = math.inf
        prev = math.inf
        for it in range(max_iter + 1):
            _end_and_jacobian(code, var, coef, T, v, F, E, O, J)
            e = _residual(F, R, p, i, ell, r)
            done = (e <= close_tol * ell) or ((e <= stall_tol * ell) and (e >= 0.5 * prev))
            last = it == max_iter
            if last:
                done = e <= stall_tol * ell
            if done or last:
                err[i] = e
                ok[i] = done
                break
            prev2 = prev
            prev = e
            for a in range(k):
                for b in range(3, 6):
                    J[a, b] *= ell
            _normal_solve(J, r, L, x)
            big = 0.0
            for a in range(k):
                t = abs(x[a]) / lim[a]
                if math.isnan(t) or math.isnan(big):
                    big = math.nan
                elif t > big:
                    big = t
            s = 1.0 / big if big > 1.0 else 1.0
            for a in range(k):
                dv = -x[a] * s
                v[a] = v[a] + (dv if math.isfinite(dv) else 0.0)
            # quadratic convergence: the full step from error e leaves about c e^2 (vjm.kinematics.ik.newton)
            c2 = e / (prev2 * prev2) if prev2 != 0.0 else (math.nan if e == 0.0 else math.inf)
            c2 = max(c2, 10.0 / ell) if math.isfinite(c2) else math.inf
            if big <= 1.0 and 10.0 * c2 * e * e <= predict_tol * ell:
                ok[i] = True
                err[i] = 0.0
                break
        for a in range(k):
            vt[a, i] = v[a]


@njit(cache=True, error_model="numpy")
def predict(code, var, coef, T, va, anc, frames, X, before, after, ell, lim, seed, v0):  # pragma: no cover
    """Starting values ``v0`` (k, n): each pose's anchor's values ``va`` (k, na) plus the
    first-order change ``J^+ (dp, ell omega)`` from the anchor's frame to the pose's, J the
    anchor's Jacobian (as vjm.kinematics.ik._from_anchors); the ``seed`` (k,) where that change exceeds a
    Newton step's limits ``lim`` (k,) or is not finite.  The anchors are the poses ``anc`` (na,)
    of ``frames`` (n, 4, 4); pose i takes the nearer (coordinates ``X``, (n, 6)) of anchors
    ``before[i]`` and ``after[i]``."""
    k, na = va.shape
    nf = code.size
    F = np.empty((3, 4))
    E = np.empty((nf, 3))
    O = np.empty((nf, 3))
    J = np.empty((k, 6))
    L = np.empty((k, k))
    x = np.empty(k)
    u = np.zeros(6)
    Jp = np.empty((na, k, 6))
    v = np.empty(k)
    for a in range(na):
        for b in range(k):
            v[b] = va[b, a]
        _end_and_jacobian(code, var, coef, T, v, F, E, O, J)
        for b in range(k):
            for c in range(3, 6):
                J[b, c] *= ell
        for c in range(6):                       # column c of the least-squares inverse
            u[c] = 1.0
            _normal_solve(J, u, L, x)
            u[c] = 0.0
            for b in range(k):
                Jp[a, b, c] = x[b]
    d = np.empty(6)
    for i in range(frames.shape[0]):
        db, da = 0.0, 0.0
        for c in range(6):
            db += (X[i, c] - X[anc[before[i]], c]) ** 2
            da += (X[i, c] - X[anc[after[i]], c]) ** 2
        a = after[i] if da < db else before[i]
        ia = anc[a]
        f, g = frames[i], frames[ia]
        for c in range(3):
            d[c] = f[c, 3] - g[c, 3]
        # small rotation R R_anchor^T, first order: its vee; (R R_a^T)[s, t] = row s of R . row t of R_a
        m21 = f[2, 0] * g[1, 0] + f[2, 1] * g[1, 1] + f[2, 2] * g[1, 2]
        m12 = f[1, 0] * g[2, 0] + f[1, 1] * g[2, 1] + f[1, 2] * g[2, 2]
        m02 = f[0, 0] * g[2, 0] + f[0, 1] * g[2, 1] + f[0, 2] * g[2, 2]
        m20 = f[2, 0] * g[0, 0] + f[2, 1] * g[0, 1] + f[2, 2] * g[0, 2]
        m10 = f[1, 0] * g[0, 0] + f[1, 1] * g[0, 1] + f[1, 2] * g[0, 2]
        m01 = f[0, 0] * g[1, 0] + f[0, 1] * g[1, 1] + f[0, 2] * g[1, 2]
        d[3] = ell * (0.5 * (m21 - m12))
        d[4] = ell * (0.5 * (m02 - m20))
        d[5] = ell * (0.5 * (m10 - m01))
        near_enough = True
        for b in range(k):
            y = Jp[a, b, 0] * d[0]
            for c in range(1, 6):
                y += Jp[a, b, c] * d[c]
            x[b] = y
            near_enough = near_enough and abs(y) <= lim[b]      # False for NaN too
        for b in range(k):
            v0[b, i] = va[b, a] + x[b] if near_enough else seed[b]


@njit(cache=True, error_model="numpy")
def conjugate(Si, S, frames, out):  # pragma: no cover - compiled
    """``out[i] = Si @ frames[i] @ S`` for frames (n, 4, 4): a pose seen by a copy of a chain."""
    for i in range(frames.shape[0]):
        f = frames[i]
        o = out[i]
        for a in range(4):
            m0 = Si[a, 0] * f[0, 0] + Si[a, 1] * f[1, 0] + Si[a, 2] * f[2, 0] + Si[a, 3] * f[3, 0]
            m1 = Si[a, 0] * f[0, 1] + Si[a, 1] * f[1, 1] + Si[a, 2] * f[2, 1] + Si[a, 3] * f[3, 1]
            m2 = Si[a, 0] * f[0, 2] + Si[a, 1] * f[1, 2] + Si[a, 2] * f[2, 2] + Si[a, 3] * f[3, 2]
            m3 = Si[a, 0] * f[0, 3] + Si[a, 1] * f[1, 3] + Si[a, 2] * f[2, 3] + Si[a, 3] * f[3, 3]
            for b in range(4):
                o[a, b] = m0 * S[0, b] + m1 * S[1, b] + m2 * S[2, b] + m3 * S[3, b]


@njit(cache=True, error_model="numpy", inline="always")
def _rot(ax, c, s, out):  # pragma: no cover - compiled
    """out (3, 3) = the rotation about axis ax (0, 1, 2) of cosine c and sine s, right-handed."""
    i, j = (ax + 1) % 3, (ax + 2) % 3
    for a in range(3):
        for b in range(3):
            out[a, b] = 0.0
    out[ax, ax] = 1.0
    out[i, i] = c
    out[j, j] = c
    out[i, j] = -s
    out[j, i] = s


@njit(cache=True, error_model="numpy", inline="always")
def _mul3(A, B, out):  # pragma: no cover - compiled
    for a in range(3):
        for b in range(3):
            out[a, b] = A[a, 0] * B[0, b] + A[a, 1] * B[1, b] + A[a, 2] * B[2, b]


@njit(cache=True, error_model="numpy", inline="always")
def _wrap(a, seed):  # pragma: no cover - compiled
    return a + 2.0 * math.pi * math.floor((seed - a) / (2.0 * math.pi) + 0.5)


@njit(cache=True, error_model="numpy")
def leg(R0i, t0i, R1i, t1i, axes, vars_, coefs, th, sgn, frames, ell, v, err):  # pragma: no cover - compiled
    """:func:`vjm.kinematics.closed_form.solve` pose by pose: values v (n, 6) and closure errors err (n,) of
    a U-P-S leg ``C0 R R T R R R C1`` on frames (n, 4, 4), with ``C0^-1 = (R0i, t0i)`` and ``C1^-1 = (R1i,
    t1i)``.  ``axes`` (6,) the factors' axes, ``vars_`` and ``coefs`` their variables and coefficients, ``th``
    the seed's factor values, ``sgn`` the signs (sb, sa, strut, cos of the U joint's second angle, wrist
    permutation, cos of its middle angle).  The error is measured in the frame of ``C0^-1 F C1^-1``."""
    Rg, A, Ra, Rb, Rp, W, T, U = (np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)),
                                  np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)))
    p, x = np.empty(3), np.empty(6)
    a, b, c = axes[0], axes[1], axes[2]
    i, j, k = axes[3], axes[4], axes[5]
    sb, sa, sl, sc, e, cw = sgn[0], sgn[1], sgn[2], sgn[3], sgn[4], sgn[5]
    for n in range(frames.shape[0]):
        F = frames[n]
        # G = C0^-1 F C1^-1: rotation R0i RF R1i, centre R0i (RF t1i + tF) + t0i
        _mul3(R0i, F[:3, :3], A)
        _mul3(A, R1i, Rg)
        for r in range(3):
            y = t0i[r]
            for q in range(3):
                y += A[r, q] * t1i[q] + R0i[r, q] * F[q, 3]
            p[r] = y
        ll = sl * math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
        # the angles, and their cosines and sines from the same numbers (for the check: no more trigonometry)
        z = min(1.0, max(-1.0, sb * p[a] / ll))
        c2 = sc * math.sqrt(1.0 - z * z)
        t2 = math.asin(z)
        if sc < 0.0:
            t2 = math.pi - t2
        y1, x1 = sc * sa * p[b] / ll, sc * p[c] / ll
        h = math.sqrt(x1 * x1 + y1 * y1)
        x[0] = _wrap(math.atan2(y1, x1), th[0])
        x[1], x[2] = _wrap(t2, th[1]), ll
        _rot(a, x1 / h, y1 / h, Ra)
        _rot(b, c2, z, Rb)
        _mul3(Ra, Rb, Rp)
        for r in range(3):   # W = Rp^T Rg
            for s in range(3):
                W[r, s] = Rp[0, r] * Rg[0, s] + Rp[1, r] * Rg[1, s] + Rp[2, r] * Rg[2, s]
        z = min(1.0, max(-1.0, e * W[i, k]))
        c2 = cw * math.sqrt(1.0 - z * z)
        s2 = math.asin(z)
        if cw < 0.0:
            s2 = math.pi - s2
        y1, x1 = -cw * e * W[j, k], cw * W[k, k]
        y3, x3 = -cw * e * W[i, j], cw * W[i, i]
        x[3] = _wrap(math.atan2(y1, x1), th[3])
        x[4] = _wrap(s2, th[4])
        x[5] = _wrap(math.atan2(y3, x3), th[5])
        for f in range(6):
            v[n, vars_[f]] = x[f] / coefs[f]
        # the check: the leg multiplied out (Rp R_i R_j R_k, Rp l e_c) against G
        h = math.sqrt(x1 * x1 + y1 * y1)
        _rot(i, x1 / h, y1 / h, T)
        _rot(j, c2, z, U)
        _mul3(T, U, W)
        h = math.sqrt(x3 * x3 + y3 * y3)
        _rot(k, x3 / h, y3 / h, T)
        _mul3(W, T, U)
        _mul3(Rp, U, T)
        er = ep = 0.0
        for r in range(3):
            ep = max(ep, abs(ll * Rp[r, c] - p[r]))
            for s in range(3):
                er = max(er, abs(T[r, s] - Rg[r, s]))
        err[n] = max(ep, ell * er) if math.isfinite(ep + er) else math.nan
