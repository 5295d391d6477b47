"""Compiled (numba) self-weight equilibrium of a serial chain, one configuration at a time.

The same equilibrium as :func:`vjm.stiffness.nonlinear.deflection_map` with body loads: the stationary point of
``1/2 sum theta_s^T K_s theta_s - sum F_b . p_b(theta)`` (the springs' deformations ``theta`` added to
the chain's variables, dead loads ``F_b`` at points ``p_b`` fixed after a factor of the chain, a tool
force being one of them), by Newton's method with its exact Hessian.  A joint factor ``f`` moves a
point after it as ``dp/da_f = e_f x (p - o_f)`` (``e_f`` for a translation) and, for ``f`` proximal to
``h``, ``d2p/da_f da_h = e_f x dp/da_h``; summed over the loads beyond ``h`` these need only the
cumulative force ``sum F`` and ``sum F p^T`` at each factor, so a configuration costs O(factors^2).

Newton starts from the undeflected chain, so its first step is the linear sag (with the geometric
stiffness of the weights); steps that turn a rotational variable more than ``max_rot`` are shortened,
as in :mod:`vjm.stiffness.nonlinear`.  Convergence: a full Newton step whose tool twist ``J dtheta`` is below
``tol`` times the tool's deflection (or below the round-off floor).  A configuration that does not
converge within ``max_iter`` steps is
flagged: the caller solves it with the general solver (load steps, rigid directions).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .kernel import CONST, factor_step


@njit(cache=True, nogil=True, error_model="numpy")
def _springs(s1, c1, s6, k6, k, Kv, fixed):  # pragma: no cover - compiled
    """Stiffness Kv (nv, nv) of the springs' variables at configuration k (1-dof compliances c1 (m1, n),
    6-dof stiffnesses k6 (m6, 6, 6)); fixed: variables without a spring or with a rigid 1-dof one."""
    Kv[:, :] = 0.0
    fixed[:] = True
    for m in range(s1.shape[0]):
        c = c1[m, k]
        if c > 0.0:
            Kv[s1[m], s1[m]] += 1.0 / c
            fixed[s1[m]] = False
    for m in range(s6.shape[0]):
        for i in range(6):
            fixed[s6[m, i]] = False
            for j in range(6):
                Kv[s6[m, i], s6[m, j]] += k6[m, i, j]


@njit(cache=True, nogil=True, error_model="numpy")
def _walk(kinds, var, coef, T, v, lidx, lpt, k, F, E, O, P):  # pragma: no cover - compiled
    """End frame F (3, 4), each factor's axis E and origin O, each load's world point P (nl, 3)."""
    for i in range(3):
        for j in range(4):
            F[i, j] = 1.0 if i == j else 0.0
    ld = 0
    nl = lidx.shape[0]
    for f in range(kinds.shape[0]):
        factor_step(kinds, var, coef, T, v, f, F, E, O)
        while ld < nl and lidx[ld] == f:
            for r in range(3):
                P[ld, r] = F[r, 0] * lpt[ld, 0, k] + F[r, 1] * lpt[ld, 1, k] + F[r, 2] * lpt[ld, 2, k] + F[r, 3]
            ld += 1


@njit(cache=True, nogil=True, error_model="numpy")
def _loads(kinds, var, coef, lidx, lforce, k, E, O, P, Fs, M, g, H, hess):  # pragma: no cover - compiled
    """Gradient g (nv,) and (with ``hess``) Hessian H (nv, nv) of the loads' work ``sum F . p`` in the
    chain's variables.

    Fs (nf, 3), M (nf, 3, 3): the force and ``sum F p^T`` of the loads beyond each factor."""
    nf = kinds.shape[0]
    g[:] = 0.0
    if hess:
        H[:, :] = 0.0
    fs = np.zeros(3)
    mm = np.zeros((3, 3))
    ld = lidx.shape[0] - 1
    for f in range(nf - 1, -1, -1):
        while ld >= 0 and lidx[ld] == f:
            for a in range(3):
                fa = lforce[ld, a, k]
                fs[a] += fa
                for b in range(3):
                    mm[a, b] += fa * P[ld, b]
            ld -= 1
        Fs[f] = fs
        M[f] = mm
    for h in range(nf):
        kh = kinds[h]
        if kh == CONST:
            continue
        vh, ch = var[h], coef[h]
        eh, oh, fh, Mh = E[h], O[h], Fs[h], M[h]
        fe = fh[0] * eh[0] + fh[1] * eh[1] + fh[2] * eh[2]
        if kh >= 3:  # e . (sum p x F - o x sum F)
            mx = Mh[2, 1] - Mh[1, 2] - (oh[1] * fh[2] - oh[2] * fh[1])
            my = Mh[0, 2] - Mh[2, 0] - (oh[2] * fh[0] - oh[0] * fh[2])
            mz = Mh[1, 0] - Mh[0, 1] - (oh[0] * fh[1] - oh[1] * fh[0])
            g[vh] += ch * (eh[0] * mx + eh[1] * my + eh[2] * mz)
            tr = Mh[0, 0] + Mh[1, 1] + Mh[2, 2] - (fh[0] * oh[0] + fh[1] * oh[1] + fh[2] * oh[2])
        else:
            g[vh] += ch * fe
            tr = 0.0
        if not hess:
            continue
        for f in range(h + 1):  # f proximal to (or equal to) h; a translation f turns nothing
            kf = kinds[f]
            if kf == CONST or kf < 3:
                continue
            ef = E[f]
            if kh >= 3:  # sum F . (e_f x (e_h x (p - o_h)))
                ePe = 0.0
                for a in range(3):
                    for b in range(3):
                        ePe += eh[a] * Mh[a, b] * ef[b]
                eo = ef[0] * oh[0] + ef[1] * oh[1] + ef[2] * oh[2]
                ee = ef[0] * eh[0] + ef[1] * eh[1] + ef[2] * eh[2]
                q = ePe - fe * eo - tr * ee
            else:  # sum F . (e_f x e_h)
                q = (fh[0] * (ef[1] * eh[2] - ef[2] * eh[1]) + fh[1] * (ef[2] * eh[0] - ef[0] * eh[2])
                     + fh[2] * (ef[0] * eh[1] - ef[1] * eh[0]))
            w = coef[f] * ch * q
            vf = var[f]
            H[vf, vh] += w
            if f != h:
                H[vh, vf] += w


@njit(cache=True, nogil=True, error_model="numpy")
def _tool_step(kinds, var, coef, F, E, O, dv, out):  # pragma: no cover - compiled
    """The tool twist (6,) of a change dv of the chain's variables, linearized: ``J dv``."""
    out[:] = 0.0
    for f in range(kinds.shape[0]):
        kd = kinds[f]
        if kd == CONST:
            continue
        a = coef[f] * dv[var[f]]
        e = E[f]
        if kd >= 3:
            dx, dy, dz = F[0, 3] - O[f, 0], F[1, 3] - O[f, 1], F[2, 3] - O[f, 2]
            out[0] += a * (e[1] * dz - e[2] * dy)
            out[1] += a * (e[2] * dx - e[0] * dz)
            out[2] += a * (e[0] * dy - e[1] * dx)
            out[3] += a * e[0]
            out[4] += a * e[1]
            out[5] += a * e[2]
        else:
            out[0] += a * e[0]
            out[1] += a * e[1]
            out[2] += a * e[2]


