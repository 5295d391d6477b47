"""Numeric inverse kinematics of any chain: batched Newton on its loop closure.

Each chain is solved on its own (in a parallel machine the platform pose fixes
every chain's end frame).  The unknowns are the chain's actuated and passive
coordinates (spring coordinates stay at zero, the rigid posture); the
residual is the end frame's position error (mm) and orientation error
``vee(R_end R_target^T)`` (rad, scaled by the chain's length so both are mm).
Newton's step is the Gauss-Newton step of that 6-vector, which is the exact
Newton step when the chain has 6 coordinates and the least-squares one when
it has fewer (a 3-PUU leg has 5: its closure equations are consistent only
because the target orientation is reachable, and a pose whose residual does
not vanish is unreachable).  The Jacobian is the chain's own (eq. 3-5), the
linear solve a batched Cholesky over poses, pose axis last.

Starting point and continuation: a pose starts from the description's seed
posture, or in a large batch from a near anchor: the poses are ordered along a
Z-order curve, one in ``ANCHOR_EVERY`` is solved from the seed and the others
start from the nearer anchor around them on the curve plus the first-order
change of the coordinates (the seed again where that change exceeds a step's
limit).  A pose whose Newton iteration does not close restarts from the seed,
then is continued along the straight path of poses from the seed pose to it
(``PATH_STEPS`` intermediate poses, each started from the previous solution),
which keeps the solution on the seed's assembly branch; a pose that still does
not close is reported unreachable.

A 6-UPS leg (a U joint, a strut, an S joint) needs none of this: :mod:`vjm.kinematics.closed_form`
solves it without iterating, and Newton only takes the poses it does not close.

Batches of ``COMPILED_FROM`` poses or more run the compiled kernels of
:mod:`vjm.kinematics.ik_kernel` (numba) pose by pose, smaller ones the numpy code below
batched over poses: same steps, same results to round-off.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import closed_form
from .chain import Chain, Factor, _frame_product
from .transforms import AXIS, KINDS, ROTATION, rotation_vector, vee

#: legs of the form of :mod:`vjm.kinematics.closed_form` (a 6-UPS hexapod's) are solved in closed form;
#: False: every chain by Newton (the reference the tests compare with)
CLOSED_FORM = True
#: in a batch, one pose in this many (along a curve through the poses) is solved from the seed
#: and the others start from a near one of them
ANCHOR_EVERY = 16
#: batches of this many poses or more use the compiled kernels (smaller ones need no numba)
COMPILED_FROM = 256
#: Newton iterations from the seed posture, and per intermediate pose of a path
MAX_ITER = 20
#: intermediate poses of the continuation path from the seed pose (the last one is the target)
PATH_STEPS = 8
#: largest change of an angle (rad), or of a length over the chain's size, in one Newton step
MAX_STEP = 0.3
#: closure tolerance relative to the chain's size (orientation errors count times that size)
CLOSE_TOL = 1e-13
#: a full Newton step whose predicted error (quadratic convergence, ten times over) is below this
#: (relative to the chain's size) ends the iteration without measuring again
PREDICT_TOL = 1e-12
#: a pose whose error stops decreasing below this (relative) has reached the round-off floor
STALL_TOL = 1e-10


def chain_size(chain: Chain) -> float:
    """A length scale of the chain (mm): the sum of its constant translations, at least 1."""
    s = sum(float(np.linalg.norm(f.T[:3, 3])) for f in chain.factors if f.kind == "const")
    return max(1.0, s)


def rigid_chain(chain: Chain, unknowns) -> Chain:
    """The chain at its rigid posture, with only the ``unknowns`` as variables (renumbered in
    that order): spring factors (0 there) are dropped and neighbouring constants multiplied
    together, so each Newton iteration touches only the joints it solves for."""
    idx = {v: i for i, v in enumerate(unknowns)}
    factors, T = [], None
    for f in chain.factors:
        if f.kind == "const" or f.var not in idx:
            if f.kind == "const":
                T = f.T if T is None else T @ f.T
            continue
        if T is not None:
            factors.append(Factor("const", T=T))
            T = None
        factors.append(Factor(f.kind, idx[f.var], f.coef))
    if T is not None:
        factors.append(Factor("const", T=T))
    names = tuple(chain.var_names[v] for v in unknowns)
    return Chain(chain.name, tuple(factors), names, tuple(chain.roles[v] for v in unknowns), ())


@functools.cache
def _kernel():
    """The compiled kernels (:mod:`vjm.kinematics.ik_kernel`), or None where numba is not installed
    (then the numpy path below runs: same arithmetic, batched over poses)."""
    try:
        from . import ik_kernel
    except ImportError:
        return None
    return ik_kernel


def encode(chain: Chain):
    """A chain as arrays for :mod:`vjm.kinematics.ik_kernel`: per factor a code (index in ``KINDS``, or
    ``len(KINDS)`` for a constant), the variable, the coefficient and the 4x4 constant."""
    nf = len(chain.factors)
    code = np.array([len(KINDS) if f.kind == "const" else KINDS.index(f.kind) for f in chain.factors],
                    dtype=np.int64).reshape(nf)
    var = np.array([max(f.var, 0) for f in chain.factors], dtype=np.int64).reshape(nf)
    coef = np.array([f.coef for f in chain.factors], dtype=float).reshape(nf)
    T = np.zeros((nf, 4, 4))
    for k, f in enumerate(chain.factors):
        if f.kind == "const":
            T[k] = f.T
    return code, var, coef, T


# the kernels read a code's axis as code % 3 and a rotation as code >= 3
assert all(AXIS[k] == i % 3 and ROTATION[k] == (i >= 3) for i, k in enumerate(KINDS))


def conjugate(S: np.ndarray, frames: np.ndarray, out: np.ndarray) -> None:
    """``out = S^-1 frames S`` for frames (n, 4, 4): the poses a copy ``S chain S^-1`` of a
    chain reaches at ``frames``, as the original chain sees them."""
    kern = _kernel() if frames.shape[0] >= COMPILED_FROM else None
    if kern is None:
        out[:] = np.linalg.inv(S) @ frames @ S
    else:
        kern.conjugate(np.linalg.inv(S), np.ascontiguousarray(S, dtype=float), np.ascontiguousarray(frames, dtype=float),
                       out)


def _step_limits(chain: Chain, U, ell: float) -> np.ndarray:
    """Largest Newton step (MAX_STEP) of each unknown: rad for an angle, times ``ell`` for a length."""
    rot = np.array([any(f.var == u and ROTATION[f.kind] for f in chain.factors if f.kind != "const") for u in U])
    return np.where(rot, MAX_STEP, MAX_STEP * ell)


def _end_and_jacobian(chain: Chain, vt: np.ndarray):
    """End frame columns and Jacobian (n_vars, 6, n) (eq. 3-5) of a chain whose variables are all solved for."""
    cols, recs = _frame_product(chain, vt)
    pe = cols[3]
    J = np.zeros((chain.n_vars, 6, vt.shape[1]))
    for var, kind, coef, e, o in recs:
        if ROTATION[kind]:
            d = pe - o
            J[var, 0] += coef * (e[1] * d[2] - e[2] * d[1])
            J[var, 1] += coef * (e[2] * d[0] - e[0] * d[2])
            J[var, 2] += coef * (e[0] * d[1] - e[1] * d[0])
            J[var, 3:] += coef * e
        else:
            J[var, :3] += coef * e
    return cols, J


def closure_error(chain: Chain, vt: np.ndarray, R: np.ndarray, p: np.ndarray):
    """Position (3, n) and orientation (3, n) errors of the chain's end frame at values ``vt``
    (n_vars, n) against target rotations R (3, 3, n) and points p (3, n); also the Jacobian
    (n_vars, 6, n).  ``chain`` is a :func:`rigid_chain` (every variable solved for)."""
    cols, Jt = _end_and_jacobian(chain, vt)
    ep = cols[3] - p
    # M = R_end R_target^T, only its skew part is needed
    def m(i, j):  # (R_end R_target^T)[i, j]
        return cols[0][i] * R[j, 0] + cols[1][i] * R[j, 1] + cols[2][i] * R[j, 2]

    er = 0.5 * np.stack([m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1)])
    return ep, er, Jt


def _normal_solve(A: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Least-squares solution (k, n) of ``A^T x = r`` for A (k, 6, n), r (6, n): the normal
    equations ``A A^T x = A r`` by a batched Cholesky (pose axis last; a relative 1e-12
    on the diagonal keeps a rank-deficient pose finite)."""
    k = A.shape[0]
    a = [[A[i, c] for c in range(6)] for i in range(k)]   # row views, (n,) each

    def dot(u, v):
        out = u[0] * v[0]
        for c in range(1, len(u)):
            out += u[c] * v[c]
        return out

    rr = [r[c] for c in range(6)]
    L: list[list[Any]] = [[None] * k for _ in range(k)]
    for j in range(k):
        d = dot(a[j], a[j]) * (1.0 + 1e-12)
        for m in range(j):
            d -= L[j][m] * L[j][m]
        L[j][j] = np.sqrt(np.maximum(d, 1e-300))
        inv = 1.0 / L[j][j]
        for i in range(j + 1, k):
            c = dot(a[i], a[j])
            for m in range(j):
                c -= L[i][m] * L[j][m]
            L[i][j] = c * inv
    x: list[Any] = [None] * k
    for i in range(k):
        y = dot(a[i], rr)
        for m in range(i):
            y -= L[i][m] * x[m]
        x[i] = y / L[i][i]
    for i in range(k - 1, -1, -1):
        y = x[i]
        for m in range(i + 1, k):
            y = y - L[m][i] * x[m]
        x[i] = y / L[i][i]
    return np.stack(x)


