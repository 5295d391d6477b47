"""Self-weight of a serial or tree robot: the equilibrium on the deflected geometry.

The links' weights (and a payload's) are dead loads ``m g`` at their centres of mass; as the
springs deflect, the centres of mass move and the gravity torques change.  The equilibrium is
the stationary point of ``1/2 sum theta^T K theta - sum m g . p_com(theta) - w . tool``, solved
by :func:`vjm.nonlinear.deflection_map` -- the same Newton solver (exact Hessian, load steps on
failure) as a parallel machine's, the weights entering as its body loads.  It converges when the
Newton step of the tool pose is below ``tol`` (default 1e-11) times its size; where it does not,
an :class:`~vjm.errors.EquilibriumError` names the configurations (``strict=False``: NaN rows
and ``info["converged"]`` False).

A body on a branch of a tree that leaves the path to the tool (the other arm of a torso) loads
the path as a rigid body hanging from the last joint the two share: its own springs' effect on
where its weight acts is neglected (second order).
"""
from __future__ import annotations

import numpy as np

from ..chain import forward
from ..errors import VjmError
from .tree import ChainSprings, chain_values, path_chain


def _frame_at(model, joint: int, q: np.ndarray) -> np.ndarray:
    """World frames (n, 4, 4) of a joint's frame at q (rigid)."""
    if joint < 0:
        return np.broadcast_to(np.eye(4), (len(q), 4, 4))
    ch, _ = path_chain(model.tree, joint, np.eye(4), ChainSprings(), "frame")
    return forward(ch, chain_values(ch, model.tree, q))


def _attach(model, marks: dict, joint: int, point: np.ndarray, q: np.ndarray, own: bool):
    """(factor index, local point (n, 3)) where a point fixed to ``joint`` loads the chain with ``marks``,
    or None if it hangs from the base."""
    if joint in marks:
        return marks[joint][0 if own else 1], np.broadcast_to(point, (len(q), 3))
    a = joint
    while a >= 0 and a not in marks:
        a = model.tree.joints[a].parent
    if a < 0:
        return None
    Tb = _frame_at(model, joint, q)
    Ta = _frame_at(model, a, q)
    pw = np.einsum("nij,j->ni", Tb[:, :3, :3], point) + Tb[:, :3, 3]
    local = np.einsum("nji,nj->ni", Ta[:, :3, :3], pw - Ta[:, :3, 3])
    return marks[a][1], local


def check_inertials(model) -> None:
    """Every moving link declares its inertial (a mass of 0 included), or VjmError naming the first that does not."""
    massive = set(model.tree.declared) | {b.joint for b in model.tree.bodies if b.mass > 0}
    for i, j in enumerate(model.tree.joints):
        if i not in massive:
            raise VjmError(f"{model._where}self-weight: link {j.child or j.name!r} (moved by joint {j.name!r}) has no inertial "
                           f"(mass and centre of mass); give them in the URDF or under masses: in the model file")


def body_loads(model, q: np.ndarray, tool: str, gravity, payload) -> list:
    """The body loads (factor index, point, force) of the chain to ``tool`` (see vjm.nonlinear)."""
    _, marks = model.chain(tool)
    g = np.asarray(gravity, dtype=float)
    loads = []
    for b in model.tree.bodies:
        if b.joint < 0 or b.mass == 0:
            continue
        hit = _attach(model, marks, b.joint, np.asarray(b.com, dtype=float), q, own=True)
        if hit is not None:
            loads.append((hit[0], hit[1], b.mass * g))
    if payload is not None and payload.mass > 0:
        hit = point_load(model, q, tool, payload.frame, payload.com, payload.mass * g)
        if hit is not None:
            loads.append(hit)
    return loads


def point_load(model, q: np.ndarray, tool: str, frame: str, point, force):
    """The body load (factor index, point, force) of a dead force (3,) or (n, 3) (N, world axes) at
    ``point`` (mm) of the named ``frame``, on the chain to ``tool``; None where it hangs from the base."""
    _, marks = model.chain(tool)
    f = model.tree.frame(frame)
    p = f.placement[:3, :3] @ np.asarray(point, dtype=float) + f.placement[:3, 3]
    hit = _attach(model, marks, f.joint, p, q, own=False)
    return None if hit is None else (hit[0], hit[1], force)


def self_weight(model, q, tool, gravity, payload, wrench, tol, max_iter, return_info, strict):
    """:meth:`vjm.robot.RobotModel.self_weight` (see the module docstring)."""
    from ..nonlinear import deflection_map

    check_inertials(model)
    tool = model._tool(tool)
    kin = model.kinematics(q, tool)
    g = model.gravity if gravity is None else gravity
    g = np.asarray(g, dtype=float)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise VjmError(f"gravity must be 3 finite numbers (m/s^2, base frame), got {gravity!r}")
    pl = model.payload if payload is None else payload
    loads = body_loads(model, kin.q, tool, g, pl)
    W = np.zeros(6) if wrench is None else wrench
    t, info = deflection_map(model, kin, W, tol=tol, max_iter=max_iter, return_info=True, strict=strict,
                             body_loads=[loads])
    single = np.ndim(q) == 1
    if return_info:
        return (t[0], {k: v[0] for k, v in info.items() if k != "springs"}) if single else (t, info)
    return t[0] if single else t
