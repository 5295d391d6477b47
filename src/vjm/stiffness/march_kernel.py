"""Compiled (numba) equilibria along a path: runs of consecutive points, each started from its neighbour's
equilibrium and settled by chord and Newton steps of :mod:`vjm.stiffness.nonlinear_kernel`.

:func:`march` is what :mod:`vjm.toolpath.equilibrium` calls (its numpy path stays the reference): the starts
(a predecessor's state, extrapolated where the wrench changes linearly; a given start corrected by what its
predecessors needed), :func:`_settle` (chord steps with a kept factorization, Newton steps where they
converge slowly, the residual check) and :func:`to_x`, the transferable states in a block's spring bases.
The spring bases S and D come per point (n, ...) or once for all points (1, ...): constant compliances.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import nonlinear_block
from .nonlinear_kernel import _check, _rhs, linearize_ws, workspace_lin


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
        linearize_ws(tab, pt, zi, Pi, False, g, G, Hs, wl)
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
            linearize_ws(tab, pt, zi, Pi, True, g, G, Hs, wl)
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