@dataclass(frozen=True, eq=False)
class Closure:
    """One chain's loop closure, prepared for Newton: its :func:`rigid_chain` on the unknowns,
    the chain's size ``ell`` (mm), each unknown's largest step ``lim`` (k,) and the arrays of
    :func:`encode`.  Values in this space are (k, n): the unknowns only, pose axis last."""

    chain: Chain
    ell: float
    lim: np.ndarray
    code: tuple

    @property
    def k(self) -> int:
        return self.chain.n_vars


def closure(chain: Chain, unknowns) -> Closure:
    """The :class:`Closure` of ``chain`` solved for its variables ``unknowns``."""
    U = list(unknowns)
    ell = chain_size(chain)
    rc = rigid_chain(chain, U)
    return Closure(rc, ell, _step_limits(chain, U, ell), encode(rc))


def newton(cl: Closure, v: np.ndarray, R: np.ndarray, p: np.ndarray, max_iter: int = MAX_ITER,
           compiled: bool = True):
    """Newton on one chain's closure for targets (R, p), from values ``v`` (k, n) of its unknowns.

    Returns the values (k, n), a converged mask (n,) and the final error (n,) mm.  ``compiled``:
    the kernels of :mod:`vjm.kinematics.ik_kernel` where numba is installed, else the numpy path (same steps).
    """
    vt = np.array(v, dtype=float)
    n = vt.shape[1]
    ell = cl.ell
    kern = _kernel() if compiled else None
    if kern is not None:
        ok, err = np.zeros(n, dtype=bool), np.full(n, np.inf)
        kern.newton(*cl.code, vt, np.ascontiguousarray(R, dtype=float), np.ascontiguousarray(p, dtype=float), ell,
                    cl.lim, int(max_iter), CLOSE_TOL, STALL_TOL, PREDICT_TOL, ok, err)
        return vt, ok, err
    chain, lim = cl.chain, cl.lim[:, None]
    ok = np.zeros(n, dtype=bool)
    err = np.full(n, np.inf)
    # working set: poses still iterating (plus finished ones until compacting pays off)
    act, v, Rw, pw = np.arange(n), vt, R, p
    live = np.ones(n, dtype=bool)
    prev = np.full(n, np.inf)
    for it in range(max_iter + 1):
        if not live.any():
            break
        if live.sum() < 0.75 * live.size:
            act, v, Rw, pw, prev = act[live], v[:, live], Rw[:, :, live], pw[:, live], prev[live]
            live = np.ones(act.size, dtype=bool)
        ep, er, Jt = closure_error(chain, v, Rw, pw)
        e = np.maximum(np.max(np.abs(ep), axis=0), ell * np.max(np.abs(er), axis=0))
        # closed to round-off, or no longer improving at the round-off floor
        done = live & ((e <= CLOSE_TOL * ell) | ((e <= STALL_TOL * ell) & (e >= 0.5 * prev)))
        last = it == max_iter
        if last:
            done = live & (e <= STALL_TOL * ell)
        fin = done | (live & last)
        err[act[fin]] = e[fin]
        ok[act[done]] = True
        vt[:, act[fin]] = v[:, fin]
        live &= ~done
        prev2 = prev
        prev = e
        if last or not live.any():
            break
        r = np.concatenate([ep, ell * er])                      # (6, m) mm
        A = Jt
        A[:, 3:] *= ell
        dv = -_normal_solve(A, r)
        big = np.max(np.abs(dv) / lim, axis=0)
        dv *= np.where(big > 1.0, 1.0 / np.where(big > 1.0, big, 1.0), 1.0)
        dv = np.where(np.isfinite(dv) & live, dv, 0.0)
        v = v + dv
        # quadratic convergence: the full step from error e leaves about c e^2, with c measured
        # from the last two errors (at least 10 / ell); ten times that below 1e-12 ell is closed
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            c = e / (prev2 * prev2)
        c = np.where(np.isfinite(c), np.maximum(c, 10.0 / ell), np.inf)
        with np.errstate(invalid="ignore", over="ignore"):
            tiny = live & (big <= 1.0) & (10.0 * c * e * e <= PREDICT_TOL * ell)
        if tiny.any():
            ok[act[tiny]] = True
            err[act[tiny]] = 0.0
            vt[:, act[tiny]] = v[:, tiny]
            live &= ~tiny
    return vt, ok, err


