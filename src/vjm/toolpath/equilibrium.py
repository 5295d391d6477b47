"""Nonlinear equilibria along a path, warm-started from the neighbouring point.

The same equations and Newton step as :func:`vjm.stiffness.nonlinear.deflection_map` (which stays
the reference and the cold start), organised for a sequence of nearby (pose, wrench) pairs:

* a block of points is cut into ``SEGMENTS`` runs of consecutive points; the first point of
  each run is solved cold (Newton from the unloaded posture), and every other point starts
  from its predecessor's equilibrium (spring deformations in the
  chain variables, platform displacement, chain wrenches), all runs advancing together;
* from a warm start, Newton steps under the full load until the point's residual passes
  the check below (typically one step: the path moves the equilibrium by a small fraction
  of a deflection between two samples), at most ``WARM_STEPS``; a point still failing is
  solved by :func:`vjm.stiffness.nonlinear.deflection_map` (load steps if needed) and counted;
* the compensation's check equilibria start from the deflection's equilibrium at the same
  point (``start=``): the commanded pose differs from the programmed one by a deflection (the
  compiled path adds the correction the points before needed, :func:`vjm.stiffness.nonlinear_kernel.march`);
* a spring coordinate that is rigid at a point (no Newton step moves it) starts at rest, whatever
  its neighbour's deformation.

Every equilibrium reached by these Newton steps (warm, or cold from the unloaded posture) passes
the residual check before it is accepted; a point handed to the reference solver is accepted by
that solver's own, stricter test (its Newton step below 1e-11 of the pose).  The check is relative
to each equation block's own scale (``RTOL``): the springs' balance against the spring forces, the platform's balance
against the applied wrench and the chain wrenches (moments over the machine's length), the
loop closure against the platform's deflection (plus a round-off floor of the machine's
size).  Rows where no equilibrium was found are NaN, as in ``deflection_map(strict=False)``.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..kinematics.transforms import elementary, rotation_vector
from ..stiffness import nonlinear as nl

#: relative residual of every equation block at an accepted equilibrium
RTOL = 1e-5
#: runs of consecutive points per block, each started cold at its first point
SEGMENTS = 128
#: pairs solved together from given starts (their KKT matrices: ~45 kB each on the 3-PUU)
BATCH = 256
#: Newton steps from a warm start before the point is solved cold
WARM_STEPS = 3
#: use the compiled kernels (:mod:`vjm.stiffness.nonlinear_kernel`) where numba is installed; False: the numpy path
KERNEL = True
#: ... on blocks of at least this many points (a short path does not wait for the kernel's compilation
#: or its load from the cache, ~1 s)
KERNEL_MIN = 1000


@functools.cache
def _kernel():
    """The compiled runs of Newton steps (:mod:`vjm.stiffness.nonlinear_kernel`), or None without numba (the numpy
    path)."""
    try:
        from ..stiffness import nonlinear_kernel
    except ImportError:  # pragma: no cover - numba is a dependency
        return None
    return nonlinear_kernel


@dataclass(frozen=True)
class Solved:
    """Platform twists (n, 6) (NaN where not found), the transferable states (n, ns) and the counts:
    cold starts (first points of the runs and warm starts that failed), points that needed the
    reference solver (``warm_failed``), Newton steps (full: a new factorization)."""

    twist: np.ndarray
    state: np.ndarray
    cold: int
    warm_failed: int
    newton: int
    #: chord steps (the compiled path: a kept factorization of an earlier point's Newton matrix)
    chord: int = 0


def _to_x(chains, dv):
    """Unknowns x (n, nx) of the chains' bases whose chain-variable deformation is ``dv`` (n, sum n_vars)."""
    out, col = [], 0
    for cd in chains:
        nv = cd.S.shape[2]
        S = cd.S
        rhs = np.einsum("nmv,nv->nm", S, dv[:, col:col + nv])
        out.append(np.linalg.solve(S @ np.swapaxes(S, 1, 2), rhs[:, :, None])[:, :, 0])
        col += nv
    return np.concatenate(out, axis=1)


def _to_dv(chains, x):
    out, col = [], 0
    for cd in chains:
        m = cd.S.shape[1]
        out.append(np.einsum("nm,nmv->nv", x[:, col:col + m], cd.S))
        col += m
    return np.concatenate(out, axis=1)


