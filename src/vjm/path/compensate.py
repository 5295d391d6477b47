"""Compensation: the commanded TCP poses whose loaded TCP lands on the programmed ones.

Fixed-point iteration per point on the nonlinear model (with its effects):
``q_{k+1} = p - d(q_k)`` for the position and, on a 6-dof platform,
``Q_{k+1} = Exp(-r(q_k)) R_p`` for the orientation, where ``d`` and ``r`` are
the TCP's deflection and rotation under the point's wrench at command
``q_k``.  The deflection changes with the command only through the stiffness'
variation over a deflection (micrometres), so the contraction factor is
tiny and a few iterations reach round-off.  All points iterate together
(batched equilibrium) with a per-point convergence mask; each starts from
the programmed pose minus its own uncompensated deflection, which the
deflection pass has already computed (a better start than the neighbour's
solution).  On a 3-dof translational platform only the position can be
compensated; the rotation is reported.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import EquilibriumError, VjmError
from ..kinematics import rotation_matrix
from ..transforms import rotation_vector
from .deflect import nonlinear_tcp

#: a point has converged when its loaded TCP is this fraction of its deflection from the programmed one ...
REL_TOL = 1e-5
#: ... or closer than this, mm (0.1 nm)
ABS_TOL = 1e-7
MAX_ITER = 20


@dataclass(frozen=True)
class Compensation:
    """Commanded TCP poses (n, 3) or (n, 6), the residual (n,) of the loaded TCP from the programmed one
    (mm, evaluated by the last equilibrium), and the iterations used."""

    commanded: np.ndarray
    residual: np.ndarray
    iterations: int


def compose(poses, rot) -> np.ndarray:
    """Poses (n, 6) whose rotation is ``Exp(rot) R(poses)``."""
    R = rotation_matrix(rot) @ rotation_matrix(poses[:, 3:])
    return np.hstack([poses[:, :3], rotation_vector(R)])


def loaded_error(model, cmd, programmed, W, tool, workers=1) -> tuple[np.ndarray, np.ndarray]:
    """(position error (n, 3), deflection twist (n, 6)) of the loaded TCP of commands ``cmd`` from ``programmed``."""
    t = nonlinear_tcp(model, cmd, W, tool, workers)
    return programmed[:, :3] - (cmd[:, :3] + t[:, :3]), t


def compensate(model, programmed, W, tool, d0, workers: int = 1, where=None) -> Compensation:
    """Commanded TCP poses for ``programmed`` (n, 3|6) under TCP wrenches W (n, 6).

    ``d0`` (n, 6): the uncompensated nonlinear deflection at the programmed poses (the start);
    ``where(i)`` names point i in messages (its file and line).
    """
    programmed = np.asarray(programmed, dtype=float)
    six = programmed.shape[1] == 6
    n = len(programmed)
    cmd = programmed.copy()
    cmd[:, :3] -= d0[:, :3]
    if six:
        cmd = compose(programmed, -d0[:, 3:])
    target = np.maximum(REL_TOL * np.linalg.norm(d0[:, :3], axis=1), ABS_TOL)
    active = np.arange(n)
    res = np.full(n, np.inf)
    it = 0
    for it in range(1, MAX_ITER + 1):
        _reachable(model, cmd[active], tool, active, where)
        err, t = loaded_error(model, cmd[active], programmed[active], W[active], tool, workers)
        bad = ~np.all(np.isfinite(t), axis=1)
        if bad.any():
            i = int(active[np.argmax(bad)])
            raise EquilibriumError(f"{where(i) if where else f'point {i}'}: no equilibrium at the compensated "
                                   f"pose (load too large for the model?)")
        res[active] = np.linalg.norm(err, axis=1)
        done = res[active] <= target[active]
        cmd[active, :3] += err
        if six:
            rot = _rot_error(cmd[active], programmed[active], t)
            done &= np.linalg.norm(rot, axis=1) <= np.maximum(REL_TOL * np.linalg.norm(d0[active, 3:], axis=1),
                                                              ABS_TOL * 1e-3)
            cmd[active] = compose(programmed[active], -t[:, 3:])
        active = active[~done]
        if active.size == 0:
            break
    if active.size:
        i = int(active[0])
        raise EquilibriumError(f"{where(i) if where else f'point {i}'}: compensation did not converge in "
                               f"{MAX_ITER} iterations (residual {res[i]:.3g} mm)")
    return Compensation(cmd, res, it)


def _rot_error(cmd, programmed, t):
    """Rotation vector (n, 3) from the loaded TCP orientation ``Exp(t_r) R_cmd`` to the programmed ``R_p``."""
    Rl = rotation_matrix(t[:, 3:]) @ rotation_matrix(cmd[:, 3:])
    Rp = rotation_matrix(programmed[:, 3:])
    return rotation_vector(Rp @ np.swapaxes(Rl, 1, 2))


def _reachable(model, tcp_cmd, tool, idx, where) -> None:
    """VjmError naming the first commanded pose the machine cannot reach (workspace, actuator limits)."""
    from .deflect import platform_poses

    P, _ = platform_poses(model, tcp_cmd, tool)
    ok = np.asarray(model.arch.reachable(model, P if model.dof == 6 else P[:, :3]), bool)
    if not ok.all():
        k = int(np.argmax(~ok))
        i = int(idx[k])
        raise VjmError(f"{where(i) if where else f'point {i}'}: the compensated pose "
                       f"{np.round(tcp_cmd[k, :3], 6).tolist()} mm is outside the workspace or needs an actuator "
                       f"outside its limits")
