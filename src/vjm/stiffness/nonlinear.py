"""Nonlinear static equilibrium of a VJM model under a platform wrench (finite rotations).

Independent of the linear solver: no Jacobian from :mod:`vjm.kinematics.chain`, no
bordered system, nothing from :mod:`vjm.stiffness.linear`.  Unknowns are every free
joint coordinate of every chain (virtual springs, actuator spring
``theta0``, passive joints) and the platform pose ``(p, phi)`` with
``R = Rx(phi1) Ry(phi2) Rz(phi3) R0``.  The equilibrium is the stationary
point of

    Pi = sum_s 1/2 theta_s^T K_s theta_s  -  F . (p - p0)  -  M . phi

subject to loop closure: each chain's end frame, the full nonlinear product
of eq. 1, coincides with the platform frame.  The dead-load moment's work
``M . phi`` differs from the exact one by O(phi^2), an even term that
central differences in the load cancel.

Method: Newton's method on the Lagrange (KKT) conditions with the exact
Hessian of the Lagrangian, batched over all (pose, wrench) pairs (stacked
KKT matrices, one ``np.linalg.solve`` per iteration, a convergence mask per
pair).  Derivatives of the chain product are exact and written here: if
``X_f`` is the world twist matrix of joint factor ``f`` (``F_f G_f F_f^-1``,
``F_f`` the frame just after the factor), then ``dT/da_f = X_f T`` and, for
``f`` proximal to (or equal to) ``h``, ``d2T/da_f da_h = X_f X_h T``; the
closure residual is linear in ``T``, so these give the constraint gradients
and their curvature (tests check them against complex-step derivatives of
:func:`vjm.kinematics.chain.forward`).  A pair whose Newton iteration does not converge
under the full load is continued from the unloaded posture by load steps,
halving the step on failure; pairs that still fail are reported (VjmError
naming the poses, or a per-pair flag with ``strict=False``), never returned
silently wrong.

Springs are those of the model at the unloaded posture (the actuator
compliance at the nominal q; a parallelogram leg keeps its equivalent
spring of that posture).  A spring's coordinates are restricted to the range
of its compliance ``C``: the energy there is ``theta^T C^+ theta`` and a
direction where ``C`` is zero is held rigid.  This matters for the
parallelogram, whose ``C`` is zero along its own mobility: that motion is
carried, exactly, by the passive coupled joint ``Ry(q) Tx(L) Ry(-q)``; a
second, straight-line copy of it inside the spring would be a spurious
zero-energy mechanism at finite displacements.  The platform's deflection
returned is ``(p - p0, rotation vector of R R0^T)``, world axes, mm and rad.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from linkfea.mechanics.frames import skew as _skew

from ..errors import EquilibriumError, VjmError
from ..kinematics.chain import Chain, end_frames
from ..kinematics.poses import Kinematics, as_poses
from ..kinematics.transforms import AXIS, ROTATION, elementary, generator, rotation_vector, vee

#: relative eigenvalue below which a (scaled) spring compliance direction is held rigid
RIGID_RTOL = 1e-12
#: largest change of a rotational joint coordinate in one Newton step, rad (damping far from the solution)
MAX_ROT_STEP = 0.3
#: smallest load increment of the continuation before a pair is declared failed
MIN_LOAD_STEP = 1.0 / 1024
#: round-off floor of a Newton step: 1e3 ulps of the machine's length (mm) or of 1 rad
ROUNDOFF = 1e3 * np.finfo(float).eps


def platform_rotation(phi):
    """``Rx(phi1) Ry(phi2) Rz(phi3)`` (n, 3, 3) and its first (n, 3, 3, 3) and second
    (n, 3, 3, 3, 3) derivatives with respect to ``phi`` (n, 3)."""
    phi = np.atleast_2d(phi)
    A = [elementary(k, phi[:, i])[:, :3, :3] for i, k in enumerate(("rx", "ry", "rz"))]
    G = [generator(k)[:3, :3] for k in ("rx", "ry", "rz")]

    def prod(order):
        M = A[0] @ np.linalg.matrix_power(G[0], order[0]) if order[0] else A[0]
        for i in (1, 2):
            B = A[i] @ np.linalg.matrix_power(G[i], order[i]) if order[i] else A[i]
            M = M @ B
        return M

    e = np.eye(3, dtype=int)
    D1 = np.stack([prod(e[i]) for i in range(3)], axis=1)
    D2 = np.stack([np.stack([prod(e[i] + e[j]) for j in range(3)], axis=1) for i in range(3)], axis=1)
    return prod((0, 0, 0)), D1, D2


@dataclass(frozen=True)
class _ChainData:
    """One chain over n pairs: the unknowns ``x`` (m of them) move the chain variables as
    ``v = v0 + x @ S``; the elastic energy is ``1/2 sum kappa x^2``; ``fixed`` coordinates
    (rigid directions of a spring) stay at zero."""

    chain: Chain
    v0: np.ndarray      # (n, n_vars)
    R0: np.ndarray      # (n, 3, 3) end orientation at v0
    S: np.ndarray       # (n, m, n_vars)
    kappa: np.ndarray   # (n, m), 0 for passive joints and fixed coordinates
    fixed: np.ndarray   # (n, m) bool
    D: np.ndarray       # (n, m, n_joints): d(joint factor angle)/dx
    joints: tuple       # factor indices of the non-constant factors
    x0: np.ndarray      # (n, m) rest values of x: imposed spring deformations (0 without offsets)
    loads: tuple = ()   # body loads: (factor index, point (n, 3) in the frame after it, world force (n, 3))

    def take(self, idx):
        return _ChainData(self.chain, self.v0[idx], self.R0[idx], _rows(self.S, idx), self.kappa[idx],
                          self.fixed[idx], _rows(self.D, idx), self.joints, self.x0[idx],
                          tuple((i, c[idx], f[idx]) for i, c, f in self.loads))

    @property
    def constant(self) -> bool:
        """The spring basis S and D are the same at every pose (views over the poses)."""
        return self.S.strides[0] == 0


def _rows(a, idx):
    """a[idx] (indices, a mask or a slice); a view over the new poses where ``a`` is one row at every pose."""
    if a.strides[0] == 0 and a.shape[0]:
        return np.broadcast_to(a[:1], (np.arange(a.shape[0])[idx].size,) + a.shape[1:])
    return a[idx]


def _spring_basis(C):
    """Basis (n, k, k), stiffnesses (n, k) and rigid mask (n, k) of springs with compliances C (n, k, k).

    Eigen-decomposition of the diagonally scaled compliance (unit-independent):
    ``C = s E diag(c) E^T s``; coordinates ``theta = s E xi`` carry the energy
    ``1/2 sum xi^2 / c`` (= ``theta^T C^+ theta``); directions with ``c ~ 0`` are rigid.
    """
    if len(C) > 1 and np.array_equal(C, np.broadcast_to(C[:1], C.shape)):  # one spring at every pose (a link)
        B, kappa, rigid = _spring_basis(C[:1])
        n = len(C)
        return (np.broadcast_to(B, (n,) + B.shape[1:]), np.broadcast_to(kappa, (n,) + kappa.shape[1:]),
                np.broadcast_to(rigid, (n,) + rigid.shape[1:]))
    d = np.einsum("nii->ni", C)
    s = np.sqrt(np.where(d > 0, d, 1.0))
    Cs = C / (s[:, :, None] * s[:, None, :])
    Cs = np.where((d[:, :, None] > 0) & (d[:, None, :] > 0), Cs, 0.0)
    c, E = np.linalg.eigh(0.5 * (Cs + np.swapaxes(Cs, 1, 2)))
    rigid = c <= RIGID_RTOL * np.maximum(c.max(axis=1, keepdims=True), 1e-300)
    kappa = np.where(rigid, 0.0, 1.0 / np.where(rigid, 1.0, c))
    return s[:, :, None] * E, kappa, rigid


def _rest_coordinates(ch, name, theta0, B, rigid, n):
    """Spring ``name``'s imposed deformation ``theta0`` (n, k) in its energy coordinates ``xi = B^-1 theta``."""
    k = B.shape[1]
    try:
        th = np.broadcast_to(np.asarray(theta0, dtype=float), (n, k))
    except ValueError:
        raise VjmError(f"offsets[{name!r}] of chain {ch.name!r} must have shape ({n}, {k}) or ({k},), "
                       f"got {np.shape(theta0)}") from None
    xi = np.linalg.solve(B, th[:, :, None])[:, :, 0]
    if np.any(np.abs(xi[rigid]) > 1e-12 * np.abs(xi).max(initial=0.0)):
        raise VjmError(f"offsets[{name!r}] of chain {ch.name!r} deforms a direction in which the spring is rigid")
    return np.where(rigid, 0.0, xi)


