"""Deflection of the tool centre point (TCP) under a wrench at it, for commanded poses: linear or nonlinear.

The machine's pose is its platform frame; the TCP sits at ``tool`` (platform
axes, mm) from the platform point, so in world axes at ``R tool``.  The
wrench acts at the TCP; at the platform point it is ``(F, M + R tool x F)``.
The TCP's deflection counts the platform rotation times the tool lever:

* ``linear``: ``t = C(p) w`` (the model's springs, :meth:`vjm.Model.stiffness_map`),
  TCP translation ``t_p + t_r x R tool``.  The model's ``effects:`` are left out.
* ``nonlinear``: the equilibrium of :mod:`vjm.stiffness.nonlinear` (finite rotations; along a path warm-started
  from the neighbouring point, :mod:`vjm.toolpath.equilibrium`), TCP
  translation ``u + (Exp(t_r) - I) R tool``, with the model's ``effects:``
  (what ``vjm diagnose`` writes into model_updated.yaml):

  - ``gravity: {weight: W}``: ``W g`` (N, along ``geometry.gravity``, default -z) on the
    platform point, with the process wrench; on a 6-dof platform with ``first_moment_x/y/z``
    (``m``, N mm, platform axes: weight x lever arm) also the moment ``(R m) x g``;
  - ``clearance: {backlash: b}``: every actuator slips by ``b`` (mm) toward the force it
    carries under the total load, imposed as the rest value of its spring in the same
    equilibrium;
  - ``passive_clearance: {backlash: b}``: the passive joints slip by ``b`` (rad) toward their
    moments, added through their unit-load influence (linear, as vjm diagnose fits it);
  - ``geometric_nonlinearity: {scale: s}``: ``C w + s (nonlinear - C w)``.

Every function takes the commanded poses of the TCP (not of the platform).
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from ..kinematics.poses import rotation_matrix
from .equilibrium import equilibria

#: the effects this module knows how to apply (the additive effects of vjm diagnose)
EFFECTS = ("gravity", "clearance", "passive_clearance", "geometric_nonlinearity")
#: (pose, wrench) pairs per block of the nonlinear solver (marched in SEGMENTS runs: KKT matrices of 128 pairs)
BLOCK = 4096


def check_effects(model) -> None:
    unknown = sorted(set(model.effects) - set(EFFECTS))
    if unknown:
        raise VjmError(f"the model's effects {unknown} are not known to vjm path (known: {', '.join(EFFECTS)})")


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


def _effect(model, name: str, key: str, optional: bool = False) -> float:
    """Parameter ``key`` of the model's effect ``name`` (0 without the effect, or an optional key left out)."""
    e = model.effects.get(name)
    if e is None or (optional and isinstance(e, dict) and key not in e):
        return 0.0
    try:
        return float(e[key])
    except (KeyError, TypeError, ValueError):
        raise VjmError(f"effects.{name} must give a number {key}, got {e!r}") from None


def linear(model, tcp_poses, W_tcp, tool, kin=None) -> np.ndarray:
    """TCP deflection twists (n, 6) ``C(p) w`` with the tool lever (no effects)."""
    from .wrench import at_platform

    P, lever = platform_poses(model, tcp_poses, tool)
    C = model.stiffness_map(P if kin is None else kin).C
    t = np.einsum("nij,nj->ni", C, at_platform(W_tcp, lever))
    t[:, :3] += np.cross(t[:, 3:], lever)
    return t


def _actuator_springs(model) -> str:
    names = set()
    for ch in model.chains:
        a = ch.actuated[0]
        names |= {s.name for s in ch.springs if s.vars == (a,)}
    if len(names) != 1:
        raise VjmError("clearance: the model's chains have no single actuator spring to slip")
    return names.pop()


@dataclass(frozen=True)
class NonlinearTcp:
    """TCP twists (n, 6) (NaN rows where no equilibrium was found), the equilibrium states (n, ns) to
    warm-start nearby solves from, the cold starts and the points that needed the reference solver."""

    twist: np.ndarray
    state: np.ndarray
    cold: int = 0
    fallback: int = 0


def _nonlinear_block(model, P, Wp, start=None):
    """Nonlinear platform twists of one block, with gravity and actuator clearance; NaN rows where
    the equilibrium was not found; and the :class:`~.equilibrium.Solved` of the equilibria."""
    from ..effects import modelops as mo

    W = np.array(Wp)
    weight = _effect(model, "gravity", "weight")
    if weight:
        W[:, :3] += weight * mo.gravity_direction(model)
    m = np.array([_effect(model, "gravity", f"first_moment_{a}", optional=True) for a in "xyz"])
    if m.any():
        W[:, 3:] += np.cross(mo.platform_rotations(P) @ m, mo.gravity_direction(model))
    offsets = None
    b = _effect(model, "clearance", "backlash")
    if b:
        tau = np.asarray(model.joint_forces(P, W)["actuator"]).reshape(len(P), -1)
        tol = 1e-9 * max(float(np.max(np.abs(tau), initial=0.0)), 1e-300)
        offsets = {_actuator_springs(model): (b * np.where(np.abs(tau) > tol, np.sign(tau), 0.0))[:, :, None]}
    solved = equilibria(model, P, W, offsets=offsets, start=start)
    t = solved.twist
    s = model.effects.get("geometric_nonlinearity")
    if s is not None or _effect(model, "passive_clearance", "backlash"):
        lin = np.einsum("nij,nj->ni", model.stiffness_map(P).C, W)
        if s is not None:
            t = lin + _effect(model, "geometric_nonlinearity", "scale") * (t - lin)
        bp = _effect(model, "passive_clearance", "backlash")
        if bp:
            from ..discrepancy.predict import _slip_toward

            t = t + bp * _slip_toward(mo.joint_spring_influence(model, P), W)
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