@njit(cache=True, nogil=True, error_model="numpy")
def _factor(A, L, d):  # pragma: no cover - compiled
    """A = diag(1/d) L D L^T diag(1/d) in place (Jacobi scaling d, unit L below the diagonal, D on it,
    no pivoting: A is a stiffness); False if a pivot is not clear of zero."""
    n = A.shape[0]
    for i in range(n):
        d[i] = 1.0 / np.sqrt(abs(A[i, i])) if A[i, i] != 0.0 else 1.0
    for i in range(n):
        for j in range(n):
            L[i, j] = A[i, j] * d[i] * d[j]
    for j in range(n):
        s = L[j, j]
        for m in range(j):
            s -= L[j, m] * L[j, m] * L[m, m]
        if not abs(s) > 1e-12:
            return False
        L[j, j] = s
        for i in range(j + 1, n):
            t = L[i, j]
            for m in range(j):
                t -= L[i, m] * L[j, m] * L[m, m]
            L[i, j] = t / s
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _back(L, d, b, x):  # pragma: no cover - compiled
    """x = A^-1 b from :func:`_factor`'s L, d."""
    n = b.shape[0]
    for i in range(n):
        t = b[i] * d[i]
        for m in range(i):
            t -= L[i, m] * x[m]
        x[i] = t
    for i in range(n):
        x[i] /= L[i, i]
    for i in range(n - 1, -1, -1):
        t = x[i]
        for m in range(i + 1, n):
            t -= L[m, i] * x[m]
        x[i] = t
    for i in range(n):
        x[i] *= d[i]


@njit(cache=True, nogil=True, error_model="numpy")
def _assemble(Kv, fixed, H, L, sc):  # pragma: no cover - compiled
    """The energy's Hessian ``K - H_loads`` in H (H_loads in, fixed variables as unit rows), factorized."""
    nv = H.shape[0]
    for i in range(nv):
        for j in range(nv):
            H[i, j] = Kv[i, j] - H[i, j]
    for i in range(nv):
        if fixed[i]:
            for j in range(nv):
                H[i, j] = 0.0
                H[j, i] = 0.0
            H[i, i] = 1.0
    return _factor(H, L, sc)


@njit(cache=True, nogil=True, error_model="numpy")
def _sizes(step, tw, alpha):  # pragma: no cover - compiled
    """Adds ``alpha step`` to the tool twist tw; the step's largest translation and rotation, tw's size."""
    sp = 0.0
    sr = 0.0
    size = 0.0
    for i in range(6):
        tw[i] += alpha * step[i]
        size = max(size, abs(tw[i]))
        if i < 3:
            sp = max(sp, abs(step[i]))
        else:
            sr = max(sr, abs(step[i]))
    return sp, sr, size


