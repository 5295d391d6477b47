"""Compensation of the self-weight sag: the joint values to command so that the deflected tool reaches a target.

A robot commanded to the rigid inverse kinematics ``q0 = IK(T)`` of a target ``T`` misses it by its sag: its
joints and links give under its own weight (and a payload), and the tool lands at ``D(q0) = F(q0) + s(q0)``,
``F`` the rigid forward kinematics and ``s`` the equilibrium on the deflected geometry
(:meth:`~vjm.robot.model.RobotModel.self_weight`).  The compensated command solves the equilibrium problem
``D(q) = T`` itself:

1. the rigid IK from the seed (damped least squares, as :mod:`vjm.robot.ik`) puts q on the seed's branch;
2. from there, Levenberg-Marquardt on the deflected pose's error ``T - D(q)``, every residual evaluated with
   the full self-weight equilibrium at q.  The step uses the rigid Jacobian (the sag's derivative, about
   ``|s| / reach`` of it, is left out of the step, never out of the residual), so the iteration converges
   linearly with a rate of that order (1e-3 on an arm sagging a millimetre over a metre): 2 to 4 iterations
   to a micrometre and below.

A target is a pose (4x4): position and orientation reached, the rotation error weighted by
:data:`vjm.robot.ik.LENGTH` mm/rad; or a point (3,): the position only, the orientation free (the redundant
directions settled nearest the seed by the damping), unless ``orientation`` gives one.  Per target the
result says ``converged`` (the deflected pose within ``tol``), ``reached`` (False: the rigid IK does not
reach it -- out of reach or the joint limits in the way; not compensated), ``singular`` (the tool Jacobian's
smallest singular value below :data:`vjm.robot.ik.SINGULAR` of its largest at the command) and the
``iterations`` of step 2.  Units mm, rad.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from ..kinematics.poses import rotation_matrix
from ..kinematics.transforms import rotation_vector
from .ik import LENGTH, SINGULAR, levenberg_marquardt

#: default tolerance (mm; rotations times LENGTH) of the deflected tool pose
TOL = 1e-6
#: iterations of the compensation (step 2); the rigid IK (step 1) has up to 200
MAX_ITER = 50


@dataclass(frozen=True, eq=False)
class Compensation:
    """The commands and, per target: ``q`` (n, nq) the commands (the last iterate where not converged),
    ``plain`` (n, nq) the rigid IK (uncompensated) commands, ``converged``, ``reached``, ``singular`` (n,),
    ``residual`` (n,) the deflected pose's error at ``q`` (mm, rotations times LENGTH for poses),
    ``miss`` (n,) the plain commands' deflected position error (mm: the sag compensated), ``sag`` (n, 6) the
    tool's deflection at ``q`` (mm, rad) and ``iterations`` (n,) of the compensation (0: not run)."""

    q: np.ndarray
    plain: np.ndarray
    converged: np.ndarray
    reached: np.ndarray
    singular: np.ndarray
    residual: np.ndarray
    miss: np.ndarray
    sag: np.ndarray
    iterations: np.ndarray
    tol: float
    positions_only: bool


def targets_of(targets, orientation=None) -> tuple[np.ndarray, bool]:
    """Target frames (n, 4, 4) and whether only their positions count: poses (n, 4, 4) or (4, 4), or points
    (n, 3) with an ``orientation`` (rotation vector (3,) or (n, 3), rad) or none (orientation free)."""
    a = np.asarray(targets, dtype=float)
    if a.shape[-2:] == (4, 4):
        T = a.reshape(-1, 4, 4)
        if orientation is not None:
            raise VjmError("compensate: an orientation goes with target points (n, 3), not poses (n, 4, 4)")
        free = False
    elif a.ndim in (1, 2) and a.shape[-1] == 3:
        P = a.reshape(-1, 3)
        T = np.zeros((len(P), 4, 4))
        T[:, :3, 3], T[:, 3, 3] = P, 1.0
        free = orientation is None
        T[:, :3, :3] = np.eye(3) if free else rotation_matrix(np.broadcast_to(np.asarray(orientation, float),
                                                                              (len(P), 3)))
    else:
        raise VjmError(f"compensate: targets must be poses (n, 4, 4) or points (n, 3) in mm, got shape {a.shape}")
    if len(T) == 0 or not np.all(np.isfinite(T)):
        raise VjmError("compensate: targets must be at least one pose or point of finite numbers (mm, rad)")
    return T, free