def _setup(model, P, offsets=None, body_loads=None):
    """The chains' unknowns, springs and nominal values at poses P (or a Kinematics); returns (points, chains).

    ``offsets``: {spring name: (n, n_chains, k) or broadcastable} rest deformations of springs.
    ``body_loads``: per chain, a list of (factor index, point, force): see :func:`deflection_map`."""
    kin = model.kinematics(P)
    P = kin.points
    n = P.shape[0]
    offsets = dict(offsets or {})
    unknown = set(offsets) - {s.name for ch in kin.chains for s in ch.springs}
    if unknown:
        raise VjmError(f"offsets name springs the model does not have: {sorted(unknown)}")
    out = []
    for ci, (ch, v, cdict) in enumerate(zip(kin.chains, kin.values, model.compliances(kin))):
        v = np.asarray(v, dtype=float).reshape(n, ch.n_vars)
        blocks = []  # (vars, basis (n,k,k), kappa (n,k), fixed (n,k), rest xi (n,k))
        for s in ch.springs:
            C = cdict.get(s.name)
            k = len(s.vars)
            if C is None:
                if s.name in offsets:
                    raise VjmError(f"offsets[{s.name!r}]: the spring is rigid in chain {ch.name!r}")
                continue  # rigid link: its coordinates stay at their nominal values
            C = np.broadcast_to(np.asarray(C, dtype=float).reshape(-1, k, k), (n, k, k))
            B, kap, fx = _spring_basis(C)
            x0 = np.zeros((n, k))
            if s.name in offsets:
                th = np.asarray(offsets[s.name], dtype=float)
                if th.ndim not in (2, 3) or th.shape[-2] != len(kin.chains):
                    raise VjmError(f"offsets[{s.name!r}] must have shape (n, {len(kin.chains)}, k) or "
                                   f"({len(kin.chains)}, k): one row per chain, got {th.shape}")
                x0 = _rest_coordinates(ch, s.name, th[..., ci, :], B, fx, n)
            blocks.append((list(s.vars), B, kap, fx, x0))
        for j in ch.passive:
            blocks.append(([j], np.broadcast_to(1.0, (n, 1, 1)), np.zeros((n, 1)), np.zeros((n, 1), bool),
                           np.zeros((n, 1))))
        m = sum(len(b[0]) for b in blocks)
        # springs of the same compliance at every pose (links, actuators): one basis S and one D, as
        # read-only views over the poses, instead of n copies
        ns = 1 if n and all(b[1].strides[0] == 0 for b in blocks) else n
        S = np.zeros((ns, m, ch.n_vars))
        kappa = np.zeros((n, m))
        fixed = np.zeros((n, m), bool)
        rest = np.zeros((n, m))
        row = 0
        for vars_, B, kap, fx, x0 in blocks:
            k = len(vars_)
            S[:, row:row + k, vars_] = np.swapaxes(B[:ns], 1, 2)  # d theta_v / d xi_j = B[v, j]
            kappa[:, row:row + k] = kap
            fixed[:, row:row + k] = fx
            rest[:, row:row + k] = x0
            row += k
        joints = tuple(i for i, f in enumerate(ch.factors) if f.kind != "const")
        Fm = np.zeros((ch.n_vars, len(joints)))
        for jj, i in enumerate(joints):
            Fm[ch.factors[i].var, jj] += ch.factors[i].coef
        D = S @ Fm
        if ns < n:
            S, D = np.broadcast_to(S, (n,) + S.shape[1:]), np.broadcast_to(D, (n,) + D.shape[1:])
        R0 = np.ascontiguousarray(end_frames(ch, v)[:, :3, :3]) if n else np.zeros((0, 3, 3))
        loads = _body_loads(ch, (body_loads or [()] * len(kin.chains))[ci], n)
        out.append(_ChainData(ch, v, R0, S, kappa, fixed, D, joints, rest, loads))
    return P, out


