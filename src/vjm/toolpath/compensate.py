"""Compensation: the commanded TCP poses whose loaded TCP lands on the programmed ones.

Fixed-point iteration per point on the nonlinear model (with its effects):
``q_{k+1} = p - d(q_k)`` for the position and, on a 6-dof platform,
``Q_{k+1} = Exp(-r(q_k)) R_p`` for the orientation, where ``d`` and ``r`` are
the TCP's deflection and rotation under the point's wrench at command
``q_k``.  The deflection changes with the command only through the stiffness'
variation over a deflection, so the contraction factor is tiny.  Between two
nonlinear equilibria ``d`` is the last equilibrium's plus the change of the
linear ``C w`` (a stiffness map costs ~1/200 of an equilibrium), and the
equilibrium at the converged commands checks them: typically two equilibria
per point in all (the uncompensated one and the check).  All points iterate
together (batched) with a per-point convergence mask; each starts from its
own uncompensated deflection, which the deflection pass has computed (a
better start than the previous point's solution, and one that needs no
sequential loop).  The result is a :class:`vjm.compensation.Compensation`.  On a 3-dof translational platform only the position can
be compensated; the rotation is reported.
"""
from __future__ import annotations

import numpy as np

from ..compensation import Compensation
from ..errors import EquilibriumError, VjmError
from ..kinematics.poses import rotation_matrix
from ..kinematics.transforms import rotation_vector
from .deflect import linear, nonlinear_tcp_solved

#: a point has converged when its loaded TCP is this fraction of its deflection from the programmed one ...
REL_TOL = 1e-4
#: ... or closer than this, mm (0.1 nm)
ABS_TOL = 1e-7
#: nonlinear equilibria (and fixed-point steps on the local model between two of them) allowed
MAX_ITER = 10
#: the fixed point on the local model stops once its step is below this fraction of a point's target:
#: what is left, the step times the local model's contraction (the stiffness' change over a deflection,
#: ~1e-3), is some 1e-4 of the target, and the next nonlinear equilibrium checks the point anyway
LOCAL_TOL = 0.1


def compose(poses, rot) -> np.ndarray:
    """Poses (n, 6) whose rotation is ``Exp(rot) R(poses)``."""
    R = rotation_matrix(rot) @ rotation_matrix(poses[:, 3:])
    return np.hstack([poses[:, :3], rotation_vector(R)])


def loaded_error(model, cmd, programmed, W, tool, workers=1, start=None):
    """(position error (n, 3), deflection twist (n, 6), :class:`~.deflect.NonlinearTcp`) of the loaded TCP
    of commands ``cmd`` from ``programmed``; ``start``: equilibrium states at nearby poses to start from."""
    s = nonlinear_tcp_solved(model, cmd, W, tool, workers, start=start)
    return programmed[:, :3] - (cmd[:, :3] + s.twist[:, :3]), s.twist, s


def _update(cmd, programmed, t, six):
    """One fixed-point step: position ``p - d``, orientation ``Exp(-r) R_p``; returns the position step (n, 3)."""
    step = programmed[:, :3] - t[:, :3] - cmd[:, :3]
    cmd[:, :3] += step
    if six:
        cmd[:] = compose(np.hstack([cmd[:, :3], programmed[:, 3:]]), -t[:, 3:])
    return step


