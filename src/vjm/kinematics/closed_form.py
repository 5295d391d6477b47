"""Closed-form inverse kinematics of a leg that positions a point and turns a spherical wrist.

A chain whose unknowns read, once its springs are at rest and its constants multiplied together
(:func:`vjm.kinematics.ik.rigid_chain`),

    C0  R_a(a1) R_b(a2) T_c(l)  R_d(s1) R_e(s2) R_f(s3)  C1

with ``a, b, c`` three different axes and ``d, e, f`` three different axes (a U joint, a prismatic
strut along the third axis and an S joint: the leg of a Gough-Stewart hexapod, 6-UPS) closes on a
platform frame ``F`` in closed form.  The wrist's rotations do not move its centre, so the centre
of ``G = C0^-1 F C1^-1`` fixes the strut: ``l = |p|`` and the two angles that turn the third axis
onto ``p``; the wrist's three angles are then a Tait-Bryan decomposition of the rotation left.

Of the two solutions of each part (the strut's direction reversed, or the wrist's middle angle past
a right angle) the one on the seed posture's side is taken, and every angle is wrapped to within half
a turn of its seed value.  The U joint and the strut are then those the numeric solver (Newton
continued from the seed) reaches.  A wrist working near its gimbal lock (the middle angle near a right
angle, as the S joints of the bundled hexapod do) has two sets of angles close together, and Newton
may end on either; both give the same joint motion, so the same stiffness (the tests compare the
maps).
Every pose is checked by multiplying the chain out; one that does not close to ``CLOSE_TOL`` of the
chain's size (the strut through the U joint's centre, a wrist at gimbal lock where round-off
matters) is left to the numeric solver.
"""
from __future__ import annotations

import numpy as np

from .chain import Chain
from .transforms import AXIS, ROTATION, elementary

#: closure tolerance of the check, relative to the chain's size (ten times Newton's
#: vjm.kinematics.ik.CLOSE_TOL: the check's own product adds its round-off)
CLOSE_TOL = 1e-12


def _cyclic(i: int, j: int, k: int) -> float:
    """+1 for an even permutation (i, j, k) of the axes (x y z, y z x, z x y), -1 for an odd one."""
    return 1.0 if (j - i) % 3 == 1 else -1.0


def pattern(chain: Chain):
    """The leg's factors if ``chain`` (a rigid chain over its unknowns) has the form above, else None:
    (C0, [(kind, var, coef)] * 6, C1)."""
    f = list(chain.factors)
    C0 = f.pop(0).T if f and f[0].kind == "const" else np.eye(4)
    C1 = f.pop().T if f and f[-1].kind == "const" else np.eye(4)
    if len(f) != 6 or any(x.kind == "const" for x in f) or chain.n_vars != 6:
        return None
    kinds = [x.kind for x in f]
    if not (all(ROTATION[k] for k in kinds[:2] + kinds[3:]) and not ROTATION[kinds[2]]):
        return None
    if len({AXIS[k] for k in kinds[:3]}) != 3 or len({AXIS[k] for k in kinds[3:]}) != 3:
        return None
    if sorted(x.var for x in f) != list(range(6)) or any(x.coef == 0.0 for x in f):
        return None
    return C0, [(x.kind, x.var, x.coef) for x in f], C1


def _wrap(a: np.ndarray, seed: float) -> np.ndarray:
    """Angles a shifted by whole turns to within half a turn of ``seed``."""
    return a + 2.0 * np.pi * np.floor((seed - a) / (2.0 * np.pi) + 0.5)