def solve_chain(chain: Chain, unknowns, seed: np.ndarray, seed_frame: np.ndarray, frames: np.ndarray,
                compiled: bool | None = None):
    """Values (n, n_vars) of one chain closing on platform frames (n, 4, 4), from a seed posture.

    ``seed`` (n_vars,) are the chain's values at the platform frame ``seed_frame`` (4, 4); the
    variables other than ``unknowns`` keep their seed values.  A leg of the form of
    :mod:`vjm.kinematics.closed_form` (with ``CLOSED_FORM``) is solved in closed form, the poses it
    does not close by Newton; otherwise direct Newton from the seed, or from a near anchor in a large
    batch; poses left open are continued along the path of poses from the seed frame (see the module
    docstring).  Returns values (n, n_vars), converged mask
    (n,) and closure error (n,) mm.  ``compiled``: use the compiled kernels (default: for
    batches of ``COMPILED_FROM`` poses or more, where they repay loading them).
    """
    n = frames.shape[0]
    if compiled is None:
        compiled = n >= COMPILED_FROM
    U = list(unknowns)
    seed = np.asarray(seed, dtype=float)
    frames = np.asarray(frames, dtype=float)
    cl = closure(chain, U)
    cf = closed_form.solve(cl.chain, seed[U], frames, cl.ell, _kernel() if compiled else None) if CLOSED_FORM else None
    out = np.empty((n, chain.n_vars))
    out[:] = seed
    if cf is None:
        vu, ok, err = _solve(cl, seed[U], seed_frame, frames, compiled)
        out[:, U] = vu.T
        return out, ok, err
    vr, ok, err = cf  # a 6-UPS leg: closed form, the numeric solver where it does not close
    bad = np.flatnonzero(~ok)
    if bad.size:
        vb, ok[bad], err[bad] = _solve(cl, seed[U], seed_frame, frames[bad], compiled)
        vr[bad] = vb.T
    out[:, U] = vr
    return out, ok, err