def _body_loads(ch: Chain, loads, n: int) -> tuple:
    """A chain's body loads as (factor index, point (n, 3), force (n, 3)), checked."""
    out = []
    for i, c, f in loads:
        if not 0 <= int(i) < len(ch.factors):
            raise VjmError(f"body load on factor {i} of chain {ch.name!r}, which has {len(ch.factors)}")
        c = np.array(np.broadcast_to(np.asarray(c, dtype=float), (n, 3)))
        f = np.array(np.broadcast_to(np.asarray(f, dtype=float), (n, 3)))
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(f))):
            raise VjmError(f"body loads of chain {ch.name!r} must be finite numbers")
        out.append((int(i), c, f))
    return tuple(out)


def _loaded(chains, n: int) -> np.ndarray:
    """Pairs (n,) with a non-zero body load."""
    out = np.zeros(n, bool)
    for cd in chains:
        for _, _, f in cd.loads:
            out |= np.any(f != 0.0, axis=1)
    return out


def _cross(a, b):
    """Row-wise cross product of (n, 3) arrays (np.cross's axis handling costs more than the arithmetic)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _chain_kinematics(cd: _ChainData, x, keep=()):
    """End frames T (n, 4, 4), joint twist matrices X (n, nJ, 4, 4) and dT = X T (n, nJ, 4, 4);
    with ``keep`` (factor indices), also {index: the frame just after that factor}."""
    ch = cd.chain
    v = cd.v0 + np.einsum("nm,nmv->nv", x, cd.S)
    n = v.shape[0]
    F = np.broadcast_to(np.eye(4), (n, 4, 4))
    X = np.zeros((n, len(cd.joints), 4, 4))
    kept = {}
    jj = 0
    for fi, f in enumerate(ch.factors):
        if f.kind == "const":
            F = F @ f.T
            if fi in keep:
                kept[fi] = F
            continue
        F = F @ elementary(f.kind, f.coef * v[:, f.var])
        e = F[:, :3, AXIS[f.kind]]
        if ROTATION[f.kind]:  # world twist of a revolute factor: omega = e, v = o x e
            X[:, jj, :3, :3] = _skew(e)
            X[:, jj, :3, 3] = _cross(F[:, :3, 3], e)
        else:
            X[:, jj, :3, 3] = e
        if fi in keep:
            kept[fi] = F
        jj += 1
    return (F, X, X @ F[:, None], kept) if keep else (F, X, X @ F[:, None])


def _body_terms(cd: _ChainData, X, kept, hessian: bool):
    """Gradient (n, m) and Hessian (n, m, m) of the body loads' work ``sum F . p(x)``.

    A point ``p`` fixed after factor ``i`` moves with the joint factors ``f <= i`` as
    ``dp/da_f = X_f p`` and ``d2p/da_f da_h = X_f X_h p`` (``f`` proximal to ``h``)."""
    n, nJ = X.shape[0], X.shape[1]
    gf = np.zeros((n, nJ))
    Q = np.zeros((n, nJ, nJ))
    jidx = np.asarray(cd.joints)
    for i, c, force in cd.loads:
        Fi = kept[i]
        p = np.einsum("nij,nj->ni", Fi[:, :3, :3], c) + Fi[:, :3, 3]
        on = (jidx <= i).astype(float)  # the joint factors proximal to the point
        dp = (np.einsum("nfij,nj->nfi", X[:, :, :3, :3], p) + X[:, :, :3, 3]) * on[None, :, None]
        gf += np.einsum("nfi,ni->nf", dp, force)
        if hessian:
            A = np.einsum("nfji,nj->nfi", X[:, :, :3, :3], force) * on[None, :, None]
            Q += A @ np.swapaxes(dp, 1, 2)  # Q[f, h] = F . (w_f x dp_h), valid for f <= h
    Dm = np.where(cd.fixed[:, :, None], 0.0, cd.D)
    Hb = None
    if hessian:
        Hf = np.triu(Q) + np.swapaxes(np.triu(Q, 1), 1, 2)
        Hb = Dm @ Hf @ np.swapaxes(Dm, 1, 2)
    return np.einsum("nmf,nf->nm", Dm, gf), Hb


def _linearize(chains, x, u, lam, p0, hessian=True):
    """Closure residual g (n, nc), its gradient G (n, nc, nx + 6) and, with ``hessian``,
    the Hessian of ``lam . g`` (n, nx + 6, nx + 6), at unknowns x (n, nx), u (n, 6); then the
    gradient (n, nx) and Hessian (n, nx, nx) of the body loads' work (None without body loads)."""
    n = x.shape[0]
    nx = x.shape[1]
    nc = 6 * len(chains)
    Rxyz, D1, D2 = platform_rotation(u[:, 3:])
    g = np.zeros((n, nc))
    G = np.zeros((n, nc, nx + 6))
    Hs = np.zeros((n, nx + 6, nx + 6)) if hessian else None
    loaded = any(cd.loads for cd in chains)
    gB = np.zeros((n, nx)) if loaded else None
    HB = np.zeros((n, nx, nx)) if loaded and hessian else None
    col = 0
    for k, cd in enumerate(chains):
        m = cd.S.shape[1]
        xs = slice(col, col + m)
        rows = slice(6 * k, 6 * k + 6)
        if cd.loads:
            T, X, dT, kept = _chain_kinematics(cd, x[:, xs], {i for i, _, _ in cd.loads})
            gB[:, xs], Hb = _body_terms(cd, X, kept, hessian)
            if hessian:
                HB[:, xs, xs] = Hb
        else:
            T, X, dT = _chain_kinematics(cd, x[:, xs])
        Rp = Rxyz @ cd.R0
        Rc = T[:, :3, :3]
        RcRpT = Rc @ np.swapaxes(Rp, 1, 2)
        g[:, rows] = np.concatenate([T[:, :3, 3] - (p0 + u[:, :3]), vee(RcRpT)], axis=1)
        # gradients: joint factors, then the unknowns through D
        RpT = np.swapaxes(Rp, 1, 2)[:, None]
        Gf = np.concatenate([dT[:, :, :3, 3], vee(dT[:, :, :3, :3] @ RpT)], axis=2)  # (n, nJ, 6)
        Gx = np.swapaxes(cd.D @ Gf, 1, 2)
        Gx[np.broadcast_to(cd.fixed[:, None, :], Gx.shape)] = 0.0
        G[:, rows, xs] = Gx
        G[:, 6 * k:6 * k + 3, nx:nx + 3] = -np.eye(3)
        dRpT = np.swapaxes(D1 @ cd.R0[:, None], 2, 3)  # (n, 3, 3, 3): d Rp^T / d phi_i
        G[:, 6 * k + 3:6 * k + 6, nx + 3:] = np.swapaxes(vee(Rc[:, None] @ dRpT), 1, 2)
        if hessian:
            lp, lr = lam[:, 6 * k:6 * k + 3], lam[:, 6 * k + 3:6 * k + 6]
            # lam . g = <Lam, T[:3]> + const, since l . vee(M) = 1/2 <skew(l), M>
            Sl = 0.5 * _skew(lr)
            Lam = np.concatenate([Sl @ Rp, lp[:, :, None]], axis=2)  # (n, 3, 4)
            nJ = X.shape[1]
            Y = Lam[:, None] @ np.swapaxes(dT, 2, 3)  # (n, nJ, 3, 4): Y_h = Lam dT_h^T
            # Q[f, h] = <Lam, X_f X_h T> = sum_ik X_f[i, k] Y_h[i, k]
            Q = X[:, :, :3, :].reshape(-1, nJ, 12) @ np.swapaxes(Y.reshape(-1, nJ, 12), 1, 2)
            Hf = np.triu(Q) + np.swapaxes(np.triu(Q, 1), 1, 2)  # valid for f <= h, symmetric
            Dm = np.where(cd.fixed[:, :, None], 0.0, cd.D)
            Hs[:, xs, xs] = Dm @ Hf @ np.swapaxes(Dm, 1, 2)
            SlD1 = Sl[:, None] @ D1 @ cd.R0[:, None]  # (n, 3, 3, 3)
            Hxphi = np.einsum("nijk,nfjk->nfi", SlD1, dT[:, :, :3, :3])
            Hxphi = Dm @ Hxphi
            Hs[:, xs, nx + 3:] = Hxphi
            Hs[:, nx + 3:, xs] = np.swapaxes(Hxphi, 1, 2)
            SlD2 = Sl[:, None, None] @ D2 @ cd.R0[:, None, None]
            Hs[:, nx + 3:, nx + 3:] += np.einsum("nijab,nab->nij", SlD2, Rc)
        col += m
    return g, G, Hs, gB, HB