def _twist(u):
    """Platform twists (n, 6) of platform displacements u (translation, angles of ``Rx Ry Rz``)."""
    R = elementary("rx", u[:, 3])[:, :3, :3] @ elementary("ry", u[:, 4])[:, :3, :3] \
        @ elementary("rz", u[:, 5])[:, :3, :3]  # nl.platform_rotation without its derivatives
    return np.concatenate([u[:, :3], rotation_vector(R)], axis=1)


def residual_ok(chains, z, W, P, kappa, x_rest, nx, lref, rtol=RTOL) -> np.ndarray:
    """(n,) bool: the equilibrium equations hold at ``z`` (x, u, lam) to ``rtol`` of each block's scale."""
    x, u, lam = z[:, :nx], z[:, nx:nx + 6], z[:, nx + 6:]
    g, G = nl._linearize(chains, x, u, lam, P, hessian=False)[:2]
    fs = kappa * (x - x_rest)
    Gl = np.einsum("nci,nc->ni", G, lam)
    rx = fs - Gl[:, :nx]
    ru = -W - Gl[:, nx:]
    amax = lambda a: np.max(np.abs(a), axis=1, initial=0.0)  # noqa: E731
    f_scale = amax(W[:, :3]) + amax(W[:, 3:]) / lref + amax(lam.reshape(len(z), -1, 6)[:, :, :3].reshape(len(z), -1))
    ok = amax(rx) <= rtol * np.maximum(amax(fs), amax(Gl[:, :nx]))
    ok &= amax(ru[:, :3]) <= rtol * f_scale
    ok &= amax(ru[:, 3:]) <= rtol * f_scale * lref
    gp = g.reshape(len(z), -1, 6)
    ok &= amax(gp[:, :, :3].reshape(len(z), -1)) <= rtol * amax(u[:, :3]) + nl.ROUNDOFF * lref
    ok &= amax(gp[:, :, 3:].reshape(len(z), -1)) <= rtol * amax(u[:, 3:]) + nl.ROUNDOFF
    return ok & np.all(np.isfinite(z), axis=1)


class _Block:
    """The chains and equation data of one block of points (``nonlinear._setup``)."""

    def __init__(self, model, P, W, offsets):
        self.model, self.P_in, self.offsets = model, P, offsets
        self.P, self.chains = nl._setup(model, P, offsets)
        self.W = np.asarray(W, dtype=float)
        self.nx = sum(cd.S.shape[1] for cd in self.chains)
        self.nc = 6 * len(self.chains)
        self.kappa = np.concatenate([cd.kappa for cd in self.chains], axis=1)
        self.fixed = np.concatenate([cd.fixed for cd in self.chains], axis=1)
        self.x_rest = np.concatenate([cd.x0 for cd in self.chains], axis=1)
        self.kd = np.where(self.fixed, 1.0, self.kappa)
        self.lref = max([float(np.max(np.abs(self.P)))] + [float(np.max(np.abs(f.T[:3, 3])))
                                                           for cd in self.chains for f in cd.chain.factors
                                                           if f.kind == "const"])

    def cold(self, idx):
        """Equilibria of points idx by the reference solver; returns (twists, x-states)."""
        if idx.size > BATCH:
            parts = [self.cold(idx[a:a + BATCH]) for a in range(0, idx.size, BATCH)]
            return np.vstack([p[0] for p in parts]), np.vstack([p[1] for p in parts])
        off = None if self.offsets is None else {k: np.asarray(v)[idx] if np.ndim(v) == 3 else v
                                                 for k, v in self.offsets.items()}
        t, info = nl.deflection_map(self.model, self.P_in[idx], self.W[idx], strict=False, offsets=off,
                                    return_info=True)
        return t, info["state"]

    def warm(self, idx, z):
        """Newton from states z (x, u, lam) of points idx until the residual check passes; returns
        (z, passed (k,) bool, Newton steps)."""
        ch = [cd.take(idx) for cd in self.chains]
        W, P, kap, xr = self.W[idx], self.P[idx], self.kappa[idx], self.x_rest[idx]
        # a spring coordinate that is rigid at this point stays at rest: no Newton step moves it (its
        # column is not in the equations), so a deformation carried over from a neighbour would stay
        z[:, :self.nx] = np.where(self.fixed[idx], xr, z[:, :self.nx])
        ok = np.zeros(len(idx), bool)
        steps = 0
        for _ in range(WARM_STEPS):
            a = np.flatnonzero(~ok)
            if a.size == 0:
                break
            cha = ch if a.size == len(idx) else [cd.take(a) for cd in ch]
            dz = nl._newton_step(cha, z[a], np.ones(a.size), W[a], P[a], kap[a], self.kd[idx][a], xr[a],
                                 self.nx, self.nc)
            z[a] = z[a] + np.where(np.isfinite(dz), dz, np.nan)
            steps += a.size
            ok[a] = residual_ok(cha, z[a], W[a], P[a], kap[a], xr[a], self.nx, self.lref)
        return z, ok, steps


