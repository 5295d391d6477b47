"""Numerical inverse kinematics of a serial robot's tool, holding a chosen configuration.

A 6R arm reaches most poses in up to eight configurations (shoulder left or right, elbow up or down,
wrist flipped or not).  The configuration is chosen by a seed ``q``: damped least squares
(Levenberg-Marquardt on the tool's pose error, rotations weighted by a length so that mm and rad mix)
started from the seed converges to the solution of the seed's branch, and over a grid each point
starts from its neighbour's solution, so the branch is kept as long as the grid stays away from the
singular postures between branches.  A point is *unreachable* when the residual does not fall
below the tolerance (out of reach, or the joint limits in the way); it is *singular* when the
tool Jacobian's smallest singular value at the solution is below ``SINGULAR`` times its largest.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from ..kinematics.poses import rotation_matrix
from ..kinematics.transforms import rotation_vector

#: length (mm) weighting the rotation error against the position error
LENGTH = 1000.0
#: relative singular value of the weighted tool Jacobian below which a solution is called singular
SINGULAR = 1e-4


@dataclass(frozen=True, eq=False)
class IKResult:
    """Joint values (n, nq) of the tool poses, and per pose: ``reached`` (residual below the tolerance),
    ``singular`` (at or next to a singular posture), ``residual`` (mm, with rotations times LENGTH)."""

    q: np.ndarray
    reached: np.ndarray
    singular: np.ndarray
    residual: np.ndarray


def rotation_vectors(w, where: str) -> np.ndarray:
    """Rotation vectors (rad) as given, refused if not finite or longer than 2 pi (one turn: degrees?)."""
    a = np.asarray(w, dtype=float)
    if not np.all(np.isfinite(a)):
        raise VjmError(f"{where}: a rotation vector must be finite numbers (rad)")
    turn = np.linalg.norm(np.reshape(a, (-1, 3)), axis=1) if a.size else np.zeros(0)
    if np.any(turn > 2 * np.pi + 1e-9):
        i = int(np.argmax(turn))
        raise VjmError(f"{where}: a rotation vector of {turn[i]:.4g} rad (rx,ry,rz = "
                       f"{', '.join(f'{v:g}' for v in np.reshape(a, (-1, 3))[i])}), beyond one turn (2 pi): degrees? "
                       f"rx,ry,rz are the rotation vector in rad")
    return a


def pose_targets(points, orientation=None) -> np.ndarray:
    """Tool frames (n, 4, 4) at points (n, 3) mm with one orientation (rotation vector, rad; default none)."""
    P = np.atleast_2d(np.asarray(points, dtype=float))
    if P.ndim != 2 or P.shape[1] != 3 or not np.all(np.isfinite(P)):
        raise VjmError(f"points must be (n, 3) finite numbers (mm), got shape {np.shape(points)}")
    T = np.zeros((len(P), 4, 4))
    T[:, :3, :3] = rotation_matrix(np.zeros(3) if orientation is None else rotation_vectors(orientation, "orientation"))
    T[:, :3, 3] = P
    T[:, 3, 3] = 1.0
    return T


def _error(model, q, targets, tool):
    T = model.forward(q, tool)
    e = np.empty((len(q), 6))
    e[:, :3] = targets[:, :3, 3] - T[:, :3, 3]
    e[:, 3:] = LENGTH * rotation_vector(targets[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2))
    return e


def levenberg_marquardt(model, q0, error, tool, W: np.ndarray, tol: float, max_iter: int, lam0: float = 1e-2):
    """Damped Gauss-Newton (Levenberg-Marquardt) on a pose error, every configuration on its own, within the
    joint limits: ``error(q, idx)`` is the error (k, 6) (mm; rotations weighted; inf where it is not defined)
    at configurations q (k, nq) of the targets ``idx``; the step uses the rigid tool Jacobian weighted by W (6,).
    A configuration stops below ``tol`` or when its damping passes 1e12 (no step improves it).  Returns q
    (n, nq), the residual norms (n,) and the iterations (n,)."""
    lo, hi = model.tree.limits
    q = np.clip(np.array(q0, dtype=float), lo, hi)
    e = error(q, np.arange(len(q)))
    r = np.linalg.norm(e, axis=1)
    lam = np.full(len(q), lam0)
    its = np.zeros(len(q), dtype=int)
    for _ in range(max_iter):
        act = np.flatnonzero((r > tol) & (lam < 1e12))
        if act.size == 0:
            break
        its[act] += 1
        J = model.jacobian(q[act], tool) * W[None, :, None]
        JtJ = np.swapaxes(J, 1, 2) @ J
        g = np.einsum("nij,ni->nj", J, np.nan_to_num(e[act], posinf=0.0))
        scale = np.trace(JtJ, axis1=1, axis2=2)[:, None, None] / model.nq
        dq = np.linalg.solve(JtJ + (lam[act, None, None] * scale) * np.eye(model.nq), g[:, :, None])[:, :, 0]
        qn = np.clip(q[act] + dq, lo, hi)
        en = error(qn, act)
        rn = np.linalg.norm(en, axis=1)
        better = rn < r[act]
        ok = act[better]
        q[ok], e[ok], r[ok] = qn[better], en[better], rn[better]
        lam[ok] = np.maximum(lam[ok] / 3.0, 1e-12)
        lam[act[~better]] *= 4.0
    return q, r, its


def solve(model, targets, seed, tool=None, tol: float = 1e-8, max_iter: int = 200) -> IKResult:
    """Joint values reaching ``targets`` (n, 4, 4) from ``seed`` ((nq,) or (n, nq)), each pose on its own."""
    W = np.r_[np.ones(3), LENGTH * np.ones(3)]
    q0 = np.broadcast_to(np.asarray(seed, dtype=float), (len(targets), model.nq))
    q, r, _ = levenberg_marquardt(model, q0, lambda qq, idx: _error(model, qq, targets[idx], tool), tool, W, tol,
                                  max_iter)
    s = np.linalg.svd(model.jacobian(q, tool) * W[None, :, None], compute_uv=False)
    return IKResult(q, r <= tol, s[:, -1] < SINGULAR * s[:, 0], r)


def solve_path(model, targets, seed, tool=None, tol: float = 1e-8) -> IKResult:
    """:func:`solve` pose after pose, each from the previous solution (the last one reached): the
    configuration of ``seed`` is carried along a path or a grid's rows."""
    qs, reached, singular, res = [], [], [], []
    q = np.asarray(seed, dtype=float)
    for T in targets:
        r = solve(model, T[None], q, tool, tol)
        qs.append(r.q[0])
        reached.append(r.reached[0])
        singular.append(r.singular[0])
        res.append(r.residual[0])
        if r.reached[0]:
            q = r.q[0]
    return IKResult(np.array(qs), np.array(reached), np.array(singular), np.array(res))