def solve(chain: Chain, seed: np.ndarray, frames: np.ndarray, ell: float, kernel=None):
    """Values (n, 6) of the unknowns closing ``chain`` on frames (n, 4, 4), a closed mask (n,) and the
    closure error (n,) mm, or None when the chain is not of the form above.  ``seed`` (6,): the values
    at the seed posture (which branch), ``ell``: the chain's size (mm) for the closure check.
    ``kernel``: :mod:`vjm.kinematics.ik_kernel` to solve pose by pose compiled, None: numpy."""
    pat = pattern(chain)
    if pat is None:
        return None
    C0, fac, C1 = pat
    seed = np.asarray(seed, dtype=float)
    th = np.array([seed[v] * c for _, v, c in fac])   # the seed's angles (and length) as the factors see them
    ax = [AXIS[f[0]] for f in fac]
    a, b, c, i, j, k = ax
    # R_b(t) e_c = cos t e_c + sb sin t e_a and R_a(t) e_c = cos t e_c + sa sin t e_b (sa, sb = +-1); the
    # strut's direction, the sign of the U joint's cos a2 and of the wrist's cos s2 on the seed's side
    sgn = np.array([_cyclic(b, c, a), _cyclic(a, c, b), 1.0 if th[2] >= 0.0 else -1.0,
                    1.0 if np.cos(th[1]) >= 0.0 else -1.0, _cyclic(i, j, k), 1.0 if np.cos(th[4]) >= 0.0 else -1.0])
    n = len(frames)
    if kernel is not None:
        v, err = np.empty((n, 6)), np.empty(n)
        C0i, C1i = np.linalg.inv(C0), np.linalg.inv(C1)
        kernel.leg(C0i[:3, :3].copy(), C0i[:3, 3].copy(), C1i[:3, :3].copy(), C1i[:3, 3].copy(), np.array(ax, np.int64),
                   np.array([f[1] for f in fac], np.int64), np.array([f[2] for f in fac], float), th, sgn,
                   np.ascontiguousarray(frames), float(ell), v, err)
    else:
        G = np.linalg.inv(C0) @ frames @ np.linalg.inv(C1)
        v = _solve_numpy(fac, th, sgn, G)
        err = closure_error(fac, v, G, ell)
    with np.errstate(invalid="ignore"):
        return v, err <= CLOSE_TOL * ell, err


def _solve_numpy(fac, th, sgn, G) -> np.ndarray:
    """The values (n, 6) on ``G = C0^-1 F C1^-1`` (n, 4, 4) by numpy, batched over poses (the compiled
    kernel's arithmetic)."""
    sb, sa, sl, sc, e, cw = sgn
    p = G[:, :3, 3]
    a, b, c = (AXIS[f[0]] for f in fac[:3])
    ll = sl * np.linalg.norm(p, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = p / ll[:, None]
        t2 = np.arcsin(np.clip(sb * u[:, a], -1.0, 1.0))
        t2 = t2 if sc > 0 else np.pi - t2
        t1 = np.arctan2(sc * sa * u[:, b], sc * u[:, c])
    t1, t2 = _wrap(t1, th[0]), _wrap(t2, th[1])
    Rp = elementary(fac[0][0], t1)[:, :3, :3] @ elementary(fac[1][0], t2)[:, :3, :3]
    W = np.swapaxes(Rp, 1, 2) @ G[:, :3, :3]       # R_d(s1) R_e(s2) R_f(s3)
    i, j, k = (AXIS[f[0]] for f in fac[3:])
    s2 = np.arcsin(np.clip(e * W[:, i, k], -1.0, 1.0))
    s2 = s2 if cw > 0 else np.pi - s2
    s1 = np.arctan2(-cw * e * W[:, j, k], cw * W[:, k, k])
    s3 = np.arctan2(-cw * e * W[:, i, j], cw * W[:, i, i])
    ang = [t1, t2, ll, _wrap(s1, th[3]), _wrap(s2, th[4]), _wrap(s3, th[5])]
    v = np.empty((len(G), 6))
    for (_, var, coef), x in zip(fac, ang):
        v[:, var] = x / coef
    return v


def closure_error(fac, v, G, ell) -> np.ndarray:
    """(n,) how far (mm; rotations times the chain's size) the leg ``R R T R R R`` multiplied out at values
    v is from ``G = C0^-1 F C1^-1`` (n, 4, 4) (the constants are rigid: the frame of G measures as well as
    the world's); NaN where v is."""
    T = elementary(fac[0][0], fac[0][2] * v[:, fac[0][1]])
    for kind, var, coef in fac[1:]:
        T = T @ elementary(kind, coef * v[:, var])
    ep = np.max(np.abs(T[:, :3, 3] - G[:, :3, 3]), axis=1)
    er = np.max(np.abs(T[:, :3, :3] - G[:, :3, :3]), axis=(1, 2))
    return np.where(np.isnan(ep + er), np.nan, np.maximum(ep, ell * er))