def _solve(cl: Closure, seed, seed_frame, frames, compiled):
    """:func:`solve_chain` in the unknowns' space: values (k, n), ok (n,), err (n,)."""
    n = frames.shape[0]
    R = np.ascontiguousarray(frames[:, :3, :3].transpose(1, 2, 0))
    p = np.ascontiguousarray(frames[:, :3, 3].T)
    v0 = None                    # None: every pose starts from the seed
    if n >= 4 * ANCHOR_EVERY:
        # anchors from the seed, the other poses from a near anchor (fewer iterations)
        X = _pose_coordinates(frames, cl.ell)
        order = _curve_order(X)
        anc = order[::ANCHOR_EVERY]
        va, oka, _ = _solve(cl, seed, seed_frame, frames[anc], compiled)
        if oka.any():
            v0 = _from_anchors(cl, frames, X, order, oka, va[:, oka], seed, compiled)
    anchored = v0 is not None
    if v0 is None:
        v0 = np.repeat(seed[:, None], n, axis=1)
    vt, ok, err = newton(cl, v0, R, p, compiled=compiled)
    bad = np.flatnonzero(~ok)
    if bad.size and anchored:
        vs = np.repeat(seed[:, None], bad.size, axis=1)
        v2, ok2, e2 = newton(cl, vs, R[:, :, bad], p[:, bad], compiled=compiled)
        vt[:, bad], ok[bad], err[bad] = v2, ok2, e2
        bad = bad[~ok2]
    if bad.size:
        vs = np.repeat(seed[:, None], bad.size, axis=1)
        vt[:, bad], ok[bad], err[bad] = _continue(cl, vs, seed_frame, frames[bad], compiled)
    return vt, ok, err