def _solve(A, b):
    """Batched solve after row and column equilibration (units mix mm, rad, N, N mm)."""
    mag = np.abs(A)
    rs = 1.0 / np.maximum(np.max(mag, axis=2), 1e-300)
    As = A * rs[:, :, None]
    cs = 1.0 / np.maximum(np.max(np.abs(As, out=mag), axis=1), 1e-300)
    As *= cs[:, None, :]
    bs = b * rs
    try:
        y = np.linalg.solve(As, bs[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:  # an exactly singular pair: least squares for all (rare)
        y = np.einsum("nij,nj->ni", np.linalg.pinv(As, rcond=1e-14), bs)
    return y * cs


def _describe(P, W, idx):
    rows = [f"p = {np.round(P[i], 4).tolist()} mm under wrench {W[i].tolist()}" for i in idx[:3]]
    more = f" (and {len(idx) - 3} more)" if len(idx) > 3 else ""
    return "; ".join(rows) + more


def deflection_map(model, P, W, tol: float = 1e-11, max_iter: int = 60, return_info: bool = False,
                   strict: bool = True, offsets=None, body_loads=None):
    """Nonlinear platform deflections (n, 6) for points P (n, 3) and wrenches W (n, 6) or (6,).

    All (pose, wrench) pairs are solved together (see the module docstring).

    Parameters
    ----------
    model : vjm Model
    P : (n, 3) end-effector points, mm; for a 6-dof platform (n, 6) poses x, y, z, rx, ry, rz
        or (n, 4, 4) frames (see :func:`vjm.kinematics.poses.as_poses`); or a Kinematics
    W : (n, 6) or (6,) platform wrenches Fx Fy Fz Mx My Mz, N and N mm
    tol : convergence when the Newton step of the platform pose is below ``tol`` x its size
    max_iter : Newton iterations allowed per load increment
    return_info : also return a dict: ``converged`` (n,) bool, ``iterations`` (n,) total Newton
        iterations, ``load_steps`` (n,) load increments used (1 = full load at once),
        ``chain_wrench`` (n, n_chains, 6) closure multipliers (the share of the applied
        wrench each chain carries, world axes at the platform point), ``state`` (n, nx + 6 + 6
        n_chains) the final unknowns (spring coordinates, platform pose, multipliers)
    strict : raise VjmError naming the poses whose equilibrium was not found; with
        ``strict=False`` their rows are NaN and ``info["converged"]`` is False
    offsets : optional {spring name: (n, n_chains, k) or (n_chains, k)} imposed deformations
        of springs (their rest values: a joint's slip in its clearance, an assembly error), rad
        or mm, in the spring's variables; applied together with the load (same ramp).  The
        twist returned is then measured from the unloaded posture *without* the offsets.
        ``info["springs"]`` gives every spring's deformation at equilibrium.
    body_loads : optional, per chain, a list of ``(i, c, F)``: a dead load ``F`` (world axes, N; (3,)
        or (n, 3)) at the point ``c`` (mm) of the frame just after factor ``i`` of the chain, ramped
        with the wrench: a robot's weight (:meth:`vjm.robot.RobotModel.self_weight`).

    Returns
    -------
    (n, 6) twists ``(p - p0, rotation vector)``, mm and rad [, info]
    """
    if not isinstance(P, Kinematics):
        P = as_poses(P, model.dof)
    n = P.n if isinstance(P, Kinematics) else P.shape[0]
    try:
        W = np.array(np.broadcast_to(np.asarray(W, dtype=float), (n, 6)))
    except ValueError:
        raise VjmError(f"wrenches must have shape (6,) or ({n}, 6), got {np.shape(W)}") from None
    if not np.all(np.isfinite(W)):
        raise VjmError("wrenches must be finite numbers")
    P, chains = _setup(model, P, offsets, body_loads)
    nx = sum(cd.S.shape[1] for cd in chains)
    nc = 6 * len(chains)
    kappa = np.concatenate([cd.kappa for cd in chains], axis=1)
    fixed = np.concatenate([cd.fixed for cd in chains], axis=1)
    x_rest = np.concatenate([cd.x0 for cd in chains], axis=1)
    # length scale of the machine for the round-off floor of the convergence test
    lref = max([np.max(np.abs(P))] + [np.max(np.abs(f.T[:3, 3])) for cd in chains for f in cd.chain.factors
                                       if f.kind == "const"])
    kd = np.where(fixed, 1.0, kappa)  # fixed coordinates: a unit diagonal keeps their step at zero

    z = np.zeros((n, nx + 6 + nc))          # current iterate (x, u, lam)
    z_ok = z.copy()                          # last converged load increment
    s_ok = np.zeros(n)                       # its load factor
    ds = np.ones(n)                          # current increment (full load first)
    it_step = np.zeros(n, int)
    iters = np.zeros(n, int)
    steps = np.zeros(n, int)
    prev = np.full(n, np.inf)
    done = np.all(W == 0.0, axis=1) & np.all(x_rest == 0.0, axis=1) & ~_loaded(chains, n)
    failed = np.zeros(n, bool)
    cap = max(1, int(max_iter))
    while True:
        act = np.flatnonzero(~done & ~failed)
        if act.size == 0:
            break
        ch_a = [cd.take(act) for cd in chains]
        za = z[act]
        s = np.minimum(s_ok[act] + ds[act], 1.0)
        dz = _newton_step(ch_a, za, s, W[act], P[act], kappa[act], kd[act], x_rest[act], nx, nc)
        # damping far from the solution: no rotational coordinate turns more than MAX_ROT_STEP
        big = np.maximum(_max_rotation_change(ch_a, dz[:, :nx]), np.max(np.abs(dz[:, nx + 3:nx + 6]), axis=1))
        alpha = np.where(big > MAX_ROT_STEP, MAX_ROT_STEP / np.maximum(big, 1e-300), 1.0)
        finite = np.all(np.isfinite(dz), axis=1)
        dz = np.where(finite[:, None], dz, 0.0)
        z[act] = za + alpha[:, None] * dz
        it_step[act] += 1
        iters[act] += 1
        step = np.max(np.abs(dz[:, nx:nx + 6]), axis=1)
        size = np.max(np.abs(z[act, nx:nx + 6]), axis=1) + 1e-300
        # round-off floor of the closure (a few ulps of the machine's size), mm and rad
        floor = (np.max(np.abs(dz[:, nx:nx + 3]), axis=1) <= ROUNDOFF * lref) & \
            (np.max(np.abs(dz[:, nx + 3:nx + 6]), axis=1) <= ROUNDOFF)
        full = alpha == 1.0
        conv = full & finite & ((step <= tol * size) | (step == 0.0) | floor
                                | ((it_step[act] > 3) & (step < 1e-9 * size) & (step > 0.5 * prev[act])))
        prev[act] = np.where(full, step, np.inf)
        bad = ~finite | (~conv & (it_step[act] >= cap))
        # converged increments: accept, finish or take a larger increment
        ci = act[conv]
        s_ok[ci] = s[conv]
        z_ok[ci] = z[ci]
        steps[ci] += 1
        done[ci] = s_ok[ci] >= 1.0
        ds[ci] = np.minimum(2.0 * ds[ci], 1.0 - s_ok[ci])
        # failed increments: back to the last converged state with a smaller increment
        bi = act[bad]
        z[bi] = z_ok[bi]
        ds[bi] *= 0.25
        failed[bi] = ds[bi] < MIN_LOAD_STEP
        it_step[np.concatenate([ci, bi])] = 0
        prev[np.concatenate([ci, bi])] = np.inf
    u = z[:, nx:nx + 6]
    Rxyz = platform_rotation(u[:, 3:])[0]
    t = np.concatenate([u[:, :3], rotation_vector(Rxyz)], axis=1)
    bad = np.flatnonzero(failed)
    if bad.size:
        if strict:
            raise EquilibriumError(f"nonlinear equilibrium not found for {bad.size} of {n} (pose, wrench) pairs: "
                           f"{_describe(P, W, bad)} (load too large for the model, or past a buckling load?)")
        t[bad] = np.nan
    if return_info:
        info = {"converged": ~failed, "iterations": iters, "load_steps": steps,
                "chain_wrench": z[:, nx + 6:].reshape(n, len(chains), 6),
                "springs": _spring_deformations(chains, z[:, :nx]), "state": z}
        return t, info
    return t


def _newton_step(ch_a, za, s, W, P, kappa, kd, x_rest, nx: int, nc: int) -> np.ndarray:
    """The Newton step of the bordered equilibrium (springs, platform, closure) at iterates ``za``
    (x, u, lam) under the load fraction ``s`` of the wrenches ``W`` and of the imposed offsets."""
    x, u, lam = za[:, :nx], za[:, nx:nx + 6], za[:, nx + 6:]
    w = W * s[:, None]
    g, G, Hs, gB, HB = _linearize(ch_a, x, u, lam, P)
    r = np.concatenate([kappa * (x - s[:, None] * x_rest) - np.einsum("nci,nc->ni", G[:, :, :nx], lam),
                        -w - np.einsum("nci,nc->ni", G[:, :, nx:], lam), g], axis=1)
    N = nx + 6 + nc
    A = np.zeros((len(za), N, N))
    A[:, :nx + 6, :nx + 6] = -Hs
    if gB is not None:  # the body loads' work, ramped with the load: - s F . p(x)
        r[:, :nx] -= s[:, None] * gB
        A[:, :nx, :nx] -= s[:, None, None] * HB
    A[:, np.arange(nx), np.arange(nx)] += kd
    A[:, :nx + 6, nx + 6:] = -np.swapaxes(G, 1, 2)
    A[:, nx + 6:, :nx + 6] = G
    return _solve(A, -r)


def _spring_deformations(chains, x) -> list[dict]:
    """Per chain, {spring name: (n, k) deformation ``theta = v - v0`` of its variables} at unknowns x."""
    out, col = [], 0
    for cd in chains:
        m = cd.S.shape[1]
        dv = np.einsum("nm,nmv->nv", x[:, col:col + m], cd.S)
        out.append({s.name: dv[:, list(s.vars)] for s in cd.chain.springs})
        col += m
    return out


def _max_rotation_change(chains, dx):
    """Largest change (n,) of an angular chain variable for a step dx (n, nx) of the unknowns."""
    out = np.zeros(dx.shape[0])
    col = 0
    for cd in chains:
        m = cd.S.shape[1]
        ang = [f.var for f in cd.chain.factors if f.kind != "const" and ROTATION[f.kind]]
        if ang:
            dv = np.einsum("nm,nmv->nv", dx[:, col:col + m], cd.S[:, :, sorted(set(ang))])
            out = np.maximum(out, np.max(np.abs(dv), axis=1))
        col += m
    return out


def deflection(model, p, wrench, tol: float = 1e-11, max_iter: int = 60, return_info: bool = False):
    """Platform deflection twist (6,) at point ``p`` under ``wrench`` (Fx..Mz, N and N mm).

    Full nonlinear kinematics of every chain; see the module docstring.  The
    same solver as :func:`deflection_map` with one pair.  Raises VjmError
    (naming the pose) if the equilibrium is not found.
    """
    w = np.asarray(wrench, dtype=float).reshape(6)
    t, info = deflection_map(model, np.asarray(p, dtype=float)[None], w[None], tol=tol,
                             max_iter=max_iter, return_info=True)
    if return_info:
        return t[0], {"iterations": int(info["iterations"][0]), "load_steps": int(info["load_steps"][0]),
                      "chain_wrench": info["chain_wrench"][0]}
    return t[0]