@njit(cache=True, nogil=True, error_model="numpy")
def _newton(kinds, var, coef, T, vt, lidx, lpt, lforce, k, Kv, fixed, rot, tol, max_iter, max_rot, floor_p,
            floor_r, w):  # pragma: no cover - compiled
    """Newton on configuration k; the frames of the last iterate are left in w's F; returns (iterations,
    converged).  The Hessian's factorization is kept while the steps shrink tenfold or faster (the
    chord method: the same equations, the same fixed point); it is rebuilt when they do not."""
    F, E, O, P, Fs, M, H, L, sc, g, r, dv, th, v, tw, step, p0, R0 = w
    nv = th.shape[0]
    th[:] = 0.0
    tw[:] = 0.0
    fresh = False
    prev = np.inf
    for it in range(max_iter + 1):
        for i in range(nv):
            v[i] = vt[i, k] + th[i]
        _walk(kinds, var, coef, T, v, lidx, lpt, k, F, E, O, P)
        if it == 0:
            for i in range(3):
                p0[i] = F[i, 3]
                for j in range(3):
                    R0[i, j] = F[i, j]
        if it == max_iter:
            return it, False
        hess = not fresh
        _loads(kinds, var, coef, lidx, lforce, k, E, O, P, Fs, M, g, H, hess)
        for i in range(nv):  # residual g - K theta, Hessian K - H_loads; fixed variables stay
            t = 0.0
            for j in range(nv):
                t += Kv[i, j] * th[j]
            r[i] = 0.0 if fixed[i] else g[i] - t
        if hess:
            if not _assemble(Kv, fixed, H, L, sc):
                return it, False
            fresh = True
        _back(L, sc, r, dv)
        big = 0.0
        for i in range(nv):
            if rot[i] and abs(dv[i]) > big:
                big = abs(dv[i])
        if not np.isfinite(big):
            return it, False
        alpha = max_rot / big if big > max_rot else 1.0
        _tool_step(kinds, var, coef, F, E, O, dv, step)
        sp, sr, size = _sizes(step, tw, alpha)
        for i in range(nv):
            th[i] += alpha * dv[i]
        cur = max(sp, sr)
        if alpha < 1.0 or cur > 0.1 * prev:
            fresh = False  # slow or damped: a new Hessian next time
        prev = cur if alpha == 1.0 else np.inf
        if alpha == 1.0 and (cur <= tol * size or (sp <= floor_p and sr <= floor_r)):
            for i in range(nv):
                v[i] = vt[i, k] + th[i]
            _walk(kinds, var, coef, T, v, lidx, lpt, k, F, E, O, P)
            return it + 1, True
    return max_iter, False


@njit(cache=True, nogil=True, error_model="numpy")
def sag_kernel(kinds, var, coef, T, vt, s1, c1, s6, k6, lidx, lpt, lforce, tol, max_iter, max_rot, floor_p,
               floor_r, pts0, R0, pts, R, iters, ok):  # pragma: no cover - compiled
    """Equilibrium of every configuration k of vt (n_vars, n): the undeflected tool point pts0 (n, 3) and
    orientation R0 (n, 3, 3), the deflected ones pts, R, Newton iterations iters (n,), converged ok (n,).

    Loads sorted by factor: lidx (nl,) factor indices, lpt (nl, 3, n) points in the frame after the
    factor, lforce (nl, 3, n) world forces; springs as :func:`vjm.robot.kernel.stiffness_kernel`'s, the 6-dof
    ones by their stiffnesses k6 (m6, 6, 6)."""
    nf, nv = kinds.shape[0], vt.shape[0]
    nl = lidx.shape[0]
    rot = np.zeros(nv, dtype=np.bool_)
    for f in range(nf):
        if kinds[f] != CONST and kinds[f] >= 3:
            rot[var[f]] = True
    w = (np.zeros((3, 4)), np.zeros((nf, 3)), np.zeros((nf, 3)), np.zeros((nl, 3)), np.zeros((nf, 3)),
         np.zeros((nf, 3, 3)), np.zeros((nv, nv)), np.zeros((nv, nv)), np.zeros(nv), np.zeros(nv), np.zeros(nv),
         np.zeros(nv), np.zeros(nv), np.zeros(nv), np.zeros(6), np.zeros(6), np.zeros(3), np.zeros((3, 3)))
    F, p0, r0 = w[0], w[16], w[17]
    Kv = np.zeros((nv, nv))
    fixed = np.zeros(nv, dtype=np.bool_)
    for k in range(vt.shape[1]):
        _springs(s1, c1, s6, k6, k, Kv, fixed)
        iters[k], ok[k] = _newton(kinds, var, coef, T, vt, lidx, lpt, lforce, k, Kv, fixed, rot, tol, max_iter,
                                  max_rot, floor_p, floor_r, w)
        for i in range(3):
            pts0[k, i] = p0[i]
            pts[k, i] = F[i, 3]
            for j in range(3):
                R0[k, i, j] = r0[i, j]
                R[k, i, j] = F[i, j]