def _vee_product(A, B):
    """``vee(A B^T)`` (n, 3) for rotation stacks A (n, 3, 3) and B (n, 3, 3) or (3, 3), elementwise."""
    B = np.broadcast_to(B, A.shape)

    def m(i, j):
        return A[:, i, 0] * B[:, j, 0] + A[:, i, 1] * B[:, j, 1] + A[:, i, 2] * B[:, j, 2]

    return 0.5 * np.stack([m(2, 1) - m(1, 2), m(0, 2) - m(2, 0), m(1, 0) - m(0, 1)], axis=1)


def _pose_coordinates(frames: np.ndarray, ell: float) -> np.ndarray:
    """Coordinates (n, 6) of platform frames for finding near poses: the point (mm) and the
    orientation as ``ell vee(R)`` (sin of the angle times the axis, times the chain's size)."""
    return np.concatenate([frames[:, :3, 3], ell * vee(frames[:, :3, :3])], axis=1)


#: bits per coordinate of the Z-order key
CURVE_BITS = 10
#: bit ``b`` of a coordinate goes to bit ``6 b`` of the key (the six coordinates interleaved)
_SPREAD = np.zeros(1 << CURVE_BITS, dtype=np.int64)
for _b in range(CURVE_BITS):
    _SPREAD |= ((np.arange(1 << CURVE_BITS) >> _b) & 1) << (6 * _b)


def _curve_order(X: np.ndarray) -> np.ndarray:
    """The rows of X (n, 6) in the order of a Z-order (Morton) curve through their bounding box,
    one scale for all coordinates: poses close along the curve are close in space."""
    lo = X.min(axis=0)
    span = float(np.max(X.max(axis=0) - lo))
    q = ((X - lo) * ((1 << CURVE_BITS) / span if span > 0 else 0.0)).astype(np.int64)
    np.clip(q, 0, (1 << CURVE_BITS) - 1, out=q)
    key = _SPREAD[q[:, 0]]
    for d in range(1, 6):
        key |= _SPREAD[q[:, d]] << d
    return np.argsort(key, kind="stable")


