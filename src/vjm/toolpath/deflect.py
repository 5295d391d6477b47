"""Deflection of the tool centre point (TCP) under a wrench at it, for commanded poses: linear or nonlinear.

The machine's pose is its platform frame; the TCP sits at ``tool`` (platform
axes, mm) from the platform point, so in world axes at ``R tool``.  The
wrench acts at the TCP; at the platform point it is ``(F, M + R tool x F)``.
The TCP's deflection counts the platform rotation times the tool lever:

* ``linear``: ``t = C(p) w`` (the model's springs, :meth:`vjm.Model.stiffness_map`),
  TCP translation ``t_p + t_r x R tool``.  The model's ``effects:`` are left out.
* ``nonlinear``: the equilibrium of :mod:`vjm.stiffness.nonlinear` (finite rotations; along a path
  warm-started from the neighbouring point, :mod:`vjm.toolpath.equilibrium`), TCP translation
  ``u + (Exp(t_r) - I) R tool``, with the model's ``effects:`` (what ``vjm diagnose`` writes into
  model_updated.yaml), each applied by its own :meth:`~vjm.effects.Effect.load` and
  :meth:`~vjm.effects.Effect.nonlinear` (a weight joins the load, an actuator's slip is the rest value
  of its spring, ...: see :mod:`vjm.effects.library`).

Every function takes the commanded poses of the TCP (not of the platform).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from ..kinematics.poses import rotation_matrix
from .equilibrium import equilibria

#: (pose, wrench) pairs per block of the nonlinear solver (marched in SEGMENTS runs: KKT matrices of 128 pairs)
BLOCK = 4096


def check_effects(model) -> None:
    """Every entry of the model's ``effects:`` is a registered additive effect (the model file's reader
    checks the same; a model built in Python may carry anything)."""
    from .. import effects as fx

    for name in model.effects:
        if fx.get(name, f"effects.{name}").kind != "additive":
            raise VjmError(f"effects.{name}: {name} changes the model itself; apply it to the model")


def platform_poses(model, tcp_poses, tool) -> tuple[np.ndarray, np.ndarray]:
    """Platform poses (n, 3) or (n, 6) and world levers ``R tool`` (n, 3) of TCP poses (n, 3) or (n, 6)."""
    tcp_poses = np.asarray(tcp_poses, dtype=float)
    tool = np.asarray(tool, dtype=float)
    if tcp_poses.shape[1] == 6:
        R = rotation_matrix(tcp_poses[:, 3:])
        lever = R @ tool
        return np.hstack([tcp_poses[:, :3] - lever, tcp_poses[:, 3:]]), lever
    lever = np.broadcast_to(tool, (len(tcp_poses), 3))
    P = tcp_poses[:, :3] - lever
    return (np.hstack([P, np.zeros_like(P)]) if model.dof == 6 else P), lever


def linear(model, tcp_poses, W_tcp, tool, kin=None) -> np.ndarray:
    """TCP deflection twists (n, 6) ``C(p) w`` with the tool lever (no effects)."""
    from .wrench import at_platform

    P, lever = platform_poses(model, tcp_poses, tool)
    C = model.stiffness_map(P if kin is None else kin).C
    t = np.einsum("nij,nj->ni", C, at_platform(W_tcp, lever))
    t[:, :3] += np.cross(t[:, 3:], lever)
    return t


@dataclass(frozen=True)
class NonlinearTcp:
    """TCP twists (n, 6) (NaN rows where no equilibrium was found), the equilibrium states (n, ns) to
    warm-start nearby solves from, the cold starts and the points that needed the reference solver."""

    twist: np.ndarray
    state: np.ndarray
    cold: int = 0
    fallback: int = 0


def _nonlinear_block(model, P, Wp, start=None):
    """Nonlinear platform twists of one block with the model's effects; NaN rows where the equilibrium
    was not found; and the :class:`~.equilibrium.Solved` of the equilibria.

    Each effect first adds to the load (:meth:`~vjm.effects.Effect.load`), then says how it enters the
    equilibrium under the total load (:meth:`~vjm.effects.Effect.nonlinear`): rest values of springs,
    a scale of the nonlinear part, a twist added after."""
    from .. import effects as fx

    effects = [(fx.get(name, f"effects.{name}"), values) for name, values in model.effects.items()]
    W = np.array(Wp)
    for eff, values in effects:
        W = eff.load(model, values, P, W)
    ctx = fx.Context(model, P, np.arange(len(P)), W)
    parts = [eff.nonlinear(model, values, ctx) for eff, values in effects]
    offsets: dict = {}
    for part in parts:
        offsets.update(part.offsets or {})
    solved = equilibria(model, P, W, offsets=offsets or None, start=start)
    t = solved.twist
    scales = [part.scale for part in parts if part.scale is not None]
    if scales:
        lin = np.einsum("nij,nj->ni", ctx.compliance()[ctx.idx], W)
        t = lin + float(np.prod(scales)) * (t - lin)
    for part in parts:
        if part.twist is not None:
            t = t + part.twist
    return t, solved


def nonlinear_tcp_solved(model, tcp_poses, W_tcp, tool, workers: int = 1, start=None) -> NonlinearTcp:
    """TCP deflection twists by the nonlinear equilibrium with the model's effects (see
    :func:`nonlinear_tcp`), with the states to warm-start nearby solves: ``start`` (n, ns) the states
    of a previous call at nearby poses (e.g. the programmed poses of compensated commands)."""
    from .wrench import at_platform

    check_effects(model)
    P, lever = platform_poses(model, tcp_poses, tool)
    Wp = at_platform(W_tcp, lever)
    n = len(P)
    blocks = [slice(a, min(n, a + BLOCK)) for a in range(0, n, BLOCK)]

    def run(sl):
        return _nonlinear_block(model, P[sl], Wp[sl], None if start is None else start[sl])

    if workers > 1 and len(blocks) > 1:
        with ThreadPoolExecutor(workers) as ex:
            parts = list(ex.map(run, blocks))
    else:
        parts = [run(sl) for sl in blocks]
    t = np.vstack([p[0] for p in parts])
    R = rotation_matrix(t[:, 3:])
    t[:, :3] += np.einsum("nij,nj->ni", R - np.eye(3), lever)
    return NonlinearTcp(t, np.vstack([p[1].state for p in parts]), sum(p[1].cold for p in parts),
                        sum(p[1].warm_failed for p in parts))


def nonlinear_tcp(model, tcp_poses, W_tcp, tool, workers: int = 1) -> np.ndarray:
    """TCP deflection twists (n, 6) by the nonlinear equilibrium with the model's effects; NaN rows
    where the equilibrium was not found (the caller names them).  Consecutive points are solved
    warm-started from their neighbours (:mod:`vjm.toolpath.equilibrium`)."""
    return nonlinear_tcp_solved(model, tcp_poses, W_tcp, tool, workers).twist


def tcp_deflection(model, tcp_poses, W_tcp, tool, method: str = "nonlinear", workers: int = 1) -> np.ndarray:
    """TCP deflection twists (n, 6): ``method`` "linear" or "nonlinear" (see the module docstring)."""
    if method == "linear":
        return linear(model, tcp_poses, W_tcp, tool)
    if method == "nonlinear":
        return nonlinear_tcp(model, tcp_poses, W_tcp, tool, workers)
    raise VjmError(f"--method must be linear or nonlinear, got {method!r}")