def _deflected(model, q, tool, gravity, payload, sag: bool):
    """The tool frames (n, 4, 4) at q, deflected by the self-weight equilibrium if ``sag`` (NaN where it is not
    found), and the sag twists (n, 6)."""
    T = model.forward(q, tool)
    if not sag:
        return T, np.zeros((len(q), 6))
    s = model.self_weight(q, tool, gravity, payload, strict=False)
    D = T.copy()
    D[:, :3, 3] += s[:, :3]
    D[:, :3, :3] = rotation_matrix(np.nan_to_num(s[:, 3:])) @ T[:, :3, :3]
    D[np.isnan(s[:, 0])] = np.nan
    return D, s


def _error(D, targets, w: float) -> np.ndarray:
    e = np.empty((len(D), 6))
    e[:, :3] = targets[:, :3, 3] - D[:, :3, 3]
    e[:, 3:] = w * rotation_vector(targets[:, :3, :3] @ np.swapaxes(D[:, :3, :3], 1, 2)) if w else 0.0
    return np.where(np.isfinite(e), e, np.inf)


def _solve(model, targets, q0, tool, w: float, tol: float, max_iter: int, lam0: float, load=None):
    """Levenberg-Marquardt from q0 on the (deflected, with ``load`` = (gravity, payload)) pose error:
    q (n, nq), residual (n,), iterations (n,)."""
    sag = load is not None
    g, pl = load if sag else (None, None)
    W = np.r_[np.ones(3), np.full(3, w)]

    def error(q, idx):
        return _error(_deflected(model, q, tool, g, pl, sag)[0], targets[idx], w)

    return levenberg_marquardt(model, q0, error, tool, W, tol, max_iter, lam0)


def _singular(model, q, tool, w: float) -> np.ndarray:
    J = model.jacobian(q, tool)
    J = J[:, :3] if not w else J * np.r_[np.ones(3), np.full(3, w)][None, :, None]
    s = np.linalg.svd(J, compute_uv=False)
    return s[:, -1] < SINGULAR * s[:, 0]


def compensate(model, targets, seed, tool=None, gravity=None, payload=None, tol: float = TOL,
               orientation=None, max_iter: int = MAX_ITER) -> Compensation:
    """:meth:`vjm.robot.RobotModel.compensate` (see the module docstring): the commands reaching ``targets``
    (poses (n, 4, 4) or points (n, 3), mm) under self-weight, in the configuration of ``seed`` ((nq,) or
    (n, nq)); ``gravity`` and ``payload`` as :meth:`~vjm.robot.RobotModel.self_weight` takes them."""
    from .weight import check_inertials

    if not (np.isfinite(tol) and tol > 0):
        raise VjmError(f"compensate: tol must be a number > 0 (mm), got {tol!r}")
    check_inertials(model)
    tool = model._tool(tool)
    T, free = targets_of(targets, orientation)
    n = len(T)
    s0 = np.asarray(seed, dtype=float)
    q0 = model.check_q(s0)[0]
    if len(q0) == 1:
        q0 = np.repeat(q0, n, axis=0)
    if len(q0) != n:
        raise VjmError(f"compensate: {len(q0)} seeds for {n} targets; give one seed or one per target")
    w = 0.0 if free else LENGTH
    plain, r0, _ = _solve(model, T, q0, tool, w, tol, 200, 1e-2)
    reached = r0 <= tol
    q = plain.copy()
    res = np.full(n, np.inf)
    its = np.zeros(n, dtype=int)
    miss = np.full(n, np.nan)
    sag = np.full((n, 6), np.nan)
    k = np.flatnonzero(reached)
    if k.size:
        load = (gravity, payload)
        D0, _ = _deflected(model, plain[k], tool, gravity, payload, True)
        miss[k] = np.linalg.norm(T[k, :3, 3] - D0[:, :3, 3], axis=1)
        q[k], res[k], its[k] = _solve(model, T[k], plain[k], tool, w, tol, max_iter, 1e-6, load)
        sag[k] = _deflected(model, q[k], tool, gravity, payload, True)[1]
    return Compensation(q, plain, res <= tol, reached, _singular(model, q, tool, w), res, miss, sag, its,
                        float(tol), free)