def compensate(model, programmed, W, tool, d0, workers: int = 1, where=None, start=None) -> Compensation:
    """Commanded TCP poses for ``programmed`` (n, 3|6) under TCP wrenches W (n, 6).

    ``d0`` (n, 6): the nonlinear deflection at the programmed poses; ``where(i)`` names point i
    in messages (its file and line); ``start`` (n, ns): the deflection's equilibrium states
    (:func:`~.deflect.nonlinear_tcp_solved`), from which the check equilibria start.  Between two nonlinear equilibria the deflection is taken as
    the last equilibrium's plus the change of the linear ``C w`` (cheap stiffness maps), whose
    fixed point is found first; the next equilibrium then checks it.  The nonlinear remainder
    varies over a deflection by a tiny fraction of itself, so one or two equilibria suffice.
    """
    programmed = np.asarray(programmed, dtype=float)
    six = programmed.shape[1] == 6
    n = len(programmed)
    cmd = programmed.copy()
    target = np.maximum(REL_TOL * np.linalg.norm(d0[:, :3], axis=1), ABS_TOL)
    active = np.arange(n)
    ref_d = np.array(d0, dtype=float)
    ref_lin = linear(model, programmed, W, tool)
    res = np.full(n, np.inf)
    resvec = np.zeros((n, 3))
    evals = cold = 0
    state = None if start is None else np.array(start)
    while evals < MAX_ITER:
        evals += 1
        a = active
        t = ref_d[a]  # at cmd[a], where ref_lin[a] was taken: the first step needs no map
        for k in range(MAX_ITER):  # fixed point on the local model (linear maps only)
            if k:
                t = ref_d[a] + linear(model, cmd[a], W[a], tool) - ref_lin[a]
            c = cmd[a]
            step = _update(c, programmed[a], t, six)
            cmd[a] = c
            _reachable(model, cmd[a], tool, a, where, programmed[a])
            if np.all(np.linalg.norm(step, axis=1) <= LOCAL_TOL * target[a]):
                break
        err, t, sol = loaded_error(model, cmd[a], programmed[a], W[a], tool, workers,
                                   None if state is None else state[a])
        cold += sol.cold
        if state is not None:
            state[a] = sol.state
        bad = ~np.all(np.isfinite(t), axis=1)
        if bad.any():
            i = int(a[np.argmax(bad)])
            raise EquilibriumError(f"{where(i) if where else f'point {i}'}: no equilibrium at the compensated "
                                   f"pose (load too large for the model?)")
        res[a] = np.linalg.norm(err, axis=1)
        resvec[a] = -err
        done = res[a] <= target[a]
        if six:
            done &= np.linalg.norm(_rot_error(cmd[a], programmed[a], t), axis=1) <= \
                np.maximum(REL_TOL * np.linalg.norm(d0[a, 3:], axis=1), ABS_TOL * 1e-3)
        # the points still off restart from this equilibrium
        ref_d[a] = t
        active = a[~done]
        if active.size == 0:
            break
        ref_lin[active] = linear(model, cmd[active], W[active], tool)
    if active.size:
        i = int(active[0])
        raise EquilibriumError(f"{where(i) if where else f'point {i}'}: compensation did not converge in "
                               f"{MAX_ITER} equilibria (residual {res[i]:.3g} mm)")
    return Compensation(cmd, res, residual_vector=resvec, equilibria=evals, cold=cold)


def _rot_error(cmd, programmed, t):
    """Rotation vector (n, 3) from the loaded TCP orientation ``Exp(t_r) R_cmd`` to the programmed ``R_p``."""
    Rl = rotation_matrix(t[:, 3:]) @ rotation_matrix(cmd[:, 3:])
    Rp = rotation_matrix(programmed[:, 3:])
    return rotation_vector(Rp @ np.swapaxes(Rl, 1, 2))


def _reachable(model, tcp_cmd, tool, idx, where, programmed=None) -> None:
    """VjmError naming the first commanded pose the machine cannot reach (actuator limits, the inverse
    kinematics), or whose platform point leaves the workspace box that its programmed one was in."""
    from .deflect import platform_poses

    P, _ = platform_poses(model, tcp_cmd, tool)
    ok = np.asarray(model.arch.reachable(model, P if model.dof == 6 else P[:, :3]), bool)
    if programmed is not None:
        lo, hi = (np.asarray(v, dtype=float) for v in model.arch.workspace)
        P0, _ = platform_poses(model, programmed, tool)
        inside = np.all((P0[:, :3] >= lo) & (P0[:, :3] <= hi), axis=1)
        ok &= ~inside | np.all((P[:, :3] >= lo) & (P[:, :3] <= hi), axis=1)
    if not ok.all():
        k = int(np.argmax(~ok))
        i = int(idx[k])
        raise VjmError(f"{where(i) if where else f'point {i}'}: the compensated pose "
                       f"{np.round(tcp_cmd[k, :3], 6).tolist()} mm is outside the workspace or needs an actuator "
                       f"outside its limits")