def equilibria(model, P, W, offsets=None, start=None) -> Solved:
    """Nonlinear platform twists (n, 6) of consecutive path points P under platform wrenches W (n, 6).

    ``start``: states (n, ns) of a previous call at nearby poses (same order) to start every point
    from; without it, the points are marched in runs (see the module docstring).
    ``offsets`` as in :func:`vjm.stiffness.nonlinear.deflection_map`.
    """
    b = _Block(model, np.asarray(P, dtype=float), W, offsets)
    kern = _kernel() if KERNEL and len(b.P) >= KERNEL_MIN and not any(cd.loads for cd in b.chains) else None
    if kern is not None:
        return _compiled(b, kern, start)
    n = len(b.P)
    nz = b.nx + 6 + b.nc
    z = np.zeros((n, nz))
    twist = np.full((n, 6), np.nan)
    cold = failed = newton = 0
    trivial = np.all(b.W == 0.0, axis=1) & np.all(b.x_rest == 0.0, axis=1)
    twist[trivial] = 0.0

    def settle(idx, z_idx, counted=False):
        nonlocal failed, newton, cold
        zz, ok, k = b.warm(idx, z_idx)
        newton += k
        z[idx] = zz
        twist[idx[ok]] = _twist(zz[ok, b.nx:b.nx + 6])
        bad = idx[~ok]
        if bad.size:  # the reference solver, with load steps if needed
            failed += bad.size
            cold += 0 if counted else bad.size
            t, zc = b.cold(bad)
            z[bad] = zc
            twist[bad] = t

    if start is not None:
        todo = np.flatnonzero(~trivial)
        for a in range(0, todo.size, BATCH):  # KKT matrices of BATCH pairs at a time
            idx = todo[a:a + BATCH]
            zs = np.asarray(start, dtype=float)[idx]
            nv = zs.shape[1] - 6 - b.nc
            ch = [cd.take(idx) for cd in b.chains]
            settle(idx, np.concatenate([_to_x(ch, zs[:, :nv]), zs[:, nv:]], axis=1))
    else:
        L = max(1, -(-n // SEGMENTS))
        heads = np.arange(0, n, L)
        h = heads[~trivial[heads]]
        if h.size:  # cold: Newton from the unloaded posture (its first step is the linear solution)
            cold += h.size
            settle(h, np.zeros((h.size, nz)), counted=True)
        for j in range(1, L):
            idx = heads + j
            idx = idx[idx < n]
            idx = idx[~trivial[idx]]
            if idx.size == 0:
                continue
            prev = idx - 1
            ch_p = [cd.take(prev) for cd in b.chains]
            ch_i = [cd.take(idx) for cd in b.chains]
            dv = _to_dv(ch_p, z[prev, :b.nx])
            settle(idx, np.concatenate([_to_x(ch_i, dv), z[prev, b.nx:]], axis=1))
    state = np.concatenate([_to_dv(b.chains, z[:, :b.nx]), z[:, b.nx:]], axis=1)
    return Solved(twist, state, cold, failed, newton)


def _pack(b: _Block):
    """The block's chains as the arrays of :mod:`vjm.stiffness.nonlinear_kernel`: the factor tables (padded to the
    longest chain) and, per point, the chain data of ``nonlinear._ChainData`` (padded likewise; the spring
    bases S and D once for all points where every chain's are the same at every point)."""
    from ..kinematics.transforms import KINDS

    ch = b.chains
    n, nch = len(b.P), len(ch)
    nf = np.array([len(cd.chain.factors) for cd in ch], np.int64)
    mk = np.array([cd.S.shape[1] for cd in ch], np.int64)
    nv = max(cd.S.shape[2] for cd in ch)
    nJ = np.array([cd.D.shape[2] for cd in ch], np.int64)
    code = np.full((nch, nf.max()), len(KINDS), np.int64)
    var = np.zeros((nch, nf.max()), np.int64)
    coef = np.zeros((nch, nf.max()))
    Tc = np.zeros((nch, nf.max(), 4, 4))
    jof = np.full((nch, nf.max()), -1, np.int64)
    v0 = np.zeros((n, nch, nv))
    R0 = np.zeros((n, nch, 3, 3))
    ns = 1 if all(cd.constant for cd in ch) else n  # one spring basis for every point (constant compliances)
    S = np.zeros((ns, nch, mk.max(), nv))
    D = np.zeros((ns, nch, mk.max(), nJ.max()))
    for k, cd in enumerate(ch):
        for f, fac in enumerate(cd.chain.factors):
            if fac.kind == "const":
                Tc[k, f] = fac.T
            else:
                code[k, f], var[k, f], coef[k, f] = KINDS.index(fac.kind), fac.var, fac.coef
        jof[k, list(cd.joints)] = np.arange(len(cd.joints))
        v0[:, k, :cd.S.shape[2]] = cd.v0
        R0[:, k] = cd.R0
        S[:, k, :mk[k], :cd.S.shape[2]] = cd.S[:ns]
        D[:, k, :mk[k], :nJ[k]] = cd.D[:ns]
    col = np.concatenate([[0], np.cumsum(mk)[:-1]]).astype(np.int64)
    tab = (code, var, coef, Tc, jof, nf, mk, nJ, col)
    c = np.ascontiguousarray
    return tab, (v0, R0, S, D, c(b.fixed), c(b.kappa, dtype=float), c(b.kd, dtype=float),
                 c(b.x_rest, dtype=float), c(b.W, dtype=float), c(b.P[:, :3], dtype=float))


def _compiled(b: _Block, kern, start) -> Solved:
    """:func:`equilibria` by the compiled kernels: the same starts, Newton steps, residual check and
    reference fallback as the numpy path, point by point."""
    n = len(b.P)
    nz = b.nx + 6 + b.nc
    z = np.zeros((n, nz))
    trivial = np.all(b.W == 0.0, axis=1) & np.all(b.x_rest == 0.0, axis=1)
    tab, data = _pack(b)
    given = np.zeros(n, bool)
    if start is not None:  # one run: every point from its given start, in order (a factorization kept)
        idx_all = np.flatnonzero(~trivial)
        vcol = np.cumsum([0] + [cd.S.shape[2] for cd in b.chains]).astype(np.int64)
        kern.to_x(tab, data[2], np.ascontiguousarray(start, dtype=float), idx_all, vcol, z, b.nx)
        given[idx_all] = True
        pos, end, cold = np.zeros(1, np.int64), np.full(1, n, np.int64), 0
    else:
        L = max(1, -(-n // SEGMENTS))
        pos = np.arange(0, n, L)
        end = np.minimum(pos + L, n)
        given[pos] = True
        cold = int(np.count_nonzero(~trivial[pos]))  # run heads: Newton from the unloaded posture
    ok = np.zeros(n, bool)
    steps = np.zeros((pos.size, 2), np.int64)
    twist = np.full((n, 6), np.nan)
    failed = 0
    heads = set(pos.tolist()) if start is None else set()
    while True:
        kern.march(tab, *data[:5], data[5], data[6], data[7], data[8], data[9], trivial, z, pos, end, given,
                   WARM_STEPS, b.lref, RTOL, nl.ROUNDOFF, ok, steps)
        stop = np.flatnonzero(pos < end)
        if stop.size == 0:
            break
        bad = pos[stop]  # the reference solver, with load steps if needed
        failed += bad.size
        cold += sum(1 for i in bad.tolist() if i not in heads)
        twist[bad], z[bad] = b.cold(bad)
        pos[stop] += 1
    good = ok & ~trivial
    twist[good] = _twist(z[good, b.nx:b.nx + 6])
    twist[trivial] = 0.0
    state = np.concatenate([_to_dv(b.chains, z[:, :b.nx]), z[:, b.nx:]], axis=1)
    return Solved(twist, state, cold, failed, int(steps[:, 0].sum()), int(steps[:, 1].sum()))