def _from_anchors(cl: Closure, frames, X, order, oka, va, seed, compiled):
    """Starting values (k, n) of every pose: a near solved anchor's values plus the first-order
    change ``dv = J^+ (dp, omega)`` from the anchor's frame to the pose's (the anchor's Jacobian
    of the solved coordinates), which leaves an error of second order.  Where ``dv`` exceeds a
    Newton step's limits (``MAX_STEP``) the anchor is too far to trust its branch: such a pose
    starts from the ``seed`` (k,), as without anchors.

    The anchors are every ``ANCHOR_EVERY``-th pose along the curve ``order`` (:func:`_curve_order`),
    ``oka`` those that converged, ``va`` (k, na) their values; a pose takes the nearer (in ``X``)
    of the converged anchors just before and after it along the curve."""
    n = frames.shape[0]
    pos = np.empty(n, dtype=np.int64)
    pos[order] = np.arange(n)
    apos = np.flatnonzero(oka) * ANCHOR_EVERY                  # curve positions of the converged anchors
    j = np.searchsorted(apos, pos, side="right") - 1
    before, after = np.maximum(j, 0), np.minimum(j + 1, apos.size - 1)
    anc = order[apos]
    ell = cl.ell
    kern = _kernel() if compiled else None
    if kern is not None:
        v0 = np.empty((cl.k, n))
        kern.predict(*cl.code, np.ascontiguousarray(va), anc, np.ascontiguousarray(frames), np.ascontiguousarray(X),
                     before, after, ell, cl.lim, seed, v0)
        return v0
    db = np.sum((X - X[anc[before]]) ** 2, axis=1)
    da = np.sum((X - X[anc[after]]) ** 2, axis=1)
    near = np.where(da < db, after, before)
    Fa = frames[anc]
    _, _, Jt = closure_error(cl.chain, va, np.ascontiguousarray(Fa[:, :3, :3].transpose(1, 2, 0)),
                             np.ascontiguousarray(Fa[:, :3, 3].T))
    A = Jt.transpose(2, 1, 0)                                   # (na, 6, k)
    A[:, 3:] *= ell
    At = np.swapaxes(A, 1, 2)
    H = At @ A
    H[:, np.arange(cl.k), np.arange(cl.k)] *= 1.0 + 1e-12
    try:
        Jp = np.linalg.solve(H, At)                             # (na, k, 6) least-squares inverse
    except np.linalg.LinAlgError:
        return np.repeat(seed[:, None], n, axis=1)
    Fn = Fa[near]
    d = np.empty((n, 6))
    d[:, :3] = frames[:, :3, 3] - Fn[:, :3, 3]
    d[:, 3:] = ell * _vee_product(frames[:, :3, :3], Fn[:, :3, :3])   # small rotation R R_anchor^T, first order
    dv = np.einsum("nki,ni->kn", Jp[near], d)
    near_enough = np.all(np.abs(dv) <= cl.lim[:, None], axis=0)       # False for NaN too
    return np.where(near_enough, va[:, near] + dv, seed[:, None])


def _continue(cl: Closure, vt, seed_frame, frames, compiled):
    """Newton along the path of poses from ``seed_frame`` to each frame (interpolated position,
    rotation along the geodesic), values (k, n) of the unknowns."""
    from .poses import rotation_matrix

    n = frames.shape[0]
    R0, p0 = seed_frame[:3, :3], seed_frame[:3, 3]
    w = rotation_vector(frames[:, :3, :3] @ R0.T)               # (n, 3)
    ok = np.ones(n, dtype=bool)
    err = np.zeros(n)
    for s in np.linspace(0.0, 1.0, PATH_STEPS + 1)[1:]:
        Rs = rotation_matrix(s * w) @ R0
        ps = p0 + s * (frames[:, :3, 3] - p0)
        live = np.flatnonzero(ok)
        v, ok_s, e = newton(cl, vt[:, live], np.ascontiguousarray(Rs[live].transpose(1, 2, 0)),
                            np.ascontiguousarray(ps[live].T), compiled=compiled)
        vt[:, live] = v
        ok[live] = ok_s
        err[live] = e
        if not ok.any():
            break
    err[~ok] = np.where(np.isfinite(err[~ok]), err[~ok], np.inf)
    return vt, ok, err
